// The exact profile on a curved surface: a first-order correction of multiple scattering's
// exitance for the surface's mean curvature (shading/DIPOLE.md 6d).
//
// The exact profile is the flat half-space's. Under a convex face, light inside meets the
// boundary closer to its normal than under a flat one (a ray from depth z below a sphere of
// radius R at angle a to the radial direction crosses the surface at sin t = (1 - z/R) sin a),
// so less of it is turned back by total internal reflection and more leaves; under a concave
// face, less. And light that spreads a diffusion length or more along a curved face finds less
// medium around it than the half-space gives it. The random walk (exact transport in the
// object's shape) measures both, to first order in the mean curvature H, as the flat profile's
// multiple scattering being short by c(eta, alpha') mfp' H, mfp' = 1 / sigma_t': about
// 0.8 mfp' / R at eta 1.3, growing with eta, and at eta 1 near 0 (slightly negative where the
// albedo is high: taken as 0). Subsurface::radiance multiplies the profile's exitance by
// 1 + c mfp' H per channel, within 1 -+ kMaxCurvatureGain.
#pragma once

namespace shading {

// c(eta, alpha'), alpha' the channel's reduced albedo sigma_s' / sigma_t': measured on a grid of
// eta in [1, 2] (the exact profile's range) and alpha' in [0.4, 0.995], bilinear between its
// nodes and held beyond them (below alpha' 0.4 multiple scattering is under a third of the
// light, and its measurement noisier than its value); never below 0 (curvature.cpp).
double curvature_coefficient(double eta, double albedo);

// The table is measured for isotropic scattering (g = 0). With forward scattering the flat
// profile's error on a sphere is another (ior 1.3, radius 15 mfp': c falls to 0.66-0.91 of
// g 0's at g 0.25, to -0.3 ... 0.94 of it at g 0.5, and at g 0.9 the profile is too bright by up
// to 4 % whatever the curvature term says), so c is weighted by 1 - (g / kCurvatureGMax)^2,
// nothing from kCurvatureGMax up: a fit to those means (shading/DIPOLE.md 6d).
constexpr double kCurvatureGMax = 0.6;
double curvature_anisotropy_weight(double g);

// The correction's largest size either way: beyond mfp' / R of about 0.15 the walk's excess
// over the profile stops growing with it (Skin1 at ior 1.3: 13 % at mfp' / R 0.26, where the
// first-order term says 25 %), and on a crease or a small bump the estimated curvature stands
// for a corner no first-order term describes.
constexpr double kMaxCurvatureGain = 0.15;

}  // namespace shading
