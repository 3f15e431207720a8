// oren_nayar: Oren & Nayar 1994's qualitative model, f = rho/pi (A + B max(0, cos dphi)
// sin alpha tan beta) (MODELS.md 2.7). Reciprocal; albedo below rho (the model loses energy);
// sampled by the default mixture (brdf.cpp).
#include "shading/brdf/oren_nayar.h"

#include "shading/brdf/model_spec.h"
#include "shading/brdf/spec_args.h"
#include "shading/core/format.h"

namespace shading {

namespace {
using detail::fmt;
constexpr SpecKey kRho{"rho", "<rgb>", "albedo", 0, 1};
constexpr SpecKey kSigma{"sigma", "<x>", "facet slope std. deviation in radians", 0, kPi / 2};
constexpr SpecParam<OrenNayar> kParams[] = {{kRho, &OrenNayar::rho}, {kSigma, &OrenNayar::sigma}};
}  // namespace

Rgb OrenNayar::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return lambert_f(rho) * oren_nayar_factor(wo, wi, oren_nayar_a(sigma), oren_nayar_b(sigma));
}
std::string OrenNayar::describe() const { return "oren_nayar(rho=" + fmt(rho) + " sigma=" + fmt(sigma) + ")"; }
void OrenNayar::write_spec(SpecWriter& w) const { write_params(w, "oren_nayar", kParams, *this); }

ModelEntry oren_nayar_model() {
    return plain_model_entry("oren_nayar",
                             "Oren-Nayar 1994 qualitative model, f = rho/pi (A + B max(0,cos dphi) sin a tan b)", kParams,
                             {{"oren_nayar rho=0.7,0.5,0.3 sigma=0.4"}, {"oren_nayar rho=1 sigma=1.5"}},
                             {{"oren_nayar", 1.05}});
}

}  // namespace shading
