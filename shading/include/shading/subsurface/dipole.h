// Dipole subsurface scattering (Jensen, Marschner, Levoy, Hanrahan, "A Practical Model for
// Subsurface Light Transport", SIGGRAPH 2001) plus the exact single-scattering term of a flat
// semi-infinite medium. See shading/DIPOLE.md for derivations, sources and validation.
//
// Conventions (in addition to vec.h):
//  * The medium lies below the surface (z < 0 in the local frame); wo, wi are OUTSIDE directions
//    leaving the surface (z > 0), as for Brdf::f.
//  * eta = n_medium / n_outside (relative index; > 1 for a material in air).
//  * Coefficients sigma_s, sigma_a are in 1/mm in Medium (the unit of every published table).
//    Dipole works in SCENE units: it multiplies them by Medium::mm_per_unit, so radii passed to
//    it and returned by it are in scene units, Rd(r) is per scene-unit^2, and the dimensionless
//    totals do not depend on the unit.
//  * BRDF-like terms return 1/sr and EXCLUDE cos(theta_i), like Brdf::f; POV's pi is applied
//    by pov_weight() in brdf.h.
//  * Every value returned is finite and non-negative for valid media (Medium::validate).
#pragma once

#include <array>
#include <string>

#include "shading/brdf/brdf.h"
#include "shading/brdf/fresnel.h"  // fresnel_dielectric (exact, unpolarised)
#include "shading/core/vec.h"

namespace shading {

// ---------------------------------------------------------------------------------------------
// Scalar formulas (one colour channel). Each reads like the equation it names.

// Fresnel transmittance Ft = 1 - Fr of fresnel.h's exact dielectric reflectance; cos_i >= 0 on
// the side the light comes from, eta = n_transmitted / n_incident.
inline double fresnel_transmittance(double cos_i, double eta) {
    return 1.0 - fresnel_dielectric(cos_i, eta);
}
// Cosine of the refracted angle (Snell); 0 under total internal reflection.
double refracted_cos(double cos_i, double eta);

// Internal diffuse Fresnel reflectance Fdr of a medium of relative index eta (light inside,
// hitting the boundary from below, cosine-weighted over the hemisphere).
// Polynomial fits, as used by the dipole literature:
//   eta >= 1: Jensen 2001 (Egan & Hilgeman 1973): Fdr = -1.440/eta^2 + 0.710/eta + 0.668 + 0.0636 eta
//   eta <  1: d'Eon & Irving 2011 fit of Fdr(1/eta) for the reciprocal index (the inside is the
//             optically thinner side, no total internal reflection).
//   eta == 1 exactly: 0 (no interface; the eta>=1 fit gives 0.0016 there, a fit residual).
double fresnel_diffuse_reflectance_fit(double eta);
// The same quantity by quadrature of fresnel_dielectric (relative error < 1e-10): once per
// medium, never per pixel.
double fresnel_diffuse_reflectance_exact(double eta);
// Where the fits hold (within 2e-3 of the exact Fdr; DIPOLE.md 2 has the table). Outside, the
// eta >= 1 polynomial passes 1 at eta 3.87, where A = (1 + Fdr) / (1 - Fdr) changes sign and
// every pixel of the dipole would be NaN.
constexpr double kFdrFitMinEta = 0.5, kFdrFitMaxEta = 2.0;

// Henyey-Greenstein phase function p(cos) in 1/sr, cos = cosine between the propagation
// directions before and after scattering. |g| = 1 is a delta: it has no finite density and
// returns 0 (a measure-zero direction set).
double henyey_greenstein(double cos_theta, double g);

// Jensen 2001 total diffuse reflectance of the dipole, closed form:
//   Rd = (alpha'/2) (1 + exp(-(4/3) A sqrt(3(1-alpha')))) exp(-sqrt(3(1-alpha')))
double dipole_total_reflectance(double alpha_prime, double A);

enum class FdrModel {
    JensenFit,  // fresnel_diffuse_reflectance_fit inside [kFdrFitMinEta, kFdrFitMaxEta] (reproduces
                // Jensen 2001's Table 2 numbers), the exact quadrature outside it
    Exact,      // fresnel_diffuse_reflectance_exact everywhere: continuous in eta, exact at eta = 1
};
// Fdr as a DipoleChannel uses it: the fit where it holds (JensenFit), the exact value elsewhere.
double fresnel_diffuse_reflectance(double eta, FdrModel fdr);

// The relative index a Medium may have (Medium::validate): real materials in air are 1 to about
// 4, a medium inside a denser one (a bubble, ice in glass) above about 0.25; the bounds leave
// room on both sides and keep A = (1 + Fdr) / (1 - Fdr) below 600 (eta 10: Fdr 0.9964, A 555).
constexpr double kMinEta = 0.1, kMaxEta = 10.0;

// One channel of the dipole, lengths in whatever unit the coefficients are per.
struct DipoleChannel {
    double sigma_s_prime = 0;  // reduced scattering sigma_s (1 - g)
    double sigma_a = 0;
    double sigma_t_prime = 0;  // sigma_s' + sigma_a
    double alpha_prime = 0;    // reduced albedo sigma_s' / sigma_t'
    double sigma_tr = 0;       // effective transport coefficient sqrt(3 sigma_a sigma_t')
    double Fdr = 0;            // internal diffuse Fresnel reflectance
    double A = 1;              // boundary mismatch (1 + Fdr) / (1 - Fdr)
    double zr = 0;             // real source depth 1 / sigma_t'
    double zv = 0;             // virtual source height zr (1 + 4A/3)
    bool empty = true;         // sigma_t' == 0 or sigma_s' == 0: no diffuse reflectance at all

    static DipoleChannel make(double sigma_s_prime, double sigma_a, double eta,
                              FdrModel fdr = FdrModel::JensenFit);
    // Jensen 2001 eq. 5: radiant exitance at distance r per unit incident flux (1/length^2).
    double rd(double r) const;
    // Integral of Rd over the disc of radius R around the entry point, closed form:
    //   P(R) = sum_{z in zr,zv} (alpha'/2) (exp(-sigma_tr z) - z exp(-sigma_tr d(R)) / d(R)),
    //   d(R) = sqrt(R^2 + z^2).  P(inf) = dipole_total_reflectance.
    double rd_disc(double R) const;
    // Total diffuse reflectance (closed form; equals rd_disc(inf)).
    double rd_total() const;
    // Smallest R with rd_disc(R) >= fraction * rd_total (fraction in (0,1)); 0 if empty.
    double radius_containing(double fraction) const;
};

// ---------------------------------------------------------------------------------------------
// Medium description and RGB dipole.

struct Medium {
    Rgb sigma_s;          // scattering coefficient, 1/mm
    Rgb sigma_a;          // absorption coefficient, 1/mm
    Rgb g;                // Henyey-Greenstein asymmetry, [-1, 1]
    double eta = 1.3;     // n_medium / n_outside
    double mm_per_unit = 1.0;  // length of one scene unit in mm (1 unit = 1 cm -> 10)

    // Medium given by reduced scattering only (Jensen 2001 Table 2): g = 0, sigma_s = sigma_s'.
    static Medium from_reduced(const Rgb& sigma_s_prime, const Rgb& sigma_a, double eta,
                               double mm_per_unit = 1.0);

    Rgb sigma_s_prime() const;  // sigma_s (1 - g), 1/mm
    Rgb sigma_t() const;        // sigma_s + sigma_a, 1/mm
    // Coefficients per scene unit: sigma [1/mm] * mm_per_unit [mm/unit].
    Rgb sigma_s_per_unit() const { return sigma_s * mm_per_unit; }
    Rgb sigma_a_per_unit() const { return sigma_a * mm_per_unit; }
    Rgb sigma_s_prime_per_unit() const { return sigma_s_prime() * mm_per_unit; }
    // Empty string if valid, else a message naming the first offending field and its range:
    // mm_per_unit finite > 0, eta in [kMinEta, kMaxEta], sigma finite >= 0 with
    // sigma * mm_per_unit <= 1e100, g in [-1, 1].
    std::string validate() const;
};

class Dipole {
public:
    // Throws std::invalid_argument with Medium::validate()'s message on invalid media.
    explicit Dipole(const Medium& m, FdrModel fdr = FdrModel::JensenFit);

    const Medium& medium() const { return medium_; }
    const DipoleChannel& channel(int c) const { return ch_[c]; }

    // Jensen 2001 eq. 5 per channel, r in scene units, result per scene-unit^2.
    Rgb rd(double r) const;
    // Integral of Rd over a disc of radius R (scene units) around the entry point.
    Rgb rd_disc(double R) const;
    // Total diffuse reflectance (closed form), dimensionless.
    Rgb rd_total() const;
    // Regularised contribution of a surface sample of `area` (scene units^2) whose centre lies at
    // distance r from the entry point: area times the mean of Rd over the annulus
    // [max(0, r - rs), r + rs], rs = sqrt(area / pi). Exact (= rd_disc(rs)) for the sample
    // containing the entry point (r = 0), -> rd(r) * area for r >> rs, continuous and bounded.
    Rgb rd_sample(double r, double area) const;
    // Radius (scene units) per channel containing `fraction` of the total diffuse reflectance.
    Rgb radius_containing(double fraction) const;

    // Jensen 2001 eq. 4, diffusion BSSRDF S_d = (1/pi) Ft(eta, wi) Rd(r) Ft(eta, wo), per sr per
    // scene-unit^2; cos_i, cos_o are outside cosines at the entry and exit points.
    Rgb bssrdf(double r, double cos_i, double cos_o) const;
    // S_d integrated over the entry points of a uniformly lit flat surface: the far-field BRDF
    // (1/pi) Ft(wi) Rd_total Ft(wo), 1/sr, cos_i excluded. Zero below the horizon.
    Rgb diffusion_brdf(const Vec3& wo, const Vec3& wi) const;
    // Exact single scattering of a flat semi-infinite medium lit by a distant source, as a BRDF
    // (1/sr, cos_i excluded, zero below the horizon):
    //   f_ss = (sigma_s/sigma_t) Ft(wi) Ft(wo) p(ti . to) / (eta^2 (|cos ti| + |cos to|))
    // with ti, to the refracted propagation directions inside (DIPOLE.md derives it; the eta^2 is
    // the radiance change across the boundary, checked against the Monte Carlo reference).
    Rgb single_scatter_brdf(const Vec3& wo, const Vec3& wi) const;
    // The same for a flat slab of thickness d (scene units), in the frame of the face seen (z its
    // outward normal, wo.z > 0): light on that face (wi.z > 0) is reflected, light entering the
    // far face (wi.z < 0: wi the direction to the light from the far face, |wi.z| its cosine
    // there) transmitted. Exact single scattering of the flat slab with Fresnel faces: the
    // incident beam and the ray toward the eye each reflected between the faces any number of
    // times (geometric series), each scattering with the phase of its own angle (DIPOLE.md 5a).
    // d -> infinity gives single_scatter_brdf; eta 1 reflects f_ss (1 - e^(-tau (1/mu_i +
    // 1/mu_o))) and transmits (sigma_s/sigma_t) p (e^(-tau/mu_o) - e^(-tau/mu_i)) / (mu_o - mu_i),
    // tau = sigma_t d, mu the refracted cosines.
    Rgb single_scatter_slab(const Vec3& wo, const Vec3& wi, double d) const;

private:
    Medium medium_;
    std::array<DipoleChannel, 3> ch_;
};

// The dipole as a far-field BRDF (diffusion + single scattering) under the Brdf interface, for
// surfaces whose scattering radius is below the pixel footprint.
class SubsurfaceBrdf : public Brdf {
public:
    explicit SubsurfaceBrdf(const Medium& m, FdrModel fdr = FdrModel::JensenFit) : dipole_(m, fdr) {}
    Rgb f(const Vec3& wo, const Vec3& wi) const override {
        return dipole_.diffusion_brdf(wo, wi) + dipole_.single_scatter_brdf(wo, wi);
    }
    std::string describe() const override;
    const Dipole& dipole() const { return dipole_; }

private:
    Dipole dipole_;
};

}  // namespace shading
