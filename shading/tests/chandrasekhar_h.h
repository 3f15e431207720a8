// Chandrasekhar's H-function for the tests that check transport against it (transport_mc_test,
// ss_profile_test): written here, from the integral equation, sharing no code with the library.
#pragma once

#include <cmath>
#include <vector>

namespace {

constexpr double kPiT = 3.14159265358979323846;

// Chandrasekhar's H(mu) for isotropic scattering of albedo w, by fixed-point iteration of
// 1/H(mu) = sqrt(1 - w) + (w/2) int_0^1 mu' H(mu') / (mu + mu') dmu' (Gauss-Legendre, n nodes
// on [0, 1] found by Newton on P_n). Written here, independent of the library.
inline double chandrasekhar_h(double mu, double w) {
    const int n = 96;
    std::vector<double> x(n), wt(n);
    for (int i = 0; i < n; ++i) {
        double z = std::cos(kPiT * (i + 0.75) / (n + 0.5));
        for (int it = 0; it < 100; ++it) {
            double p1 = 1, p2 = 0;
            for (int j = 1; j <= n; ++j) {
                const double p3 = p2;
                p2 = p1;
                p1 = ((2 * j - 1) * z * p2 - (j - 1) * p3) / j;
            }
            const double pp = n * (z * p1 - p2) / (z * z - 1);
            const double z1 = z;
            z = z1 - p1 / pp;
            if (std::fabs(z - z1) < 1e-15) {
                x[i] = 0.5 * (1 - z);
                wt[i] = 1.0 / ((1 - z * z) * pp * pp);
                break;
            }
        }
    }
    const double s = std::sqrt(1.0 - w);
    std::vector<double> h(n, 1.0);
    for (int it = 0; it < 4000; ++it) {
        std::vector<double> nh(n);
        for (int i = 0; i < n; ++i) {
            double sum = 0;
            for (int j = 0; j < n; ++j) sum += wt[j] * x[j] * h[j] / (x[i] + x[j]);
            nh[i] = 1.0 / (s + 0.5 * w * sum);
        }
        h = nh;
    }
    double sum = 0;
    for (int j = 0; j < n; ++j) sum += wt[j] * x[j] * h[j] / (mu + x[j]);
    return 1.0 / (s + 0.5 * w * sum);
}

}  // namespace
