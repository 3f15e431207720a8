// The exact-profile tables' angular helpers (ss_profile_curve.h).
#include "shading/subsurface/ss_profile_curve.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "shading/brdf/fresnel.h"

namespace shading {
namespace ss_detail {

namespace {

constexpr int kExitSteps = 512;

// The inside cosines under the outside cosines mo = (i + 1/2) / 512: ExitSum's midpoint rule.
std::vector<double> exit_cosines(double eta) {
    std::vector<double> mu(kExitSteps);
    for (int i = 0; i < kExitSteps; ++i) {
        const double mo = (i + 0.5) / kExitSteps;
        mu[std::size_t(i)] = std::sqrt(std::max(0.0, 1.0 - (1.0 - mo * mo) / (eta * eta)));
    }
    return mu;
}

}  // namespace

// One record at a time (the tables' build): the same sums as ExitSum's, so the same bits.
double exit_sum(const std::vector<double>& samples, double eta) { return ExitSum(int(samples.size()), eta)(samples); }

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

ExitSum::ExitSum(int n, double eta) : fresnel2_(kExitSteps), basis_(n, exit_cosines(eta)) {
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
