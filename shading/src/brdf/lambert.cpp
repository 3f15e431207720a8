// lambert: the Lambertian diffuse reflector, f = rho/pi (MODELS.md 2.1).
// Reciprocal, albedo rho at every angle; sampled by the default mixture (brdf.cpp).
#include "shading/brdf/lambert.h"

#include "shading/brdf/model_spec.h"
#include "shading/brdf/spec_args.h"
#include "shading/core/format.h"

namespace shading {

Rgb Lambert::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return lambert_f(rho);
}
std::string Lambert::describe() const { return "lambert(rho=" + detail::fmt(rho) + ")"; }
void Lambert::write_spec(SpecWriter& w) const { w.model("lambert").rgb("rho", rho); }

namespace {
const SpecKey kRho{"rho", "<rgb>", "albedo", 0, 1};
}  // namespace

ModelEntry lambert_model() {
    ModelEntry m;
    m.name = "lambert";
    m.summary = "Lambertian diffuse, f = rho/pi";
    m.keys = [] { return help_line(kRho, detail::fmt(Lambert(Rgb(0.5)).rho)); };
    m.make = [](SpecArgs& a) -> BrdfPtr {
        auto b = std::make_shared<Lambert>(Rgb(0.5));
        b->rho = a.rgb(kRho, b->rho);
        return b;
    };
    m.examples = {{"lambert rho=0.2,0.5,0.9"}, {"lambert rho=1"}};
    m.costs = {{"lambert", 1.00}};
    return m;
}

}  // namespace shading
