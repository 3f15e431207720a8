#include <gtest/gtest.h>

#include <cmath>
#include <complex>

#include "shading/brdf/fresnel.h"

using namespace shading;

TEST(Fresnel, EtaOneIsZeroEverywhere) {
    for (double c = 0.0; c <= 1.0; c += 0.01) {
        EXPECT_EQ(fresnel_dielectric(c, 1.0), 0.0) << c;
        EXPECT_EQ(fresnel_conductor(c, 1.0, 0.0), 0.0) << c;
    }
}

TEST(Fresnel, NormalIncidenceClosedForms) {
    for (double eta : {1.0001, 1.33, 1.5, 2.4, 0.5}) {
        EXPECT_NEAR(fresnel_dielectric(1.0, eta), sqr((eta - 1) / (eta + 1)), 1e-15) << eta;
        EXPECT_NEAR(f0_from_eta(eta), sqr((eta - 1) / (eta + 1)), 1e-15);
    }
    // Gold-like and aluminium-like indices.
    for (auto nk : {std::pair<double, double>{0.18, 3.4}, {1.2, 7.0}, {1.5, 0.0}, {0.05, 0.0}}) {
        double n = nk.first, k = nk.second;
        double expect = (sqr(n - 1) + k * k) / (sqr(n + 1) + k * k);
        EXPECT_NEAR(fresnel_conductor(1.0, n, k), expect, 1e-14) << n << " " << k;
        EXPECT_NEAR(f0_from_conductor(n, k), expect, 1e-15);
    }
    // Schlick at normal incidence is F0, at grazing 1.
    EXPECT_DOUBLE_EQ(fresnel_schlick(1.0, 0.04), 0.04);
    EXPECT_DOUBLE_EQ(fresnel_schlick(0.0, 0.04), 1.0);
}

TEST(Fresnel, GrazingIsOne) {
    for (double eta : {1.0001, 1.5, 0.7}) EXPECT_NEAR(fresnel_dielectric(0.0, eta), 1.0, 1e-12) << eta;
    for (double n : {0.2, 1.5, 3.0}) EXPECT_NEAR(fresnel_conductor(0.0, n, 2.0), 1.0, 1e-12) << n;
    // And approaches 1 continuously: 89.99 deg is already close.
    double c = std::cos(89.99 * kPi / 180);
    EXPECT_GT(fresnel_dielectric(c, 1.5), 0.99);
    EXPECT_GT(fresnel_conductor(c, 0.18, 3.4), 0.99);
}

TEST(Fresnel, KnownValueAt45Degrees) {
    // Glass eta = 1.5 at 45 deg: Rs = 0.0920, Rp = 0.00847 (textbook), average 0.0503.
    double c = std::cos(kPi / 4);
    double cos_t = std::sqrt(1 - 0.5 / 2.25);
    double rs = sqr((c - 1.5 * cos_t) / (c + 1.5 * cos_t));
    double rp = sqr((1.5 * c - cos_t) / (1.5 * c + cos_t));
    EXPECT_NEAR(rs, 0.0920, 1e-4);
    EXPECT_NEAR(rp, 0.00847, 1e-5);
    EXPECT_NEAR(fresnel_dielectric(c, 1.5), 0.5 * (rs + rp), 1e-15);
}

TEST(Fresnel, TotalInternalReflection) {
    double eta = 1.0 / 1.5;  // from glass into air
    double critical = std::asin(eta);
    EXPECT_EQ(fresnel_dielectric(std::cos(critical + 1e-6), eta), 1.0);
    EXPECT_LT(fresnel_dielectric(std::cos(critical - 0.05), eta), 1.0);
    // Light from inside (cos < 0) equals swapping the media.
    EXPECT_NEAR(fresnel_dielectric(-0.9, 1.5), fresnel_dielectric(0.9, 1.0 / 1.5), 1e-15);
    // Conductor formula with k = 0 handles TIR too.
    EXPECT_NEAR(fresnel_conductor(std::cos(critical + 0.1), eta, 0.0), 1.0, 1e-12);
}

TEST(Fresnel, ConductorWithZeroKMatchesDielectric) {
    for (double eta : {1.2, 1.5, 2.0, 0.8})
        for (double c = 0.0; c <= 1.0; c += 0.05)
            EXPECT_NEAR(fresnel_conductor(c, eta, 0.0), fresnel_dielectric(c, eta), 1e-12) << eta << " " << c;
}

TEST(Fresnel, ContinuousAndInUnitInterval) {
    // Lipschitz-style check on a fine grid, including across the critical angle for eta < 1:
    // no jump larger than a small multiple of the step (away from the sqrt singularity at
    // the critical angle, the slope is bounded; there the curve is continuous but steep).
    const int n = 20000;
    for (double eta : {1.0001, 1.5, 3.0, 0.75}) {
        double prev = fresnel_dielectric(0.0, eta);
        for (int i = 1; i <= n; ++i) {
            double c = double(i) / n, v = fresnel_dielectric(c, eta);
            ASSERT_GE(v, 0.0);
            ASSERT_LE(v, 1.0);
            ASSERT_LT(std::abs(v - prev), 0.05) << eta << " " << c;
            prev = v;
        }
    }
    for (auto nk : {std::pair<double, double>{0.18, 3.4}, {1.5, 0.5}, {0.05, 4.0}}) {
        double prev = fresnel_conductor(0.0, nk.first, nk.second);
        for (int i = 1; i <= n; ++i) {
            double c = double(i) / n, v = fresnel_conductor(c, nk.first, nk.second);
            ASSERT_GE(v, 0.0);
            ASSERT_LE(v, 1.0);
            ASSERT_LT(std::abs(v - prev), 0.01) << nk.first << " " << c;
            prev = v;
        }
    }
}

TEST(Fresnel, EtaNearOneIsNearZero) {
    // Hard case eta = 1.0001: F ~ (1e-4 / 2)^2 at normal incidence and stays tiny until
    // within a fraction of a degree of grazing.
    EXPECT_NEAR(fresnel_dielectric(1.0, 1.0001), 2.5e-9, 1e-11);
    EXPECT_LT(fresnel_dielectric(std::cos(80 * kPi / 180), 1.0001), 1e-5);
    EXPECT_LT(fresnel_dielectric(std::cos(45 * kPi / 180), 1.0001), 1e-7);
    EXPECT_TRUE(std::isfinite(fresnel_dielectric(1e-300, 1.0001)));
}

TEST(Fresnel, SchlickCloseToExactForGlass) {
    double f0 = f0_from_eta(1.5);
    for (double c = 0.0; c <= 1.0; c += 0.01)
        EXPECT_NEAR(fresnel_schlick(c, f0), fresnel_dielectric(c, 1.5), 0.04) << c;  // Schlick errs by up to 0.0357, near 85 deg
    Rgb s = fresnel_schlick(0.5, Rgb(0.1, 0.2, 0.3));
    EXPECT_DOUBLE_EQ(s.g, fresnel_schlick(0.5, 0.2));
}

// The library evaluates the conductor formula in real arithmetic (a + ib = sqrt(eta^2 - sin^2)
// written out). The textbook complex evaluation, written here independently and run in long
// double, must agree over a grid of indices (metals, k = 0 dielectrics either side of
// eta = 1, eta < 1 with total internal reflection, tiny n of silver-like metals) and angles
// down to exact grazing: within 1e-12, except within 0.01 in cos of the critical angle of an
// almost lossless eta < 1, where F has a square-root singularity and the rounding of cos
// itself moves F by ~1e-11 in either evaluation (measured: 1.1e-11 real, 1.0e-11 complex in
// double; elsewhere 1.8e-13 real, 2.9e-13 complex).
namespace {
long double conductor_complex(long double c, long double n, long double k) {
    using C = std::complex<long double>;
    const C eta(n, k);
    const C cos_t = std::sqrt(C(1.0L) - (1.0L - c * c) / (eta * eta));
    const C rs = (c - eta * cos_t) / (c + eta * cos_t);
    const C rp = (eta * c - cos_t) / (eta * c + cos_t);
    return std::min(1.0L, 0.5L * (std::norm(rs) + std::norm(rp)));
}
}  // namespace

TEST(Fresnel, ConductorRealFormEqualsComplexForm) {
    const double ns[] = {0.01, 0.05, 0.18, 0.5, 0.8, 0.9999, 1.0001, 1.2, 1.5, 2.4, 5.0, 20.0};
    const double ks[] = {0.0, 1e-6, 0.01, 0.5, 1.0, 2.4, 3.4, 7.0, 40.0};
    int count = 0;
    for (double n : ns)
        for (double k : ks)
            for (int i = 0; i <= 2000; ++i) {
                // Dense near grazing: c = cos(theta), theta to exactly 90 deg.
                const double theta = (kPi / 2) * (1.0 - sqr(1.0 - i / 2000.0));
                const double c = i == 2000 ? 0.0 : std::cos(theta);
                const double want = double(conductor_complex(c, n, k)), got = fresnel_conductor(c, n, k);
                const bool critical = n < 1 && k < 1e-3 && std::abs(c - std::sqrt(1 - n * n)) < 0.01;
                ASSERT_NEAR(got, want, critical ? 5e-11 : 1e-12) << "n=" << n << " k=" << k << " cos=" << c;
                ++count;
            }
    EXPECT_GT(count, 200000);
}

TEST(Fresnel, ConductorRealFormMirrorAndTotalReflection) {
    // n = k = 0 is a perfect mirror; eta < 1 beyond the critical angle reflects everything.
    for (double c : {0.0, 0.3, 1.0}) EXPECT_DOUBLE_EQ(fresnel_conductor(c, 0.0, 0.0), 1.0) << c;
    EXPECT_DOUBLE_EQ(fresnel_conductor(std::cos(std::asin(0.5) + 0.01), 0.5, 0.0), 1.0);
    Rgb f = fresnel_conductor(0.7, Rgb(0.2, 0.4, 1.4), Rgb(3.4, 2.4, 1.8));
    EXPECT_NEAR(f.b, double(conductor_complex(0.7L, 1.4L, 1.8L)), 1e-14);
}

TEST(Fresnel, ConductorRgbIsEachChannelBitForBit) {
    // The per-channel form evaluates two channels in one SSE2 register: the same bits as the
    // scalar function on each channel, on both branches (n^2 - k^2 - sin^2 of either sign),
    // the dielectric (k = 0) and no-interface channels, and cosines outside [0, 1].
    const double ns[] = {0.0, 0.05, 0.2, 0.4, 1.0, 1.4, 1.5, 3.0, 20.0};
    const double ks[] = {0.0, 1e-9, 0.3, 1.8, 2.4, 3.4, 10.0};
    int checked = 0;
    for (double n0 : ns)
        for (double k0 : ks)
            for (double n1 : ns)
                for (double k1 : ks)
                    for (int i = -2; i <= 202; ++i) {
                        const double c = i / 200.0 + (i % 7) * 1e-5;
                        const Rgb n(n0, n1, n0 + n1), k(k0, k1, k0 * 0.5);
                        const Rgb f = fresnel_conductor(c, n, k);
                        ASSERT_EQ(f.r, fresnel_conductor(c, n.r, k.r)) << n0 << " " << k0 << " " << c;
                        ASSERT_EQ(f.g, fresnel_conductor(c, n.g, k.g)) << n1 << " " << k1 << " " << c;
                        ASSERT_EQ(f.b, fresnel_conductor(c, n.b, k.b)) << c;
                        ++checked;
                    }
    EXPECT_GT(checked, 600000);
}
