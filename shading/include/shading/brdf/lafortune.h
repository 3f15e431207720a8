// Lafortune et al. 1997 generalized cosine lobes over a Lambertian base (src/brdf/lafortune.cpp).
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"

namespace shading {

// One lobe: max(0, Cx x_o x_i + Cy y_o y_i + Cz z_o z_i)^n.
inline double lafortune_lobe(const Vec3& wo, const Vec3& wi, double cx, double cy, double cz, double n) {
    double s = cx * wo.x * wi.x + cy * wo.y * wi.y + cz * wo.z * wi.z;
    return s > 0 ? std::pow(s, n) : 0.0;  // lobe clamped to 0 where the base is not positive
}

// f = kd/pi + sum_j w_j max(0, Cx x_o x_i + Cy y_o y_i + Cz z_o z_i)^n_j.
struct Lafortune final : Brdf {
    struct Lobe {
        double cx = -1, cy = -1, cz = 1, n = 20;
        Rgb weight{1.0};
    };
    Rgb kd{0.0};
    std::vector<Lobe> lobes;
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    Rgb lambert_base() const override { return kd; }
    bool anisotropic() const override;
    std::string describe() const override;
    void write_spec(SpecWriter& w) const override;
};

}  // namespace shading
