// lambert: the Lambertian diffuse reflector, f = rho/pi (MODELS.md 2.1).
// Reciprocal, albedo rho at every angle; sampled by the default mixture (brdf.cpp).
#include "shading/brdf/lambert.h"

#include "shading/brdf/model_spec.h"
#include "shading/brdf/spec_args.h"
#include "shading/core/format.h"

namespace shading {

namespace {
constexpr SpecKey kRho{"rho", "<rgb>", "albedo", 0, 1};
constexpr SpecParam<Lambert> kParams[] = {{kRho, &Lambert::rho}};
}  // namespace

Rgb Lambert::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return lambert_f(rho);
}
std::string Lambert::describe() const { return "lambert(rho=" + detail::fmt(rho) + ")"; }
void Lambert::write_spec(SpecWriter& w) const { write_params(w, "lambert", kParams, *this); }

ModelEntry lambert_model() {
    return plain_model_entry("lambert", "Lambertian diffuse, f = rho/pi", kParams,
                             {{"lambert rho=0.2,0.5,0.9"}, {"lambert rho=1"}}, {{"lambert", 1.00}});
}

}  // namespace shading
