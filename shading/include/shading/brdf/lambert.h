// The Lambertian diffuse reflector (src/brdf/lambert.cpp).
#pragma once

#include <string>

#include "shading/brdf/brdf.h"

namespace shading {

// f = rho / pi, albedo rho in [0, 1] per channel.
struct Lambert final : Brdf {
    Rgb rho{0.5};
    Lambert() = default;
    explicit Lambert(const Rgb& rho_) : rho(rho_) {}
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    Rgb lambert_base() const override { return rho; }
    std::string describe() const override;
    void write_spec(SpecWriter& w) const override;
};

}  // namespace shading
