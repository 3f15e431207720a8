// The BRDF interface every model implements, and the one place POV's pi enters.
#pragma once

#include <memory>
#include <string>

#include "shading/vec.h"

namespace shading {

class Brdf {
public:
    virtual ~Brdf() = default;
    // BRDF value in 1/sr, cos(theta_i) EXCLUDED; wo, wi in the local frame (see vec.h).
    // Must return finite, non-negative values for every pair of unit vectors,
    // and zero when either direction is below the surface (z <= 0).
    virtual Rgb f(const Vec3& wo, const Vec3& wi) const = 0;
    // True if the model depends on the azimuth of the tangent frame (needs +x).
    virtual bool anisotropic() const { return false; }
    // Short human-readable description with parameters, e.g. "lambert(rho=0.5)".
    virtual std::string describe() const = 0;
};

using BrdfPtr = std::shared_ptr<const Brdf>;

// POV-Ray's light contribution factor for one light of colour c:
// pixel += pov_weight(...) * c. POV's pixel values are pi x radiance and its light
// colour is irradiance at normal incidence, so radiance f*cos*E becomes pi*f*cos.
// A Lambert BRDF rho/pi thus contributes rho*cos, exactly like `diffuse rho`.
inline Rgb pov_weight(const Brdf& brdf, const Vec3& wo, const Vec3& wi) {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return brdf.f(wo, wi) * (kPi * wi.z);
}

}  // namespace shading
