// Fresnel reflectance: exact unpolarised dielectric and conductor formulas, and Schlick's
// approximation. All take cos_d = cosine between the incident direction and the (micro)normal.
// Equations and limits: shading/MODELS.md, section "Fresnel".
#pragma once

#include "shading/core/vec.h"

namespace shading {

// Exact unpolarised Fresnel reflectance of a dielectric interface (Born & Wolf; pbrt-v4 FrDielectric).
// eta = n_transmitted / n_incident (> 0). cos_d < 0 means the light arrives from the
// transmitted side, handled by swapping the media. Total internal reflection returns 1.
// eta == 1 returns 0 at every angle (no interface).
double fresnel_dielectric(double cos_d, double eta);

// Exact unpolarised Fresnel reflectance at a conductor, complex eta = n + i k
// (Born & Wolf; pbrt-v4 FrComplex). k = 0 reproduces fresnel_dielectric for cos_d >= 0.
double fresnel_conductor(double cos_d, double n, double k);
// Per RGB channel.
Rgb fresnel_conductor(double cos_d, const Rgb& n, const Rgb& k);

// Schlick 1994: F = F0 + (1 - F0)(1 - cos_d)^5, cos_d clamped to [0, 1].
inline double fresnel_schlick(double cos_d, double f0) {
    double m = 1.0 - std::clamp(cos_d, 0.0, 1.0);  // rounding may put |cos| a few ulps past 1
    double m2 = m * m;
    return f0 + (1.0 - f0) * m2 * m2 * m;
}
inline Rgb fresnel_schlick(double cos_d, const Rgb& f0) {
    return {fresnel_schlick(cos_d, f0.r), fresnel_schlick(cos_d, f0.g), fresnel_schlick(cos_d, f0.b)};
}

// Normal-incidence reflectance of a dielectric: F0 = ((eta - 1) / (eta + 1))^2.
inline double f0_from_eta(double eta) { return sqr((eta - 1.0) / (eta + 1.0)); }
// Normal-incidence reflectance of a conductor: ((n-1)^2 + k^2) / ((n+1)^2 + k^2).
inline double f0_from_conductor(double n, double k) {
    return (sqr(n - 1.0) + k * k) / (sqr(n + 1.0) + k * k);
}

}  // namespace shading
