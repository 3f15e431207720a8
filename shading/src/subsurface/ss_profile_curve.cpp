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

namespace {

constexpr int kExitSteps = 512;

// The inside cosine under outside cosine mo: the midpoint of step i of exit_sum's rule.
double exit_mu_inside(int i, double eta) {
    const double mo = (i + 0.5) / kExitSteps;
    return std::sqrt(std::max(0.0, 1.0 - (1.0 - mo * mo) / (eta * eta)));
}

std::vector<double> exit_cosines(double eta) {
    std::vector<double> mu(kExitSteps);
    for (int i = 0; i < kExitSteps; ++i) mu[std::size_t(i)] = exit_mu_inside(i, eta);
    return mu;
}

}  // namespace

// 2 integral_0^1 Ft(mu_o) I(mu'(mu_o)) mu_o dmu_o of inside-radiance samples I (a 512-step
// midpoint rule, I clamped at 0): the exitance the samples imply, times eta^2 / pi.
double exit_sum(const std::vector<double>& samples, double eta) {
    double sum = 0;
    for (int i = 0; i < kExitSteps; ++i) {
        const double mo = (i + 0.5) / kExitSteps;
        sum += 2.0 * (1.0 - fresnel_dielectric(mo, eta)) * std::max(0.0, angle_poly(samples, exit_mu_inside(i, eta))) * mo /
               kExitSteps;
    }
    return sum;
}

AngleBasis::AngleBasis(int n, const std::vector<double>& mu) : n_(n), l_(mu.size() * std::size_t(std::max(n, 0))) {
    std::vector<double> x(std::size_t(std::max(n, 0)));
    for (int j = 0; j < n; ++j) x[std::size_t(j)] = angle_node(j, n);
    for (std::size_t k = 0; k < mu.size(); ++k)
        for (int j = 0; j < n; ++j) {
            const double xj = x[std::size_t(j)];
            double l = 1.0;
            for (int i = 0; i < n; ++i)
                if (i != j) l *= (mu[k] - x[std::size_t(i)]) / (xj - x[std::size_t(i)]);
            l_[k * std::size_t(n) + std::size_t(j)] = l;
        }
}

ExitSum::ExitSum(int n, double eta) : eta_(eta), fresnel2_(kExitSteps), basis_(n, exit_cosines(eta)) {
    for (int i = 0; i < kExitSteps; ++i) fresnel2_[std::size_t(i)] = 2.0 * (1.0 - fresnel_dielectric((i + 0.5) / kExitSteps, eta));
}

double ExitSum::operator()(const std::vector<double>& samples) const {
    double sum = 0;
    for (int i = 0; i < kExitSteps; ++i) {
        const double mo = (i + 0.5) / kExitSteps;
        sum += fresnel2_[std::size_t(i)] * std::max(0.0, basis_.value(samples, std::size_t(i))) * mo / kExitSteps;
    }
    return sum;
}

}  // namespace ss_detail
}  // namespace shading
