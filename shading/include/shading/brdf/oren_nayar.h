// Oren & Nayar 1994, the qualitative model (their eq. 30) (src/brdf/oren_nayar.cpp).
#pragma once

#include <algorithm>
#include <string>

#include "shading/brdf/brdf.h"

namespace shading {

// The model's coefficients, sigma in radians.
inline double oren_nayar_a(double sigma) { double s2 = sigma * sigma; return 1.0 - 0.5 * s2 / (s2 + 0.33); }
inline double oren_nayar_b(double sigma) { double s2 = sigma * sigma; return 0.45 * s2 / (s2 + 0.09); }
// A + B max(0, cos(phi_i - phi_o)) sin(alpha) tan(beta), alpha = max(theta_i, theta_o),
// beta = min. Since sin(alpha) sin(beta) = sin_i sin_o and cos(beta) = max(cos_i, cos_o),
// this is A + B max(0, wi.xy . wo.xy) / max(cos_i, cos_o).
inline double oren_nayar_factor(const Vec3& wo, const Vec3& wi, double a, double b) {
    double c = std::max(0.0, wi.x * wo.x + wi.y * wo.y);
    // Both directions grazing: tan(beta) diverges; kCosFloor keeps the factor finite.
    return a + b * c / std::max(std::max(wi.z, wo.z), kCosFloor);
}

// f = rho/pi (A + B max(0, cos dphi) sin alpha tan beta).
struct OrenNayar final : Brdf {
    Rgb rho{0.5};
    double sigma = 0.3;  // slope-angle standard deviation, radians
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    std::string describe() const override;
    void write_spec(SpecWriter& w) const override;
};

}  // namespace shading
