// POV-Ray's own highlights as BRDFs: `phong` (PhongPov) and `specular` (BlinnPov), each over
// POV's `diffuse` (src/brdf/pov_highlights.cpp).
//
// POV adds a highlight's contribution c per unit light colour with no cosine factor; as a BRDF
// that is f = c / (pi cos_i) (pov_weight() multiplies by pi cos_i again). Only cos_i divides,
// so neither model is reciprocal, and neither is energy conserving: they reproduce POV exactly.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

#include "shading/brdf/brdf.h"

namespace shading {

// POV phong (POV-Ray 3.7 Trace::ComputePhongColour): contribution P (R.L)^n per unit light
// colour, R = view direction mirrored about N, no cos factor. cos_rl = R.L.
inline double phong_pov_contribution(double cos_rl, double phong_size) {
    return cos_rl > 0 ? std::pow(cos_rl, phong_size) : 0.0;
}
// POV specular (Trace::ComputeSpecularColour): contribution S (N.H)^(1/r) per unit light colour.
inline double blinn_pov_contribution(double cos_h, double roughness) {
    return cos_h > 0 ? std::pow(cos_h, 1.0 / roughness) : 0.0;
}
// Contribution c (no cos) as a BRDF: c = pi f cos_i  =>  f = c / (pi cos_i).
inline double pov_contribution_to_f(double c, double cos_i) {
    // cos_i -> 0: POV's highlight does not fade at the horizon, so f ~ 1/cos_i diverges;
    // kCosFloor keeps f finite, and pi f cos_i still equals c for cos_i >= kCosFloor.
    return c / (kPi * std::max(cos_i, kCosFloor));
}

// PhongPov and BlinnPov share one shape but stay two classes, so that each f is branch-free.
// `phong P phong_size n` + `diffuse d`: f = d/pi + P (R.L)^n / (pi cos_i).
struct PhongPov final : Brdf {
    Rgb phong{1.0};
    double phong_size = 40;
    Rgb diffuse{0.0};
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    Rgb lambert_base() const override { return diffuse; }
    std::string describe() const override;
    void write_spec(SpecWriter& w) const override;
};

// `specular S roughness r` + `diffuse d`: f = d/pi + S (N.H)^(1/r) / (pi cos_i).
struct BlinnPov final : Brdf {
    Rgb specular{1.0};
    double roughness = 0.05;
    Rgb diffuse{0.0};
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    Rgb lambert_base() const override { return diffuse; }
    std::string describe() const override;
    void write_spec(SpecWriter& w) const override;
};

}  // namespace shading
