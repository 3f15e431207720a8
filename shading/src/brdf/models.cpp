// Analytic non-microfacet BRDF models (models.h). Equations: MODELS.md.
#include "shading/brdf/models.h"
#include "shading/core/format.h"

#include <sstream>

namespace shading {

namespace {
using detail::fmt;
}  // namespace

// Every f below starts with the same guard: a direction at or below the surface
// (z <= 0) reflects nothing, as the Brdf contract requires.

Rgb Lambert::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return lambert_f(rho);
}
std::string Lambert::describe() const { return "lambert(rho=" + fmt(rho) + ")"; }

Rgb PhongPov::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    double c = phong_pov_contribution(dot(mirror_z(wo), wi), phong_size);
    return lambert_f(diffuse) + phong * pov_contribution_to_f(c, wi.z);
}
std::string PhongPov::describe() const {
    return "phong_pov(phong=" + fmt(phong) + " phong_size=" + fmt(phong_size) + " diffuse=" + fmt(diffuse) + ")";
}

Rgb BlinnPov::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    double c = blinn_pov_contribution(half_vector(wo, wi).z, roughness);
    return lambert_f(diffuse) + specular * pov_contribution_to_f(c, wi.z);
}
std::string BlinnPov::describe() const {
    return "blinn_pov(specular=" + fmt(specular) + " roughness=" + fmt(roughness) + " diffuse=" + fmt(diffuse) +
           ")";
}

Rgb PhongNormalized::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return lambert_f(kd) + ks * modified_phong_lobe(dot(mirror_z(wo), wi), n);
}
std::string PhongNormalized::describe() const {
    return "phong_normalized(kd=" + fmt(kd) + " ks=" + fmt(ks) + " n=" + fmt(n) + ")";
}

Rgb Ward::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    double s = variant == WardVariant::Original ? ward_original_lobe(wo, wi, ax, ay) : ward_gmd_lobe(wo, wi, ax, ay);
    return lambert_f(rho_d) + rho_s * s;
}
std::string Ward::describe() const {
    return std::string("ward(variant=") + (variant == WardVariant::Original ? "original" : "gmd") +
           " rho_d=" + fmt(rho_d) + " rho_s=" + fmt(rho_s) + " ax=" + fmt(ax) + " ay=" + fmt(ay) + ")";
}
double Ward::specular_probability() const { return lobe_probability(rho_s, rho_d); }
Vec3 Ward::sample(const Vec3& wo, double u1, double u2) const {
    return sample_mix(wo, u1, u2, specular_probability());
}
Vec3 Ward::sample_glossy(const Vec3& wo, double u1, double u2) const { return sample_mix(wo, u1, u2, 1.0); }
Vec3 Ward::sample_mix(const Vec3& wo, double u1, double u2, double ps) const {
    return sample_lobe_or_cosine(wo, u1, u2, ps,
                                 [this](double a, double b) { return sample_beckmann_aniso(ax, ay, a, b); });
}
double Ward::pdf(const Vec3& wo, const Vec3& wi) const { return pdf_mix(wo, wi, specular_probability()); }
double Ward::pdf_glossy(const Vec3& wo, const Vec3& wi) const { return pdf_mix(wo, wi, 1.0); }
double Ward::pdf_mix(const Vec3& wo, const Vec3& wi, double ps) const {
    return pdf_lobe_or_cosine(wo, wi, ps, [this](const Vec3& h) { return d_beckmann_aniso(h, ax, ay) * h.z; });
}

Rgb OrenNayar::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return lambert_f(rho) * oren_nayar_factor(wo, wi, oren_nayar_a(sigma), oren_nayar_b(sigma));
}
std::string OrenNayar::describe() const { return "oren_nayar(rho=" + fmt(rho) + " sigma=" + fmt(sigma) + ")"; }

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

}  // namespace shading
