// The fitter's model families (fit_families.h) and their canonical names (fit.h).
#include "shading/fit/fit_families.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <sstream>
#include <stdexcept>

#include "shading/brdf/lafortune.h"
#include "shading/brdf/lambert.h"
#include "shading/brdf/microfacet.h"
#include "shading/brdf/oren_nayar.h"
#include "shading/brdf/ward.h"
#include "shading/core/format.h"

namespace shading {
namespace fit_detail {

namespace {

// Significant digits of a fit's printed spec (fit.h).
constexpr int kSpecDigits = 6;

// Each channel of v above 1 set to 1; true if any was.
bool clamp_to_one(Rgb& v) {
    bool clamped = false;
    for (int c = 0; c < 3; ++c)
        if (v[c] > 1.0) {
            v[c] = 1.0;
            clamped = true;
        }
    return clamped;
}

// kd + s <= 1 per channel, as the printed spec states them: both scaled down when the sum
// exceeds 1, then s nudged below 1 - kd where 6-digit printing would round the sum above 1
// (make_brdf rejects such a spec). True if the fit had to be scaled.
bool clamp_sum(Rgb& a, Rgb& b) {
    bool clamped = false;
    for (int c = 0; c < 3; ++c) {
        double s = a[c] + b[c];
        if (s > 1.0) {
            a[c] /= s;
            b[c] /= s;
            clamped = true;
        }
        const double printed_a = std::stod(detail::fmt(a[c], kSpecDigits));
        if (printed_a + std::stod(detail::fmt(b[c], kSpecDigits)) > 1.0) b[c] = 1.0 - printed_a - 1e-6;
    }
    return clamped;
}

// The printed spec of a fitted model, and its linear parameters (per channel) as it states them.
SpecOut spec_out(const Brdf& model, bool clamped, const std::vector<std::pair<std::string, Rgb>>& linear) {
    SpecOut o;
    o.spec = model.spec(kSpecDigits);
    o.clamped = clamped;
    for (const auto& [name, v] : linear) {
        o.linear.push_back({name + "_r", v.r, -1});
        o.linear.push_back({name + "_g", v.g, -1});
        o.linear.push_back({name + "_b", v.b, -1});
    }
    return o;
}

const std::vector<double> kRoughStarts = {0.03, 0.07, 0.15, 0.3, 0.6};

Family microfacet_family(const std::string& d, const std::string& g, const std::string& f) {
    Family fam;
    fam.name = "microfacet d=" + d + " g=" + g + " f=" + f;
    fam.shape.push_back({"m", 1e-3, 1.0, true, kRoughStarts});
    if (f == "dielectric") fam.shape.push_back({"eta", 1.01, 4.0, false, {1.5}});
    if (f == "conductor") {
        for (const char* c : {"n_r", "n_g", "n_b"}) fam.shape.push_back({c, 0.03, 10.0, true, {0.5}});
        for (const char* c : {"k_r", "k_g", "k_b"}) fam.shape.push_back({c, 0.0, 12.0, false, {3.0}});
        fam.scale = ScaleMode::OneMinusKd;
    }
    if (f == "schlick") fam.nbases = 2;
    const DKind dk = d == "blinn" ? DKind::Blinn : d == "gaussian" ? DKind::Gaussian
                     : d == "tr"  ? DKind::TrowbridgeReitz : DKind::Beckmann;
    const GKind gk = g == "vcavity" ? GKind::VCavity : GKind::Smith;
    fam.bases = [dk, gk, f](const Vector& x) {
        auto lobe = [&](const FresnelTerm& fresnel) {
            auto b = std::make_shared<Microfacet>();  // normalised form, kd = 0, rho_s = 1
            b->d = NormalDistribution::from_m(dk, x[0]);
            b->g = gk;
            b->fresnel = fresnel;
            return b;
        };
        FresnelTerm fr;
        std::vector<BrdfPtr> out;
        if (f == "none" || f == "schlick") out.push_back(lobe(fr));
        if (f == "schlick") {
            fr.kind = FKind::Schlick;
            fr.f0 = Rgb(0.0);
            out.push_back(lobe(fr));
        }
        if (f == "dielectric") {
            fr.kind = FKind::Dielectric;
            fr.eta = x[1];
            out.push_back(lobe(fr));
        }
        if (f == "conductor") {
            fr.kind = FKind::Conductor;
            fr.n = Rgb(x[1], x[2], x[3]);
            fr.k = Rgb(x[4], x[5], x[6]);
            out.push_back(lobe(fr));
        }
        return out;
    };
    fam.spec = [dk, gk, f](const Vector& x, const Rgb& kd, const std::vector<Rgb>& coef) {
        Microfacet m;  // normalised form
        m.d = NormalDistribution::from_m(dk, x[0]);
        m.g = gk;
        m.kd = kd;
        std::vector<std::pair<std::string, Rgb>> linear;
        if (f == "none" || f == "dielectric") {
            m.rho_s = coef[0];
            if (f == "dielectric") {
                m.fresnel.kind = FKind::Dielectric;
                m.fresnel.eta = x[1];
            }
        } else if (f == "schlick") {
            m.fresnel.kind = FKind::Schlick;
            for (int c = 0; c < 3; ++c) {
                m.rho_s[c] = coef[0][c] + coef[1][c];
                m.fresnel.f0[c] = m.rho_s[c] > 0 ? coef[0][c] / m.rho_s[c] : 0.04;
            }
            linear.push_back({"f0", m.fresnel.f0});
        } else {
            m.rho_s = Rgb(1.0) - kd;
            m.fresnel.kind = FKind::Conductor;
            m.fresnel.n = Rgb(x[1], x[2], x[3]);
            m.fresnel.k = Rgb(x[4], x[5], x[6]);
        }
        const bool clamped = clamp_sum(m.kd, m.rho_s);
        linear.push_back({"kd", m.kd});
        linear.push_back({"rho_s", m.rho_s});
        return spec_out(m, clamped, linear);
    };
    return fam;
}

Family ward_family(bool aniso) {
    Family fam;
    fam.name = aniso ? "ward_aniso" : "ward";
    if (aniso) {
        fam.shape.push_back({"ax", 1e-3, 1.0, true, {0.03, 0.08, 0.15, 0.3, 0.5}});
        fam.shape.push_back({"ay", 1e-3, 1.0, true, {0.03, 0.08, 0.15, 0.3, 0.5}});
        fam.valid_start = [](const Vector& x) { return x[0] == x[1]; };
    } else {
        fam.shape.push_back({"alpha", 1e-3, 1.0, true, {0.03, 0.08, 0.15, 0.3, 0.5}});
    }
    fam.bases = [aniso](const Vector& x) {
        auto b = std::make_shared<Ward>();  // rho_d = 0, rho_s = 1
        b->rho_d = Rgb(0.0);
        b->rho_s = Rgb(1.0);
        b->ax = x[0];
        b->ay = aniso ? x[1] : x[0];
        return std::vector<BrdfPtr>{b};
    };
    fam.spec = [aniso](const Vector& x, const Rgb& kd, const std::vector<Rgb>& coef) {
        Ward w;
        w.rho_d = kd;
        w.rho_s = coef[0];
        w.ax = x[0];
        w.ay = aniso ? x[1] : x[0];
        const bool clamped = clamp_sum(w.rho_d, w.rho_s);
        return spec_out(w, clamped, {{"rho_d", w.rho_d}, {"rho_s", w.rho_s}});
    };
    return fam;
}

Family oren_nayar_family() {
    Family fam;
    fam.name = "oren_nayar";
    fam.has_kd = false;
    fam.shape.push_back({"sigma", 0.0, kPi / 2, false, {0.05, 0.3, 0.6, 1.0}});
    fam.bases = [](const Vector& x) {
        auto b = std::make_shared<OrenNayar>();
        b->rho = Rgb(1.0);
        b->sigma = x[0];
        return std::vector<BrdfPtr>{b};
    };
    fam.spec = [](const Vector& x, const Rgb&, const std::vector<Rgb>& coef) {
        OrenNayar on;
        on.rho = coef[0];
        on.sigma = x[0];
        const bool clamped = clamp_to_one(on.rho);
        return spec_out(on, clamped, {{"rho", on.rho}});
    };
    return fam;
}

Family lambert_family() {
    Family fam;
    fam.name = "lambert";
    fam.nbases = 0;
    fam.bases = [](const Vector&) { return std::vector<BrdfPtr>{}; };
    fam.spec = [](const Vector&, const Rgb& kd, const std::vector<Rgb>&) {
        Lambert l(kd);
        const bool clamped = clamp_to_one(l.rho);
        return spec_out(l, clamped, {{"rho", l.rho}});
    };
    return fam;
}

// Lafortune lobe j: C = (-c, -c, c R) with c = ((n + 2) / (2 pi))^(1/n), so a weight of 1 is
// the normalised Phong lobe's magnitude when R = 1 (weights stay near [0, 1]).
double lafortune_c(double n) { return std::pow((n + 2.0) / (2.0 * kPi), 1.0 / n); }

Family lafortune_family(int k) {
    Family fam;
    fam.name = "lafortune k=" + std::to_string(k);
    fam.nbases = k;
    for (int j = 0; j < k; ++j) {
        std::string p = "lobe" + std::to_string(j + 1);
        fam.shape.push_back({p + "_cz_over_cxy", 0.2, 5.0, true, {1.0}});
        fam.shape.push_back({p + "_n", 0.5, 2e4, true, {3, 10, 40, 150, 600}});
    }
    fam.valid_start = [k](const Vector& x) {
        for (int j = 1; j < k; ++j)
            if (!(x[2 * j + 1] > x[2 * j - 1])) return false;
        return true;
    };
    // Lobe j of x: C = (-c, -c, c R), exponent n (weight 1 in a basis).
    auto lobe = [](const Vector& x, int j) {
        Lafortune::Lobe l;
        const double R = x[2 * j], n = x[2 * j + 1], c = lafortune_c(n);
        l.cx = l.cy = -c;
        l.cz = c * R;
        l.n = n;
        return l;
    };
    fam.bases = [k, lobe](const Vector& x) {
        std::vector<BrdfPtr> out;
        for (int j = 0; j < k; ++j) {
            auto b = std::make_shared<Lafortune>();  // kd = 0
            b->lobes.push_back(lobe(x, j));
            out.push_back(b);
        }
        return out;
    };
    fam.spec = [k, lobe](const Vector& x, const Rgb& kd, const std::vector<Rgb>& coef) {
        Lafortune lf;
        lf.kd = kd;
        const bool clamped = clamp_to_one(lf.kd);
        std::vector<std::pair<std::string, Rgb>> linear = {{"kd", lf.kd}};
        for (int j = 0; j < k; ++j) {
            Lafortune::Lobe l = lobe(x, j);
            for (int c = 0; c < 3; ++c) l.weight[c] = std::min(coef[j][c], 100.0);  // the spec's bound
            lf.lobes.push_back(l);
            linear.push_back({"lobe" + std::to_string(j + 1) + "_w", l.weight});
        }
        return spec_out(lf, clamped, linear);
    };
    return fam;
}

const std::vector<std::string> kD = {"blinn", "gaussian", "tr", "beckmann"};
const std::vector<std::string> kG = {"vcavity", "smith"};
const std::vector<std::string> kF = {"none", "dielectric", "conductor", "schlick"};

}  // namespace

Family make_family(const std::string& name) {
    if (name == "lambert") return lambert_family();
    if (name == "oren_nayar") return oren_nayar_family();
    if (name == "ward") return ward_family(false);
    if (name == "ward_aniso") return ward_family(true);
    if (name.rfind("lafortune k=", 0) == 0) {
        int k = std::atoi(name.c_str() + 12);
        if (k < 1 || k > 4) throw std::invalid_argument("fit: lafortune k must be 1..4");
        return lafortune_family(k);
    }
    std::istringstream s(name);
    std::string w, d, g, f;
    s >> w;
    if (w == "microfacet") {
        while (s >> w) {
            if (w.rfind("d=", 0) == 0) d = w.substr(2);
            else if (w.rfind("g=", 0) == 0) g = w.substr(2);
            else if (w.rfind("f=", 0) == 0) f = w.substr(2);
        }
        if (std::count(kD.begin(), kD.end(), d) && std::count(kG.begin(), kG.end(), g) &&
            std::count(kF.begin(), kF.end(), f))
            return microfacet_family(d, g, f);
    }
    throw std::invalid_argument("fit: unknown model family '" + name + "' (see brdftool fit --help)");
}

}  // namespace fit_detail

using fit_detail::kD;
using fit_detail::kF;
using fit_detail::kG;
using fit_detail::make_family;

std::vector<std::string> fit_families() {
    std::vector<std::string> out = {"lambert", "oren_nayar", "ward", "ward_aniso", "lafortune k=1", "lafortune k=2"};
    for (const auto& d : kD)
        for (const auto& g : kG)
            for (const auto& f : kF) out.push_back("microfacet d=" + d + " g=" + g + " f=" + f);
    return out;
}

std::vector<std::string> expand_families(const std::string& pattern) {
    std::istringstream s(pattern);
    std::vector<std::string> words;
    for (std::string w; s >> w;) words.push_back(w);
    if (words.empty()) throw std::invalid_argument("fit: empty model pattern");
    if (words.size() == 1 && words[0] == "all") return fit_families();
    if (words[0] == "lafortune") {
        if (words.size() == 1) return {"lafortune k=1"};
        if (words.size() == 2 && words[1].rfind("k=", 0) == 0) {
            make_family("lafortune " + words[1]);  // validates k
            return {"lafortune " + words[1]};
        }
    }
    if (words[0] == "microfacet") {
        std::map<std::string, std::string> want;
        for (size_t k = 1; k < words.size(); ++k) {
            auto eq = words[k].find('=');
            std::string key = words[k].substr(0, eq);
            if (eq == std::string::npos || (key != "d" && key != "g" && key != "f") || want.count(key))
                throw std::invalid_argument("fit: microfacet pattern takes d=, g=, f= once each, got '" + words[k] + "'");
            want[key] = words[k].substr(eq + 1);
        }
        std::vector<std::string> out;
        for (const auto& d : kD)
            for (const auto& g : kG)
                for (const auto& f : kF)
                    if ((!want.count("d") || want["d"] == d) && (!want.count("g") || want["g"] == g) &&
                        (!want.count("f") || want["f"] == f))
                        out.push_back("microfacet d=" + d + " g=" + g + " f=" + f);
        if (out.empty()) throw std::invalid_argument("fit: no microfacet family matches '" + pattern + "'");
        return out;
    }
    if (words.size() == 1) {
        make_family(words[0]);
        return {words[0]};
    }
    throw std::invalid_argument("fit: unknown model pattern '" + pattern + "'");
}
}  // namespace shading
