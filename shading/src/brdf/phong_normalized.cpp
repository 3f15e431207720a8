// phong_normalized: the energy-normalised modified Phong (Lafortune & Willems 1994),
// f = kd/pi + ks (n+2)/(2 pi) cos^n(alpha) (MODELS.md 2.4). Reciprocal, albedo <= kd + ks;
// sampled by the default mixture (brdf.cpp).
#include "shading/brdf/phong_normalized.h"

#include "shading/brdf/model_spec.h"
#include "shading/brdf/spec_args.h"
#include "shading/core/format.h"

namespace shading {

namespace {
using detail::fmt;
constexpr SpecKey kKd{"kd", "<rgb>", "diffuse albedo (Lambertian base)", 0, 1};
constexpr SpecKey kKs{"ks", "<rgb>", "specular albedo at normal incidence", 0, 1, "; kd+ks <= 1"};
constexpr SpecKey kExponent{"n", "<x>", "exponent", 0, 1e6};
constexpr SpecParam<PhongNormalized> kParams[] = {
    {kKd, &PhongNormalized::kd}, {kKs, &PhongNormalized::ks}, {kExponent, &PhongNormalized::n}};
void check_energy(const SpecArgs& a, const PhongNormalized& b) { a.check_sum("kd", b.kd, "ks", b.ks); }
}  // namespace

Rgb PhongNormalized::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return lambert_f(kd) + ks * modified_phong_lobe(dot(mirror_z(wo), wi), n);
}
std::string PhongNormalized::describe() const {
    return "phong_normalized(kd=" + fmt(kd) + " ks=" + fmt(ks) + " n=" + fmt(n) + ")";
}
void PhongNormalized::write_spec(SpecWriter& w) const { write_params(w, "phong_normalized", kParams, *this); }

ModelEntry phong_normalized_model() {
    return plain_model_entry(
        "phong_normalized", "modified Phong (Lafortune & Willems 1994), f = kd/pi + ks (n+2)/(2pi) cos^n(alpha)", kParams,
        {{"phong_normalized kd=0.3 ks=0.6 n=35"}, {"phong_normalized kd=0,0.1,0.2 ks=1,0.9,0.8 n=0"}}, {}, check_energy);
}

}  // namespace shading
