// The curvature correction's coefficient c(eta, alpha') (curvature.h), measured.
#include "shading/subsurface/curvature.h"

#include <algorithm>
#include <cmath>

namespace shading {

namespace {

// c at the nodes below: the random walk's multiple scattering over the exact profile's, less 1,
// per unit of mfp' / R, on spheres lit straight on, in the disc where the light is within 37 deg
// of the normal (48 x 48 pixels, 512 walks each; single scattering traced in the sphere on both
// sides of the ratio, multiple scattering alone by `single_scatter off`): radius 15 mfp' for
// alpha' up to 0.9, 33 mfp' above (where the diffusion length is 2.6 to 8 mfp' and a smaller
// sphere adds its own size to the ratio). Measurement noise about 0.05 (0.09 at 33 mfp');
// shading/DIPOLE.md 6d has the runs. Bilinear between nodes, held beyond the outer ones.
constexpr int kEtas = 9, kAlbedos = 8;
constexpr double kEta[kEtas] = {1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.8, 2.0};
constexpr double kAlbedo[kAlbedos] = {0.4, 0.6, 0.75, 0.85, 0.9, 0.95, 0.98, 0.995};
constexpr double kC[kEtas][kAlbedos] = {
    // 0.4    0.6    0.75   0.85   0.9    0.95   0.98   0.995
    {0.041, 0.002, -0.040, -0.062, -0.101, -0.081, -0.256, -0.473},  // eta 1.0
    {0.482, 0.439, 0.384, 0.358, 0.302, 0.312, 0.109, -0.123},       // 1.1
    {0.698, 0.671, 0.640, 0.641, 0.631, 0.841, 0.765, 0.623},        // 1.2
    {0.812, 0.813, 0.825, 0.870, 0.902, 1.063, 1.008, 0.882},        // 1.3
    {0.894, 0.921, 0.963, 1.051, 1.112, 1.351, 1.378, 1.346},        // 1.4
    {1.013, 1.054, 1.119, 1.235, 1.322, 1.572, 1.660, 1.701},        // 1.5
    {1.062, 1.128, 1.222, 1.368, 1.487, 1.781, 1.925, 2.066},        // 1.6
    {1.178, 1.262, 1.383, 1.577, 1.741, 2.169, 2.594, 2.898},        // 1.8
    {1.288, 1.371, 1.503, 1.721, 1.943, 2.387, 2.992, 3.669},        // 2.0
};

// The interval of `v` among `n` ascending nodes and the weight of its upper node (held outside).
void locate(const double* nodes, int n, double v, int* i, double* t) {
    if (!(v > nodes[0])) {  // also NaN
        *i = 0;
        *t = 0;
        return;
    }
    if (v >= nodes[n - 1]) {
        *i = n - 2;
        *t = 1;
        return;
    }
    int k = 0;
    while (v >= nodes[k + 1]) ++k;
    *i = k;
    *t = (v - nodes[k]) / (nodes[k + 1] - nodes[k]);
}

}  // namespace

double curvature_anisotropy_weight(double g) {
    const double u = g / kCurvatureGMax;
    return std::fabs(g) < kCurvatureGMax ? 1.0 - u * u : 0.0;  // (NaN: 0)
}

double curvature_coefficient(double eta, double albedo) {
    int i, j;
    double s, t;
    locate(kEta, kEtas, eta, &i, &s);
    locate(kAlbedo, kAlbedos, albedo, &j, &t);
    const double lo = kC[i][j] * (1 - t) + kC[i][j + 1] * t;
    const double hi = kC[i + 1][j] * (1 - t) + kC[i + 1][j + 1] * t;
    // Negative nodes (ior near 1, high albedo: the sphere's own size, lit straight on) are taken
    // as 0: under light from the side the same spheres' whole flux is too dark already, and the
    // term would darken it further (Skin1 of radius 4 mm at ior 1: -5.3 -> -8.0 % in red).
    return std::max(0.0, lo * (1 - s) + hi * s);
}

}  // namespace shading
