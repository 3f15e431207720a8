// Thin geometry for the dipole finish: the diffusion profiles of a slab of finite thickness d
// (reflection R(r; d) at the face the light entered, transmission T(r; d) at the opposite
// face), from the multipole of Donner & Jensen, "Light Diffusion in Multi-Layered Translucent
// Materials", SIGGRAPH 2005, section 3 (their eqs. for R and T: dipole pairs mirrored across
// both extrapolated boundaries). Per colour channel, lengths in scene units like dipole.h.
// What Subsurface does with them (a lookup at a point of thickness d gathers the light that
// entered its own face with R and the light that entered the opposite face with T):
// shading/DIPOLE.md section "Thin geometry".
#pragma once

#include <functional>
#include <memory>

#include "shading/subsurface/dipole.h"

namespace shading {

class RdProfile;

// A slab's profile tables (made per thickness node in every render, SlabCache) call the
// multipole's image sums at every this many nodes only, the nodes between from the quintic
// Hermite of those (RdProfile's sample_every): the same tables to 1.3e-7 of the face's total,
// 5x fewer calls (SlabProfile.TablesSampledAtEveryFourthNodeAreTheFullTables).
constexpr int kSlabSampleEvery = 4;

// One channel of the multipole. Geometry (Donner & Jensen 2005 section 3, one extrapolation
// distance zb = 2 A D on both faces, D = 1/(3 sigma_t')): the slab fills 0 <= z <= d, the
// extrapolated boundaries lie at -zb and d + zb, L = d + 2 zb. The positive source sits at the
// mean depth of first scattering within the slab,
//     z0 = 1/sigma_t' - d / (exp(sigma_t' d) - 1)          (-> 1/sigma_t' = Jensen's zr as d -> inf),
// with the power scattered in the slab, alpha' (1 - exp(-sigma_t' d)); the rest passes without
// a (reduced) scattering event and is not diffuse light (not rendered by the finish). For
// d >> 1/sigma_t' this is Jensen's dipole source exactly; for d < 1/sigma_t' it keeps the
// source inside the slab, where diffusion has a meaning (a source at 1/sigma_t' beyond the back
// face would give a negative transmittance). Pairs i = -n..n:
//     z_r,i = 2 i L + z0,   z_v,i = 2 i L - z0 - 2 zb,
//     R(r) = P/(4 pi) sum_i [ z_r,i (1 + s d_r,i) e^{-s d_r,i} / d_r,i^3 - z_v,i (...) at d_v,i ],
//            d_.,i = sqrt(r^2 + z_.,i^2),
//     T(r) = P/(4 pi) sum_i [ (d - z_r,i) (1 + s d'_r,i) e^{-s d'_r,i} / d'_r,i^3 - (d - z_v,i) (...) ],
//            d'_.,i = sqrt(r^2 + (d - z_.,i)^2),
// s = sigma_tr. n is chosen per slab so the images reach three times past the profile's
// cutoff (slab_cutoff).
struct SlabChannel {
    double d = 0;        // thickness
    double power = 0;    // alpha' (1 - exp(-sigma_t' d))
    double z0 = 0;       // source depth
    double zb = 0;       // extrapolation distance 2 A D
    double sigma_tr = 0;
    double cutoff = 0;   // radius beyond which R and T are taken as 0 (slab_cutoff)
    int pairs = 0;       // image pairs summed term by term either side (the rest of each row: its integral)
    bool empty = true;

    static SlabChannel make(const DipoleChannel& ch, double d);
    double R(double r) const;  // per scene unit^2
    double T(double r) const;  // per scene unit^2, r the lateral distance from the entry point
    double image_sum(double r, bool opposite) const;  // R (false) or T (true)
    // Totals in closed form: the laterally integrated (1-D) diffusion equation with the same
    // source and Dirichlet conditions at both extrapolated boundaries, a = z0 + zb, b = L - a:
    //     R_total = P sinh(s b) cosh(s zb) / sinh(s L),  T_total = P sinh(s a) cosh(s zb) / sinh(s L)
    // (s -> 0: P b / L and P a / L). As d -> inf, R_total -> Jensen's (alpha'/2)(e^{-s zr} + e^{-s zv}).
    double R_total() const;
    double T_total() const;
};

// The three channels of one slab, and the two radial profiles a lookup integrates over the
// point cloud: R(s) at 3-D distance s on the same face, T(rho) of the lateral distance rho on
// the opposite face (PointCloud::far_exitance_sided).
struct SlabProfiles {
    double d = 0;
    Rgb R_total, T_total;
    std::shared_ptr<const RdProfile> same, transmit;
    // Empty: the finish's half-space exit factor for both faces (the multipole). Set by
    // make_exact_slab_profiles (exact_profile.h): pi L / M toward outside cosine cos_o of each
    // face (the tables' R and T faces where they cover the channel, else the model's
    // half-space factor).
    std::function<void(double cos_o, Rgb* same, Rgb* opposite)> exit;
    // Empty: light entering at outside cosine cos_i diffuses as into the half-space (the
    // multipole). Set by make_exact_slab_profiles: per channel, the tables' incidence factor of
    // the face light entering there leaves by (`same`: the face it entered, else the opposite
    // one) over the half-space's, whose factor the samples' light already holds (1 for channels
    // without tables). A thin slab scatters more of a slanted beam (0.5 mfp': 1.65x at 60
    // degrees) and passes less of it through a thick one (8 mfp': 0.67x): DIPOLE.md 6a.
    std::function<Rgb(double cos_i, bool same)> incidence;
    // Per channel: T leaves single scattering out (1; the exact tables' channels, made with
    // single_traced: the finish adds the slab's own single scattering) or holds every order (0).
    Rgb t_single_apart;
};
// `scale`: per channel, multiplies R (and its total): 1 for the dipole; for another half-space
// model (the exact profile) its total over the dipole's (RadialProfile::slab_profiles), so
// that R meets that model's half-space at the threshold. T is not scaled (it vanishes there anyway, and the
// multipole's T is within a few % of transport at high albedo where the dipole's total is not).
SlabProfiles make_slab_profiles(const Dipole& dipole, double d, const Rgb& scale = Rgb(1.0));

// The thickness above which a slab's totals differ from the semi-infinite medium's by less
// than `tolerance` of its total reflectance in every channel, (|R_total(d) - R_inf| + T_total(d)) / R_inf
// (both shrink with d: bisection in log d): the finish renders objects at least this thick as
// semi-infinite, exactly as without thin geometry. Scene units.
double slab_threshold(const Dipole& dipole, double tolerance = 0.005);
// The thickness above which a slab's total reflectance alone is within `tolerance` of the
// semi-infinite medium's in every channel, |R_total(d) - R_inf| / R_inf (at most
// slab_threshold's): where its far face is dark, such a slab's face is the half-space's.
double reflect_threshold(const Dipole& dipole, double tolerance = 0.005);
// The thickness above which a slab transmits less than `fraction` of the half-space's total
// reflectance in every channel, T_total(d) / R_inf (at least slab_threshold's for fractions
// below its tolerance). Scene units.
double transmit_threshold(const Dipole& dipole, double fraction);

}  // namespace shading
