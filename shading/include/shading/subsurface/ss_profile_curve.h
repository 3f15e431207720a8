// Internal to the exact-profile tables (ss_profile.h): the radial interpolant, the inside-radiance
// polynomial and the tail, shared by building the tables (ss_profile_build.cpp) and evaluating
// them (ss_profile.cpp), so both read a record the same way (the polynomial's integrals:
// ss_profile_curve.cpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "shading/core/format.h"
#include "shading/core/quadrature.h"
#include "shading/core/vec.h"

namespace shading {
namespace ss_detail {

constexpr double kTiny = 1e-37;  // floor of profile values before taking logs (float32 range)
// The largest tail amplitude and radius-node value a file may hold (the loader's bound).
constexpr double kMaxTailAmplitude = 1e30;

// Numbers in messages and descriptions: 9 digits, a float exactly.
inline std::string num(double v) { return detail::fmt(v, 9); }

// Nodes of the inside-radiance samples on (0, 1], increasing, the last 1: those of
// McSettings::radiance_cosines (the Monte Carlo's next-event estimate is made there).
inline double angle_node(int j, int n) { return 0.5 * (1.0 - std::cos(kPi * (j + 0.5) / (n - 0.5))); }
// 2 integral_0^1 Ft(mu_o) I(mu'(mu_o)) mu_o dmu_o of inside-radiance samples I (a 512-step
// midpoint rule, I clamped at 0): the exitance the samples imply, times eta^2 / pi.
double exit_sum(const std::vector<double>& samples, double eta);

// The Lagrange polynomial through (angle_node(j), v[j]), j < n, at fixed points: value(v, k)
// is its value at mu[k] for every v of n samples, the basis computed once (no cosine per
// call): a slab node's exit distribution reads thousands of records at the same points.
class AngleBasis {
public:
    AngleBasis(int n, const std::vector<double>& mu);
    double value(const std::vector<double>& v, std::size_t k) const {
        const double* l = &l_[k * std::size_t(n_)];
        double sum = 0;
        for (int j = 0; j < n_; ++j) sum += l[j] * v[std::size_t(j)];
        return sum;
    }

private:
    int n_;
    std::vector<double> l_;  // l_[k n + j]: basis polynomial j at mu[k]
};

// exit_sum for every v of n samples at one eta: the Fresnel factors and the basis at the 512
// inside cosines once (exit_sum makes one per call).
class ExitSum {
public:
    ExitSum(int n, double eta);
    double operator()(const std::vector<double>& samples) const;

private:
    std::vector<double> fresnel2_;  // 2 (1 - Ft) per step
    AngleBasis basis_;
};

// Tail shape (1 + k rho) exp(-k rho) / rho^3 and its integral of 2 pi rho from R to infinity.
inline double tail_shape(double k, double rho) { return (1 + k * rho) * std::exp(-k * rho) / (rho * rho * rho); }
inline double tail_flux(double k, double R) { return 2 * kPi * std::exp(-k * R) / R; }

// The radial interpolant: node 0 at rho = 0, nodes b >= 1 uniformly spaced in x = ln rho.
// Segment 0 [0, rho_1] is linear in rho between the two values; segments b >= 1 are cubic
// Hermite in x on y = ln Rd with central-difference tangents (one-sided at the ends): C1
// everywhere from rho_1 on.
struct RadialCurve {
    const double* rho = nullptr;  // nodes
    const double* y = nullptr;    // ln value at the nodes
    int n = 0;
    double h = 1;                 // node spacing in ln rho

    double tangent(int b) const {
        if (b <= 1) return (y[2] - y[1]) / h;
        if (b >= n - 1) return (y[n - 1] - y[n - 2]) / h;
        return (y[b + 1] - y[b - 1]) / (2 * h);
    }
    // Value in segment b (rho in [rho[b], rho[b+1]]).
    double eval_in(int b, double r) const {
        if (b == 0) {
            const double t = r / rho[1];
            return std::exp(y[0]) * (1 - t) + std::exp(y[1]) * t;
        }
        const double t = (std::log(r) - std::log(rho[b])) / h;
        const double t2 = t * t, t3 = t2 * t;
        const double v = (2 * t3 - 3 * t2 + 1) * y[b] + (t3 - 2 * t2 + t) * h * tangent(b) + (-2 * t3 + 3 * t2) * y[b + 1] +
                         (t3 - t2) * h * tangent(b + 1);
        return std::exp(v);
    }
    int segment(double r) const {
        if (!(r > rho[1])) return 0;
        int b = 1 + int(std::floor((std::log(r) - std::log(rho[1])) / h));
        return std::clamp(b, 1, n - 2);
    }
    double eval(double r) const { return eval_in(segment(r), r); }
    // Integral of 2 pi r value(r) over [r1, r2] inside segment b.
    double integral_in(int b, double r1, double r2) const {
        if (!(r2 > r1)) return 0.0;
        double sum = 0;
        if (b == 0) {
            for (int i = 0; i < 8; ++i) {
                const double r = r1 + (r2 - r1) * kGaussLegendre8UnitX[i];
                sum += kGaussLegendre8UnitW[i] * 2 * kPi * r * eval_in(0, r);
            }
            return sum * (r2 - r1);
        }
        const double x1 = std::log(r1), x2 = std::log(r2);
        for (int i = 0; i < 8; ++i) {
            const double r = std::exp(x1 + (x2 - x1) * kGaussLegendre8UnitX[i]);
            sum += kGaussLegendre8UnitW[i] * 2 * kPi * r * r * eval_in(b, r);
        }
        return sum * (x2 - x1);
    }
    // Integral of 2 pi r value over [r1, r2] (within the nodes' range).
    double integral(double r1, double r2) const {
        double sum = 0;
        int b = segment(r1);
        const int last = segment(r2);
        for (; b <= last; ++b) {
            const double lo = std::max(r1, rho[b]), hi = std::min(r2, rho[b + 1]);
            sum += integral_in(b, lo, hi);
        }
        return sum;
    }
};

}  // namespace ss_detail
}  // namespace shading
