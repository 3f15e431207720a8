// phong_pov and blinn_pov: POV-Ray's `phong` and `specular` highlights as BRDFs, each over
// POV's `diffuse` (MODELS.md 2.2, 2.3). Not reciprocal, energy bounded only if the user keeps
// them so; sampled by the default mixture (brdf.cpp).
#include "shading/brdf/pov_highlights.h"

#include "shading/brdf/model_spec.h"
#include "shading/brdf/spec_args.h"
#include "shading/core/format.h"

namespace shading {

namespace {
using detail::fmt;

constexpr SpecKey kPovDiffuse{"diffuse", "<rgb>", "POV diffuse (Lambert rho)", 0, 1};
constexpr SpecKey kPhong{"phong", "<rgb>", "P", 0, 100};
constexpr SpecKey kPhongSize{"phong_size", "<x>", "n", 0, 1e6};
constexpr SpecKey kSpecular{"specular", "<rgb>", "S", 0, 100};
constexpr SpecKey kRoughness{"roughness", "<x>", "r", 1e-6, 1};
constexpr SpecParam<PhongPov> kPhongParams[] = {
    {kPhong, &PhongPov::phong}, {kPhongSize, &PhongPov::phong_size}, {kPovDiffuse, &PhongPov::diffuse}};
constexpr SpecParam<BlinnPov> kBlinnParams[] = {
    {kSpecular, &BlinnPov::specular}, {kRoughness, &BlinnPov::roughness}, {kPovDiffuse, &BlinnPov::diffuse}};

// Both are registered not reciprocal, for this reason.
ModelEntry not_reciprocal(ModelEntry m) {
    m.reciprocal = false;
    m.not_reciprocal_because = "POV adds the highlight with no cosine, so only cos_i divides it (f = c / (pi cos_i))";
    return m;
}
}  // namespace

Rgb PhongPov::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    double c = phong_pov_contribution(dot(mirror_z(wo), wi), phong_size);
    return lambert_f(diffuse) + phong * pov_contribution_to_f(c, wi.z);
}
std::string PhongPov::describe() const {
    return "phong_pov(phong=" + fmt(phong) + " phong_size=" + fmt(phong_size) + " diffuse=" + fmt(diffuse) + ")";
}
void PhongPov::write_spec(SpecWriter& w) const { write_params(w, "phong_pov", kPhongParams, *this); }

Rgb BlinnPov::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    double c = blinn_pov_contribution(half_vector(wo, wi).z, roughness);
    return lambert_f(diffuse) + specular * pov_contribution_to_f(c, wi.z);
}
std::string BlinnPov::describe() const {
    return "blinn_pov(specular=" + fmt(specular) + " roughness=" + fmt(roughness) + " diffuse=" + fmt(diffuse) +
           ")";
}
void BlinnPov::write_spec(SpecWriter& w) const { write_params(w, "blinn_pov", kBlinnParams, *this); }

// phong_pov's albedo is at most d + 2P/(n+1) (f cos does not depend on theta_i). Each model's
// first example is energy bounded, its second not.
ModelEntry phong_pov_model() {
    return not_reciprocal(plain_model_entry(
        "phong_pov", "POV-Ray `phong P phong_size n`: contribution P (R.L)^n, f = d/pi + P (R.L)^n / (pi cos_i)",
        kPhongParams,
        {{"phong_pov phong=0.3 phong_size=40 diffuse=0.5"}, {"phong_pov phong=5,2,1 phong_size=2 diffuse=0.1,0.2,0.3", false}},
        {}));
}

ModelEntry blinn_pov_model() {
    return not_reciprocal(plain_model_entry(
        "blinn_pov", "POV-Ray `specular S roughness r`: contribution S (N.H)^(1/r), f = d/pi + S (N.H)^(1/r) / (pi cos_i)",
        kBlinnParams, {{"blinn_pov specular=0.4 roughness=0.05 diffuse=0.3,0.4,0.5"}, {"blinn_pov specular=20 roughness=0.5", false}},
        {}));
}

}  // namespace shading
