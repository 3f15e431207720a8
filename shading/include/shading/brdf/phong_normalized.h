// Energy-normalised modified Phong (Lafortune & Willems 1994) (src/brdf/phong_normalized.cpp).
#pragma once

#include <cmath>
#include <string>

#include "shading/brdf/brdf.h"

namespace shading {

// The normalised lobe ks (n+2)/(2 pi) cos^n(alpha), alpha between wi and the mirror
// direction of wo; this returns it for ks = 1.
inline double modified_phong_lobe(double cos_alpha, double n) {
    return cos_alpha > 0 ? (n + 2.0) / (2.0 * kPi) * std::pow(cos_alpha, n) : 0.0;
}

// f = kd/pi + ks (n+2)/(2 pi) cos^n(alpha). Reciprocal; albedo <= kd + ks.
struct PhongNormalized final : Brdf {
    Rgb kd{0.0}, ks{0.5};
    double n = 20;
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    Rgb lambert_base() const override { return kd; }
    std::string describe() const override;
    void write_spec(SpecWriter& w) const override;
};

}  // namespace shading
