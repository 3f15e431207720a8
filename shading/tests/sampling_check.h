// Sampling checks shared by the tests of samplers (microfacet_test.cpp, table_sampler_test.cpp,
// model_registry_test.cpp): a seeded portable RNG, a chi-square test of sample() against pdf(),
// and that test's expectations for a BRDF's sampler.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "shading/brdf/brdf.h"
#include "shading/core/vec.h"

namespace shading_test {

using namespace shading;

// Regularised upper incomplete gamma Q(a, x) (series / Lentz continued fraction).
inline double gamma_q(double a, double x) {
    if (x <= 0) return 1.0;
    double lg = -x + a * std::log(x) - std::lgamma(a);
    if (x < a + 1.0) {
        double ap = a, sum = 1.0 / a, del = sum;
        for (int i = 0; i < 10000; ++i) {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if (std::abs(del) < std::abs(sum) * 1e-15) break;
        }
        return std::max(0.0, 1.0 - sum * std::exp(lg));
    }
    const double tiny = 1e-300;
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 10000; ++i) {
        double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (std::abs(d) < tiny) d = tiny;
        c = b + an / c;
        if (std::abs(c) < tiny) c = tiny;
        d = 1.0 / d;
        double del = d * c;
        h *= del;
        if (std::abs(del - 1.0) < 1e-15) break;
    }
    return std::exp(lg) * h;
}

// Uniform double in [0, 1) from a seeded 64-bit Mersenne twister (portable, unlike
// std::uniform_real_distribution).
struct Rng {
    std::mt19937_64 g;
    explicit Rng(uint64_t seed) : g(seed) {}
    double operator()() { return double(g() >> 11) * 0x1.0p-53; }
};

struct Chi2 {
    double chi2 = 0, p = 0;
    int dof = 0;
    double valid_fraction = 0, pdf_mass = 0;
};

// Chi-square goodness of fit of sample() against pdf() (pbrt-v4 style): histogram of wi over
// (theta, phi) cells of the upper hemisphere plus one cell for "no sample"; expected counts
// from pdf() integrated by 2-D Simpson; cells with expected < 5 pooled.
// kSub: Simpson intervals per cell and axis (raise it for lobes narrower than a cell).
// kT x kP cells: theta in [0, 90] and the absolute phi in [0, 360) deg, equal steps.
// Quadrature::Gauss integrates each of kSub x kSub sub-cells by 3 x 3 Gauss-Legendre
// instead (no node on a sub-cell edge): exact up to smooth-function error for a pdf that is
// discontinuous only on the sub-cell edges (a tabulated sampler whose cells they follow).
enum class Quadrature { Simpson, Gauss };
inline Chi2 chi2_test(const std::function<Vec3(double, double)>& sample, const std::function<double(const Vec3&)>& pdf,
                      int n, uint64_t seed, int kSub = 8, int kT = 16, int kP = 32,
                      Quadrature quadrature = Quadrature::Simpson) {
    std::vector<double> obs(kT * kP + 1, 0.0), expv(kT * kP + 1, 0.0);
    Rng rng(seed);
    int valid = 0;
    for (int s = 0; s < n; ++s) {
        double u1 = rng(), u2 = rng();
        Vec3 w = sample(u1, u2);
        if (!(w.z > 0)) {
            obs.back() += 1;
            continue;
        }
        ++valid;
        double t = safe_acos(w.z), ph = std::atan2(w.y, w.x);
        if (ph < 0) ph += 2 * kPi;
        int it = std::min(kT - 1, int(t / (kPi / 2) * kT)), ip = std::min(kP - 1, int(ph / (2 * kPi) * kP));
        obs[it * kP + ip] += 1;
    }
    double mass = 0;
    for (int it = 0; it < kT; ++it)
        for (int ip = 0; ip < kP; ++ip) {
            double t0 = it * (kPi / 2) / kT, t1 = (it + 1) * (kPi / 2) / kT;
            double p0 = ip * 2 * kPi / kP, p1 = (ip + 1) * 2 * kPi / kP;
            double ht = (t1 - t0) / kSub, hp = (p1 - p0) / kSub, sum = 0, e;
            if (quadrature == Quadrature::Simpson) {
                for (int a = 0; a <= kSub; ++a)
                    for (int b = 0; b <= kSub; ++b) {
                        double wa = (a == 0 || a == kSub) ? 1 : (a % 2 ? 4 : 2);
                        double wb = (b == 0 || b == kSub) ? 1 : (b % 2 ? 4 : 2);
                        double t = t0 + a * ht, ph = p0 + b * hp;
                        sum += wa * wb * pdf(spherical_direction(t, ph)) * std::sin(t);
                    }
                e = sum * ht * hp / 9.0;
            } else {
                static const double gx[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
                static const double gw[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
                for (int a = 0; a < kSub; ++a)
                    for (int b = 0; b < kSub; ++b)
                        for (int i = 0; i < 3; ++i)
                            for (int k = 0; k < 3; ++k) {
                                double t = t0 + (a + 0.5 + 0.5 * gx[i]) * ht, ph = p0 + (b + 0.5 + 0.5 * gx[k]) * hp;
                                sum += gw[i] * gw[k] * pdf(spherical_direction(t, ph)) * std::sin(t);
                            }
                e = sum * ht * hp / 4.0;
            }
            expv[it * kP + ip] = e * n;
            mass += e;
        }
    expv.back() = std::max(0.0, 1.0 - mass) * n;

    Chi2 r;
    r.valid_fraction = double(valid) / n;
    r.pdf_mass = mass;
    // Pool low-expectation cells, smallest first, until the pool reaches 5.
    std::vector<int> idx(obs.size());
    for (size_t i = 0; i < idx.size(); ++i) idx[i] = int(i);
    std::sort(idx.begin(), idx.end(), [&](int a, int b) { return expv[a] < expv[b]; });
    double pool_o = 0, pool_e = 0;
    int cells = 0;
    for (int i : idx) {
        if (expv[i] == 0 && obs[i] > 0) {  // a sample where pdf() says none can be
            r.p = 0;
            r.chi2 = INFINITY;
            return r;
        }
        if (expv[i] < 5) {
            pool_o += obs[i];
            pool_e += expv[i];
            if (pool_e >= 5) {
                r.chi2 += sqr(pool_o - pool_e) / pool_e;
                ++cells;
                pool_o = pool_e = 0;
            }
            continue;
        }
        r.chi2 += sqr(obs[i] - expv[i]) / expv[i];
        ++cells;
    }
    if (pool_e > 0) {
        r.chi2 += sqr(pool_o - pool_e) / pool_e;
        ++cells;
    }
    r.dof = cells - 1;
    r.p = gamma_q(r.dof / 2.0, r.chi2 / 2.0);
    return r;
}

// A BRDF's sampler at wo against its pdf: sample()/pdf(), or sample_glossy()/pdf_glossy().
// Expects p above `p_min` (a Sidak-corrected level), more than 20 degrees of freedom, the pdf
// integrating to the fraction of valid samples (the rest fall below the horizon) and to at
// most 1 + mass_slack. kSub as chi2_test's (the default sampler's 1.5 deg lobe wants 32).
inline void expect_sampler_matches_pdf(const Brdf& b, const Vec3& wo, bool glossy, double p_min, uint64_t seed,
                                       int kSub, double mass_slack, const std::string& what) {
    auto sample = [&](double u1, double u2) { return glossy ? b.sample_glossy(wo, u1, u2) : b.sample(wo, u1, u2); };
    auto pdf = [&](const Vec3& wi) { return glossy ? b.pdf_glossy(wo, wi) : b.pdf(wo, wi); };
    Chi2 r = chi2_test(sample, pdf, 100000, seed, kSub);
    EXPECT_GT(r.p, p_min) << what << ": chi2=" << r.chi2 << " dof=" << r.dof;
    EXPECT_GT(r.dof, 20) << what;
    EXPECT_NEAR(r.pdf_mass, r.valid_fraction, 0.01) << what;
    EXPECT_LE(r.pdf_mass, 1.0 + mass_slack) << what;
}

}  // namespace shading_test
