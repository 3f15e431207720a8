// The exact-profile tables' angular helpers (ss_profile_curve.h).
#include "shading/subsurface/ss_profile_curve.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "shading/brdf/fresnel.h"

namespace shading {
namespace ss_detail {

// Lagrange polynomial through (angle_node(j), v[j]) evaluated at mu. The n nodes are computed
// once per call (n cosines, not n^2: the same numbers, so the same bits; thin geometry builds
// a slab node's exit distribution from thousands of these calls).
double angle_poly(const std::vector<double>& v, double mu) {
    const int n = int(v.size());
    constexpr int kMaxNodes = 64;
    double node_buf[kMaxNodes];
    std::vector<double> node_heap;
    double* x = node_buf;
    if (n > kMaxNodes) {
        node_heap.resize(std::size_t(n));
        x = node_heap.data();
    }
    for (int j = 0; j < n; ++j) x[j] = angle_node(j, n);
    double sum = 0;
    for (int j = 0; j < n; ++j) {
        const double xj = x[j];
        double l = 1.0;
        for (int i = 0; i < n; ++i)
            if (i != j) l *= (mu - x[i]) / (xj - x[i]);
        sum += l * v[j];
    }
    return sum;
}

// 2 integral_0^1 Ft(mu_o) I(mu'(mu_o)) mu_o dmu_o of inside-radiance samples I (a 512-step
// midpoint rule, I clamped at 0): the exitance the samples imply, times eta^2 / pi.
double exit_sum(const std::vector<double>& samples, double eta) {
    double sum = 0;
    const int steps = 512;
    for (int i = 0; i < steps; ++i) {
        const double mo = (i + 0.5) / steps;
        const double mi = std::sqrt(std::max(0.0, 1.0 - (1.0 - mo * mo) / (eta * eta)));
        sum += 2.0 * (1.0 - fresnel_dielectric(mo, eta)) * std::max(0.0, angle_poly(samples, mi)) * mo / steps;
    }
    return sum;
}

}  // namespace ss_detail
}  // namespace shading
