// Fresnel reflectance (fresnel.h). Equations: MODELS.md, "Fresnel".
#include "shading/fresnel.h"

#include <complex>

namespace shading {

double fresnel_dielectric(double cos_d, double eta) {
    // eta == 1: no interface, F == 0 everywhere (the formula below is 0/0 at grazing).
    if (eta == 1.0) return 0.0;
    cos_d = std::clamp(cos_d, -1.0, 1.0);  // rounding may put |cos| a few ulps past 1
    if (cos_d < 0) {                        // light on the transmitted side: swap the media
        eta = 1.0 / eta;
        cos_d = -cos_d;
    }
    // Snell: sin_t = sin_i / eta.
    double sin2_t = (1.0 - cos_d * cos_d) / (eta * eta);
    if (sin2_t >= 1.0) return 1.0;  // total internal reflection
    double cos_t = safe_sqrt(1.0 - sin2_t);
    double den_s = cos_d + eta * cos_t;
    double den_p = eta * cos_d + cos_t;
    // Both denominators vanish only when cos_d = cos_t = 0, i.e. grazing at the critical
    // angle (eta < 1): the limit there is total reflection.
    if (den_s <= 0 || den_p <= 0) return 1.0;
    double r_s = (cos_d - eta * cos_t) / den_s;  // s-polarised amplitude
    double r_p = (eta * cos_d - cos_t) / den_p;  // p-polarised amplitude
    return std::min(1.0, 0.5 * (r_s * r_s + r_p * r_p));
}

double fresnel_conductor(double cos_d, double n, double k) {
    // n + ik == 1: no interface (the formula is 0/0 at grazing).
    if (n == 1.0 && k == 0.0) return 0.0;
    cos_d = std::clamp(cos_d, 0.0, 1.0);  // light from inside a conductor is not modelled
    using C = std::complex<double>;
    const C eta(n, k);
    double sin2_i = 1.0 - cos_d * cos_d;
    C sin2_t = sin2_i / (eta * eta);
    C cos_t = std::sqrt(C(1.0) - sin2_t);  // principal root: transmitted wave decays
    C den_s = cos_d + eta * cos_t;
    C den_p = eta * cos_d + cos_t;
    // Denominators vanish only at grazing with eta == 1 (excluded above) or eta == 0
    // (perfect mirror): the limit is total reflection.
    if (std::norm(den_s) == 0.0 || std::norm(den_p) == 0.0) return 1.0;
    C r_s = (cos_d - eta * cos_t) / den_s;
    C r_p = (eta * cos_d - cos_t) / den_p;
    // |r| <= 1 analytically for Re(eta), Im(eta) >= 0; min() absorbs rounding.
    return std::min(1.0, 0.5 * (std::norm(r_s) + std::norm(r_p)));
}

Rgb fresnel_conductor(double cos_d, const Rgb& n, const Rgb& k) {
    return {fresnel_conductor(cos_d, n.r, k.r), fresnel_conductor(cos_d, n.g, k.g),
            fresnel_conductor(cos_d, n.b, k.b)};
}

}  // namespace shading
