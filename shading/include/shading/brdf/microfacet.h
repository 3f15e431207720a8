// Microfacet BRDFs: normal distributions D, masking-shadowing G, Fresnel F, in two forms.
//
//  * SURVEY form (Blinn 1977 as collected in the BRDF surveys): intensity
//        i = rho_s * D * G * F / (N.V)
//    with the UNNORMALISED D1..D4 below (peak value 1, or 1/m^2 for Beckmann), rendered like
//    POV's own highlights: POV adds i * lightcolour, so f = i / (pi * N.L).
//  * NORMALISED form (Cook-Torrance / Walter et al. 2007):
//        f = rho_s * D * G * F / (4 (N.L)(N.V)),   with  integral D(h) (N.h) dw_h = 1.
//  Either form may sit on a Lambertian base kd / pi.
//
// Conventions: brdf.h. Equations, parameter mapping and limits: MODELS.md 2.5 and 3.
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"
#include "shading/brdf/fresnel.h"

namespace shading {

// ---------------------------------------------------------------- survey D (unnormalised)
// cos_h = N.H = cos(alpha). Each returns 0 for cos_h <= 0 (microfacet facing away).

// D1, Blinn 1977 (Phong-like): cos^n1(alpha).
inline double d1_blinn(double cos_h, double n1) { return cos_h > 0 ? std::pow(cos_h, n1) : 0.0; }
// D2, Gaussian (Torrance-Sparrow 1967 / Blinn 1977): exp(-(alpha * n2)^2), alpha in radians.
inline double d2_gaussian(double cos_h, double n2) {
    if (cos_h <= 0) return 0.0;
    double a = safe_acos(cos_h) * n2;
    return std::exp(-a * a);
}
// D3, Trowbridge-Reitz 1975 (Blinn 1977 form): (n3^2 / (cos^2 alpha (n3^2 - 1) + 1))^2.
inline double d3_trowbridge_reitz(double cos_h, double n3) {
    if (cos_h <= 0) return 0.0;
    double c2 = n3 * n3, cos2 = cos_h * cos_h;
    // cos^2 (c2 - 1) + 1 written as c2 cos^2 + sin^2: a sum of non-negatives, >= min(c2, 1) > 0.
    double den = c2 * cos2 + std::max(0.0, 1.0 - cos2);
    return sqr(c2 / den);
}
// D4, Beckmann 1963: exp(-tan^2 alpha / m^2) / (m^2 cos^4 alpha).
inline double d4_beckmann(double cos_h, double m) {
    if (cos_h <= 0) return 0.0;
    double cos2 = cos_h * cos_h;
    double e = std::exp(-std::max(0.0, 1.0 - cos2) / cos2 / (m * m));
    // Far tail: exp underflowed; returning early also avoids 0 * Inf when cos^4 underflows.
    if (e == 0.0) return 0.0;
    return e / (m * m * cos2 * cos2);
}

// ---------------------------------------------------------------- normalised D
// Each satisfies integral over the hemisphere of D(h) cos(theta_h) dw_h = 1.

// Normalised Blinn-Phong: (n + 2) / (2 pi) cos^n(alpha).
inline double d_blinn(double cos_h, double n) { return (n + 2.0) / (2.0 * kPi) * d1_blinn(cos_h, n); }
// Normalised Trowbridge-Reitz / GGX (Walter et al. 2007): a^2 / (pi cos^4 (a^2 + tan^2)^2)
// = a^2 / (pi (a^2 cos^2 + sin^2)^2) = D3(a) / (pi a^2).
inline double d_trowbridge_reitz(double cos_h, double alpha) {
    return d3_trowbridge_reitz(cos_h, alpha) / (kPi * alpha * alpha);
}
// Normalised Beckmann: exp(-tan^2 / m^2) / (pi m^2 cos^4) = D4(m) / pi.
inline double d_beckmann(double cos_h, double m) { return d4_beckmann(cos_h, m) * kInvPi; }
// Normalisation constant of the Gaussian: 1 / (2 pi int_0^{pi/2} exp(-(a n2)^2) cos a sin a da),
// computed by Gauss-Legendre quadrature (no elementary closed form; MODELS.md gives the
// asymptote n2^2/pi (1 + 2/(3 n2^2)) for large n2).
double gaussian_norm(double n2);
// Anisotropic Beckmann (Ward's lobe), unit h: exp(-(hx^2/ax^2 + hy^2/ay^2) / hz^2) / (pi ax ay hz^4).
inline double d_beckmann_aniso(const Vec3& h, double ax, double ay) {
    if (h.z <= 0) return 0.0;
    double hz2 = h.z * h.z;
    double e = std::exp(-(sqr(h.x / ax) + sqr(h.y / ay)) / hz2);
    if (e == 0.0) return 0.0;  // far tail underflowed; avoids 0 * Inf when hz^4 underflows
    return e / (kPi * ax * ay * hz2 * hz2);
}

// ---------------------------------------------------------------- equal-roughness mapping
// Native parameter of each D from a Beckmann roughness m (MODELS.md, "Equal roughness").
// Blinn: equal peak D(N) = 1/(pi m^2) (Walter et al. 2007): n = 2/m^2 - 2.
inline double blinn_n_from_m(double m) { return 2.0 / (m * m) - 2.0; }
inline double m_from_blinn_n(double n) { return std::sqrt(2.0 / (n + 2.0)); }
// Gaussian: equal slope variance <tan^2 alpha> = m^2 to leading order in m: n2 = 1/m.
inline double gaussian_n2_from_m(double m) { return 1.0 / m; }
inline double m_from_gaussian_n2(double n2) { return 1.0 / n2; }
// Trowbridge-Reitz / GGX: equal peak D(N) = 1/(pi m^2): alpha = m.
inline double tr_alpha_from_m(double m) { return m; }

// ---------------------------------------------------------------- masking-shadowing G

// V-cavity (Torrance-Sparrow 1967, Blinn 1977):
// min(1, 2 (N.H)(N.V)/(V.H), 2 (N.H)(N.L)/(V.H)). The denominator is safe without a floor:
// for a reflection pair V.H = L.H = |V + L| / 2 >= (N.V + N.L) / 2 > 0, so the ratio is finite
// and G in [0, 1]. (Unlike Smith, G -> 1 at the grazing mirror pair; see MODELS.md.)
inline double g_vcavity(double nh, double nv, double nl, double vh) {
    if (vh <= 0) return 0.0;  // back-facing microfacet: not part of a reflection pair
    return std::min(1.0, 2.0 * nh * std::min(nv, nl) / vh);
}
// Smith Lambda for Beckmann (exact; Walter et al. 2007 sec. 5.1): a = 1/(m tan theta),
// Lambda = (erf(a) - 1)/2 + exp(-a^2)/(2 a sqrt(pi)). Written with erfc for accuracy at large a.
inline double smith_lambda_beckmann(const Vec3& w, double m) {
    double s2 = sin2_theta(w);
    if (s2 == 0.0) return 0.0;  // along the normal nothing is masked
    double a = std::abs(w.z) / (std::sqrt(s2) * m);
    // Grazing (a -> 0): Lambda -> Inf and G = 1/(1 + Lambda...) -> 0, the right limit.
    if (a == 0.0) return std::numeric_limits<double>::infinity();
    return 0.5 * (std::exp(-a * a) / (a * std::sqrt(kPi)) - std::erfc(a));
}
// Smith Lambda for Trowbridge-Reitz / GGX (exact): (-1 + sqrt(1 + alpha^2 tan^2 theta)) / 2.
inline double smith_lambda_ggx(const Vec3& w, double alpha) {
    double c2 = cos2_theta(w);
    if (c2 == 0.0) return std::numeric_limits<double>::infinity();  // grazing: fully masked
    return 0.5 * (std::sqrt(1.0 + alpha * alpha * sin2_theta(w) / c2) - 1.0);
}
// Height-correlated Smith masking-shadowing (Heitz 2014 eq. 99): 1 / (1 + Lambda(wo) + Lambda(wi)).
inline double g_smith(double lambda_o, double lambda_i) { return 1.0 / (1.0 + lambda_o + lambda_i); }
// Smith masking of one direction: 1 / (1 + Lambda(w)).
inline double g1_smith(double lambda) { return 1.0 / (1.0 + lambda); }

// Exact Smith Lambda of any isotropic normalised D, tabulated once (used for Blinn and
// Gaussian, which have no closed form). From the projected-area identity (Heitz 2014 eq. 12)
//     Lambda(wo) cos(theta_o) = integral D(h) max(0, -wo.h) dw_h,
// with the phi_h integral in closed form (MODELS.md), leaving a 1-D integral over theta_h.
// Tabulated as g = Lambda * a against u = atan(a), a = cot(theta_o) / m_scale (Beckmann's
// variable), linear in u; Lambda = g / a.
class SmithLambdaTable {
public:
    // d_normalized(cos_h): the normalised D; m_scale: its Beckmann-equivalent roughness;
    // theta_max: D is negligible (< 1e-28 of its peak) for theta_h beyond it.
    SmithLambdaTable(const std::function<double(double)>& d_normalized, double m_scale, double theta_max);
    double lambda(const Vec3& w) const;

private:
    static constexpr int kNodes = 256;
    double m_;
    std::vector<double> g_;  // kNodes + 1 values at u = i (pi/2) / kNodes
};

// ---------------------------------------------------------------- sampling half vectors
// Each maps (u1, u2) in [0,1)^2 to a unit h with density D(h) cos(theta_h) per solid angle.

// Blinn: cos theta = (1 - u1)^(1/(n+2)), phi = 2 pi u2.
Vec3 sample_blinn(double n, double u1, double u2);
// GGX: tan^2 theta = alpha^2 u1 / (1 - u1), phi = 2 pi u2.
Vec3 sample_ggx(double alpha, double u1, double u2);
// Anisotropic Beckmann via its Gaussian slope distribution (Box-Muller):
// slope = sqrt(-ln(1-u1)) (ax cos 2pi u2, ay sin 2pi u2), h = normalize(-slope, 1).
Vec3 sample_beckmann_aniso(double ax, double ay, double u1, double u2);

// ---------------------------------------------------------------- lobe + diffuse mixtures
// Shared by Microfacet and Ward: with probability ps a half vector h from `sample_h(u1', u2)`
// (density D(h) cos theta_h) mirrored about h, otherwise cosine-weighted for a diffuse base.
// No sample (zero vector) when wo is below the surface or the mirrored direction is.
template <class SampleH>
Vec3 sample_lobe_or_cosine(const Vec3& wo, double u1, double u2, double ps, const SampleH& sample_h) {
    if (wo.z <= 0) return {};
    if (u1 < ps) {
        const Vec3 wi = reflect_about(wo, sample_h(std::min(u1 / ps, kOneMinusEps), u2));
        return wi.z > 0 ? wi : Vec3();  // mirrored below the horizon (includes V.h < 0)
    }
    const double v = std::min((u1 - ps) / (1.0 - ps), kOneMinusEps), r = std::sqrt(v), phi = 2.0 * kPi * u2;
    return {r * std::cos(phi), r * std::sin(phi), std::sqrt(1.0 - v)};
}
// Its density per solid angle of wi: ps D(h)(N.h) / (4 V.h) + (1 - ps) cos_i / pi, with
// `d_cos(h)` = D(h) (N.h); dw_h/dw_i = 1/(4 V.h), V.h >= (N.V + N.L)/2 > 0 above the surface.
template <class DCos>
double pdf_lobe_or_cosine(const Vec3& wo, const Vec3& wi, double ps, const DCos& d_cos) {
    if (wo.z <= 0 || wi.z <= 0) return 0.0;
    const Vec3 h = half_vector(wo, wi);
    return ps * d_cos(h) / (4.0 * dot(wo, h)) + (1.0 - ps) * wi.z * kInvPi;
}
// Probability of the lobe branch: in proportion to the average albedos (1 if both are 0).
inline double lobe_probability(const Rgb& specular, const Rgb& diffuse) {
    const double ws = specular.average(), wd = diffuse.average();
    return ws + wd > 0 ? ws / (ws + wd) : 1.0;
}

// ---------------------------------------------------------------- one D term with its parameter

enum class DKind { Blinn, Gaussian, TrowbridgeReitz, Beckmann };

class NormalDistribution {
public:
    // `param` is the native parameter: Blinn n1 >= 0, Gaussian n2 > 0, TR alpha (n3) > 0,
    // Beckmann m > 0.
    NormalDistribution(DKind kind, double param);
    // From a Beckmann-equivalent roughness m via the mapping above.
    static NormalDistribution from_m(DKind kind, double m);

    DKind kind() const { return kind_; }
    double param() const { return param_; }
    // Beckmann roughness this D corresponds to (inverse of from_m).
    double m_equivalent() const;
    const char* name() const;

    double survey(double cos_h) const;      // D1..D4, unnormalised
    double normalized(double cos_h) const;  // integral D cos dw = 1
    // Exact Smith Lambda: closed form for TR and Beckmann, SmithLambdaTable for Blinn and
    // Gaussian.
    double smith_lambda(const Vec3& w) const;
    // Beckmann Lambda at m_equivalent(): the classic approximation for Blinn and Gaussian
    // (Walter et al. 2007). Exact only for Beckmann; NOT energy conserving at grazing for
    // broad Blinn/Gaussian lobes (MODELS.md gives the measured excess).
    double smith_lambda_beckmann_equivalent(const Vec3& w) const;
    // Unit half vector with density normalized(h.z) * h.z.
    Vec3 sample_h(double u1, double u2) const;
    // The m that from_m() was given, 0 if built from the native parameter: a spec writes
    // that m back (m_equivalent() need not return it to the bit).
    double given_m() const { return given_m_; }
    // "m" for Beckmann, else the native parameter's key: "n1", "n2", "n3".
    const char* native_key() const;

private:
    struct GaussianTable;
    DKind kind_;
    double param_;
    double given_m_ = 0;
    double norm_ = 1.0;  // Gaussian normalisation constant (gaussian_norm)
    std::shared_ptr<const GaussianTable> table_;
    std::shared_ptr<const SmithLambdaTable> smith_;  // Blinn and Gaussian only
};

// ---------------------------------------------------------------- the model

// Smith: exact height-correlated Smith for every D. (Beckmann's Lambda at the equivalent m
// for every D, the classic shortcut, is not offered: it breaks energy conservation near
// grazing, MODELS.md 3.4.)
enum class GKind { VCavity, Smith };
enum class FKind { None, Dielectric, Conductor, Schlick };
enum class MicrofacetForm { Survey, Normalized };

struct FresnelTerm {
    FKind kind = FKind::None;
    double eta = 1.5;     // dielectric: n_inside / n_outside
    Rgb n{1.5}, k{0.0};   // conductor: complex index n + i k per channel
    Rgb f0{0.04};         // Schlick: reflectance at normal incidence
    Rgb eval(double cos_d) const;
    std::string describe() const;
    void write_spec(SpecWriter& w) const;  // "f=... [its keys]"
};

struct Microfacet final : Brdf {
    MicrofacetForm form = MicrofacetForm::Normalized;
    NormalDistribution d{DKind::Beckmann, 0.3};
    GKind g = GKind::Smith;
    FresnelTerm fresnel;
    Rgb rho_s{1.0};  // specular scale
    Rgb kd{0.0};     // Lambertian base albedo

    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    std::string describe() const override;
    void write_spec(SpecWriter& w) const override;
    double geometry(const Vec3& wo, const Vec3& wi, const Vec3& h) const;
    // Smith: Lambda(wo) once per viewer (the lights of a shading point share it).
    void prepare_view(const Vec3& wo, BrdfViewCache* cache) const override;
    Rgb f_view(const Vec3& wo, const Vec3& wi, const BrdfViewCache& cache) const override;

    Rgb lambert_base() const override { return kd; }

    // Importance sampling (both forms): the normalised D(h) cos(theta_h), mirrored about h,
    // mixed with cosine sampling of the diffuse base in proportion kd : rho_s (averages).
    // Returns wi, or the zero vector when the mirrored direction is below the surface.
    Vec3 sample(const Vec3& wo, double u1, double u2) const override;
    // Density of sample() per solid angle of wi: D(h)(N.h) / (4 V.h) mixed with cos_i/pi.
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    // The specular lobe alone (probability 1 for the D-sampled branch).
    Vec3 sample_glossy(const Vec3& wo, double u1, double u2) const override;
    double pdf_glossy(const Vec3& wo, const Vec3& wi) const override;
    // Probability that sample() picks the specular lobe.
    double specular_probability() const;

private:
    Vec3 sample_mix(const Vec3& wo, double u1, double u2, double ps) const;
    double pdf_mix(const Vec3& wo, const Vec3& wi, double ps) const;
    // f with the Smith Lambda of wo given (nullptr: computed here).
    Rgb f_lambda(const Vec3& wo, const Vec3& wi, const double* lambda_o) const;
};

}  // namespace shading
