// lafortune: Lafortune et al. 1997 generalized cosine lobes, f = kd/pi + sum w (Cx xo xi +
// Cy yo yi + Cz zo zi)^n (MODELS.md 2.8). Reciprocal; albedo <= 1 only for normalised weights;
// anisotropic when some lobe has Cx != Cy; sampled by the default mixture (brdf.cpp).
#include "shading/brdf/lafortune.h"

#include "shading/brdf/model_spec.h"
#include "shading/brdf/spec_args.h"
#include "shading/core/format.h"

namespace shading {

namespace {
using detail::fmt;
const SpecKey kKd{"kd", "<rgb>", "diffuse", 0, 1};
const SpecKey kLobe{"lobe", "cx,cy,cz,n[,w | ,r,g,b]", "repeatable; C in [-100,100], n in [0,1e6], weights in [0,100]", 1, 0};

Lafortune::Lobe parse_lobe(SpecArgs& a, const std::string& text) {
    std::vector<double> v = a.numbers("lobe", text);
    if (v.size() != 4 && v.size() != 5 && v.size() != 7)
        spec_error(a.where("lobe") + "expected cx,cy,cz,n[,w] or cx,cy,cz,n,r,g,b; got " + std::to_string(v.size()) +
                   " numbers in '" + text + "'");
    Lafortune::Lobe l;
    l.cx = v[0];
    l.cy = v[1];
    l.cz = v[2];
    l.n = v[3];
    for (int i = 0; i < 3; ++i)
        if (std::abs(v[i]) > 100) spec_error(a.where("lobe") + "C coefficient " + fmt(v[i]) + " out of range [-100, 100]");
    if (!(l.n >= 0 && l.n <= 1e6)) spec_error(a.where("lobe") + "exponent n " + fmt(l.n) + " out of range [0, 1e6]");
    if (v.size() == 5) l.weight = Rgb(v[4]);
    if (v.size() == 7) l.weight = Rgb(v[4], v[5], v[6]);
    for (int c = 0; c < 3; ++c)
        if (!(l.weight[c] >= 0 && l.weight[c] <= 100))
            spec_error(a.where("lobe") + "weight " + fmt(l.weight[c]) + " out of range [0, 100]");
    return l;
}
}  // namespace

Rgb Lafortune::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    Rgb sum = lambert_f(kd);
    for (const Lobe& l : lobes) sum += l.weight * lafortune_lobe(wo, wi, l.cx, l.cy, l.cz, l.n);
    return sum;
}
bool Lafortune::anisotropic() const {
    for (const Lobe& l : lobes)
        if (l.cx != l.cy) return true;
    return false;
}
std::string Lafortune::describe() const {
    std::string s = "lafortune(kd=" + fmt(kd);
    for (const Lobe& l : lobes)
        s += " lobe=" + fmt(l.cx) + "," + fmt(l.cy) + "," + fmt(l.cz) + "," + fmt(l.n) + "," + fmt(l.weight.r) + "," +
             fmt(l.weight.g) + "," + fmt(l.weight.b);
    return s + ")";
}
// Every lobe with its three weights. A spec without lobe= means one default lobe, so a model
// without lobes is written with one lobe of weight 0 (the same f to the bit: it adds +0).
void Lafortune::write_spec(SpecWriter& w) const {
    w.model("lafortune").rgb(kKd.name, kd);
    for (const Lobe& l : lobes) w.list(kLobe.name, {l.cx, l.cy, l.cz, l.n, l.weight.r, l.weight.g, l.weight.b});
    if (lobes.empty()) w.list(kLobe.name, {0, 0, 0, 0, 0, 0, 0});
}

ModelEntry lafortune_model() {
    ModelEntry m;
    m.name = "lafortune";
    m.summary = "Lafortune 1997 generalized cosine lobes, f = kd/pi + sum w (Cx xo xi + Cy yo yi + Cz zo zi)^n";
    m.keys = [] {
        const Lafortune::Lobe l;
        return help_line(kKd, fmt(Lafortune().kd)) +
               help_line(kLobe, "one lobe " + fmt(l.cx) + "," + fmt(l.cy) + "," + fmt(l.cz) + "," + fmt(l.n) +
                                    " (weight " + fmt(l.weight) + ")");
    };
    m.make = [](SpecArgs& a) -> BrdfPtr {
        auto b = std::make_shared<Lafortune>();
        b->kd = a.rgb(kKd, b->kd);
        std::vector<std::string> lobes = a.all(kLobe.name);
        if (lobes.empty()) b->lobes.push_back(Lafortune::Lobe());
        for (const std::string& text : lobes) b->lobes.push_back(parse_lobe(a, text));
        return b;
    };
    m.examples = {{"lafortune kd=0.1 lobe=-1,-1,1,40,0.5 lobe=0.8,0.8,0.9,6,0.2,0.3,0.1"},
                  {"lafortune kd=0.2 lobe=-0.5,-1.5,1,10,0.3"},
                  {"lafortune lobe=-1,-1,1,20,3.5"}};
    m.costs = {{"lafortune", 1.10}};
    return m;
}

}  // namespace shading
