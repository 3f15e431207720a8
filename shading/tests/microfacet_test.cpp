// D, G terms, the roughness mapping, and sample()/pdf() agreement (chi-square) for the
// microfacet family (Microfacet and Ward, which samples Beckmann half vectors).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "shading/brdf/microfacet.h"
#include "shading/brdf/model_spec.h"
#include "shading/brdf/models.h"
#include "sampling_check.h"

using namespace shading;
using namespace shading_test;

namespace {

double deg(double d) { return d * kPi / 180.0; }

// Composite Simpson of f over [a, b] with n (even) intervals.
double simpson(const std::function<double(double)>& f, double a, double b, int n) {
    double h = (b - a) / n, s = f(a) + f(b);
    for (int i = 1; i < n; ++i) s += f(a + i * h) * (i % 2 ? 4 : 2);
    return s * h / 3.0;
}

// Hemispherical integral of an isotropic g(cos theta) cos theta dw = 2 pi int g cos sin dtheta.
double integrate_isotropic(const std::function<double(double)>& g, double theta_max = kPi / 2, int n = 100000) {
    return 2.0 * kPi * simpson([&](double t) { return g(std::cos(t)) * std::cos(t) * std::sin(t); }, 0.0, theta_max, n);
}

const DKind kAllD[] = {DKind::Blinn, DKind::Gaussian, DKind::TrowbridgeReitz, DKind::Beckmann};

}  // namespace

// ---------------------------------------------------------------- closed forms

TEST(MicrofacetD, SurveyClosedForms) {
    double a = deg(20), c = std::cos(a);
    EXPECT_DOUBLE_EQ(d1_blinn(c, 30), std::pow(c, 30));
    EXPECT_NEAR(d2_gaussian(c, 4), std::exp(-sqr(a * 4)), 1e-14);  // acos(cos a) rounds
    EXPECT_NEAR(d3_trowbridge_reitz(c, 0.3), sqr(0.09 / (c * c * (0.09 - 1) + 1)), 1e-15);
    EXPECT_NEAR(d4_beckmann(c, 0.3), std::exp(-sqr(std::tan(a)) / 0.09) / (0.09 * std::pow(c, 4)), 1e-14);
    // Peaks: 1 for D1..D3, 1/m^2 for D4.
    EXPECT_EQ(d1_blinn(1, 30), 1.0);
    EXPECT_EQ(d2_gaussian(1, 4), 1.0);
    EXPECT_DOUBLE_EQ(d3_trowbridge_reitz(1, 0.3), 1.0);
    EXPECT_DOUBLE_EQ(d4_beckmann(1, 0.3), 1.0 / 0.09);
    // Back-facing microfacets.
    for (double cn : {0.0, -0.5}) {
        EXPECT_EQ(d1_blinn(cn, 3), 0.0);
        EXPECT_EQ(d2_gaussian(cn, 3), 0.0);
        EXPECT_EQ(d3_trowbridge_reitz(cn, 0.3), 0.0);
        EXPECT_EQ(d4_beckmann(cn, 0.3), 0.0);
    }
}

TEST(MicrofacetD, NormalisedAreScaledSurveyForms) {
    for (double c : {1.0, 0.95, 0.7, 0.3, 0.01}) {
        EXPECT_NEAR(d_blinn(c, 30), 32 / (2 * kPi) * d1_blinn(c, 30), 1e-15);
        EXPECT_NEAR(d_trowbridge_reitz(c, 0.3), d3_trowbridge_reitz(c, 0.3) / (kPi * 0.09), 1e-13);
        EXPECT_NEAR(d_beckmann(c, 0.3), d4_beckmann(c, 0.3) / kPi, 1e-13);
        // GGX closed form of Walter et al. 2007.
        double t2 = (1 - c * c) / (c * c);
        EXPECT_NEAR(d_trowbridge_reitz(c, 0.3), 0.09 / (kPi * std::pow(c, 4) * sqr(0.09 + t2)),
                    1e-12 * (1 + d_trowbridge_reitz(c, 0.3)));
    }
    // Beckmann normalisation closed form at the peak: 1 / (pi m^2).
    EXPECT_DOUBLE_EQ(d_beckmann(1.0, 0.2), 1.0 / (kPi * 0.04));
}

TEST(MicrofacetD, NormalisationIntegratesToOne) {
    for (double m : {0.01, 0.05, 0.2, 0.5, 1.0})
        for (DKind k : kAllD) {
            NormalDistribution d = NormalDistribution::from_m(k, m);
            double v = integrate_isotropic([&](double c) { return d.normalized(c); });
            EXPECT_NEAR(v, 1.0, 1e-6) << d.name() << " m=" << m;
        }
    // Beckmann exactly (closed form) also at roughness 1e-4, integrating where the lobe lives.
    double v = integrate_isotropic([](double c) { return d_beckmann(c, 1e-4); }, 40e-4, 20000);
    EXPECT_NEAR(v, 1.0, 1e-9);
}

TEST(MicrofacetD, GaussianNormalisationAsymptote) {
    // Large n2: C = n2^2/pi (1 + 2/(3 n2^2) + O(n2^-4)) (MODELS.md).
    for (double n2 : {30.0, 100.0, 1000.0}) {
        double ratio = gaussian_norm(n2) * kPi / (n2 * n2);
        EXPECT_NEAR(ratio, 1 + 2 / (3 * n2 * n2), 2 / std::pow(n2, 4)) << n2;
    }
    // Small n2: the lobe is cut by the horizon, nothing asymptotic; the integral is still 1.
    NormalDistribution d(DKind::Gaussian, 0.5);
    EXPECT_NEAR(integrate_isotropic([&](double c) { return d.normalized(c); }), 1.0, 1e-9);
}

TEST(MicrofacetD, EqualRoughnessMapping) {
    for (double m : {0.02, 0.1, 0.3}) {
        // Blinn and TR: equal peak value 1/(pi m^2) (exact by construction).
        double peak = d_beckmann(1.0, m);
        EXPECT_NEAR(d_blinn(1.0, blinn_n_from_m(m)), peak, 1e-12 * peak);
        EXPECT_NEAR(d_trowbridge_reitz(1.0, tr_alpha_from_m(m)), peak, 1e-12 * peak);
        EXPECT_NEAR(m_from_blinn_n(blinn_n_from_m(m)), m, 1e-15);
        // Slope variance <tan^2 theta_h> under D cos dw: Beckmann m^2 (exact), Blinn 2/n (exact),
        // Gaussian n2 = 1/m: m^2 (1 + O(m^2)).
        auto moment = [&](const NormalDistribution& d) {
            return integrate_isotropic([&](double c) { return d.normalized(c) * (1 - c * c) / (c * c); },
                                       std::min(kPi / 2 - 1e-3, 30 * m), 200000);
        };
        EXPECT_NEAR(moment(NormalDistribution(DKind::Beckmann, m)), m * m, 1e-6 * m * m);
        double n = 50;
        EXPECT_NEAR(2 * kPi * simpson([&](double t) { return d_blinn(std::cos(t), n) * sqr(std::tan(t)) * std::cos(t) * std::sin(t); },
                                      0, kPi / 2 - 1e-9, 200000),
                    2 / n, 1e-6);
        double g = moment(NormalDistribution::from_m(DKind::Gaussian, m));
        EXPECT_NEAR(g / (m * m), 1.0, 2 * m * m) << m;
    }
}

// ---------------------------------------------------------------- G

TEST(MicrofacetG, VCavityBoundsAndSymmetry) {
    EXPECT_EQ(g_vcavity(1, 1, 1, 1), 1.0);
    for (double a : {0.0, 0.3, 0.8})
        for (double b : {0.01, 0.3, 0.9}) {
            Vec3 wo = spherical_direction(a + 0.5, 0.2), wi = spherical_direction(b + 0.2, 2.5);
            Vec3 h = half_vector(wo, wi);
            double g1 = g_vcavity(h.z, wo.z, wi.z, dot(wo, h)), g2 = g_vcavity(h.z, wi.z, wo.z, dot(wi, h));
            EXPECT_NEAR(g1, g2, 1e-15);
            EXPECT_GE(g1, 0.0);
            EXPECT_LE(g1, 1.0);
            EXPECT_NEAR(g1, std::min({1.0, 2 * h.z * wo.z / dot(wo, h), 2 * h.z * wi.z / dot(wo, h)}), 1e-15);
        }
}

TEST(MicrofacetG, SmithLambdaClosedForms) {
    Vec3 n(0, 0, 1);
    EXPECT_EQ(smith_lambda_beckmann(n, 0.3), 0.0);
    EXPECT_EQ(smith_lambda_ggx(n, 0.3), 0.0);
    Vec3 w = spherical_direction(deg(60), 0.4);
    double a = 1 / (0.3 * std::tan(deg(60)));
    EXPECT_NEAR(smith_lambda_beckmann(w, 0.3), (std::erf(a) - 1) / 2 + std::exp(-a * a) / (2 * a * std::sqrt(kPi)), 1e-14);
    EXPECT_NEAR(smith_lambda_ggx(w, 0.3), (-1 + std::sqrt(1 + 0.09 * sqr(std::tan(deg(60))))) / 2, 1e-14);
    // Grazing: fully masked, G -> 0 without NaN.
    Vec3 g(1, 0, 0);
    EXPECT_EQ(g_smith(smith_lambda_beckmann(g, 0.3), 0.0), 0.0);
    EXPECT_EQ(g_smith(smith_lambda_ggx(g, 0.3), 0.0), 0.0);
}

// Exact Smith G1 satisfies the projected-area constraint
// int G1(wo) D(h) max(0, wo.h) dw_h = cos theta_o (Heitz 2014 eq. 12).
TEST(MicrofacetG, SmithProjectedAreaExactForBeckmannAndTR) {
    for (DKind k : {DKind::Beckmann, DKind::TrowbridgeReitz})
        for (double m : {0.1, 0.5, 1.0})
            for (double th : {0.0, 30.0, 60.0, 80.0, 89.0}) {
                NormalDistribution d(k, m);
                Vec3 wo = spherical_direction(deg(th), 0.0);
                double g1 = g1_smith(d.smith_lambda(wo));
                // Integrate over phi_h by Simpson (smooth) and theta_h by Simpson on a grid fine
                // enough for the kink where wo.h changes sign.
                const int nt = 2000, np = 64;
                double v = 2 * simpson(
                                   [&](double ph) {
                                       return simpson(
                                           [&](double t) {
                                               Vec3 h = spherical_direction(t, ph);
                                               return d.normalized(h.z) * std::max(0.0, dot(wo, h)) * std::sin(t);
                                           },
                                           0, kPi / 2, nt);
                                   },
                                   0, kPi, np);
                EXPECT_NEAR(g1 * v, wo.z, 2e-4 * std::max(wo.z, 0.05)) << d.name() << " m=" << m << " th=" << th;
            }
}

// ---------------------------------------------------------------- sampling

TEST(MicrofacetSampling, GammaQHelper) {
    EXPECT_NEAR(gamma_q(1.0, 2.0), std::exp(-2.0), 1e-14);
    EXPECT_NEAR(gamma_q(1.0, 0.3), std::exp(-0.3), 1e-14);
    EXPECT_NEAR(gamma_q(0.5, 2.0), std::erfc(std::sqrt(2.0)), 1e-13);
    EXPECT_NEAR(gamma_q(100.0, 100.0), 0.4867, 1e-3);
}

TEST(MicrofacetSampling, HalfVectorDensityIsDCos) {
    // The sampled theta_h matches the CDF of D cos over theta_h (1-D Kolmogorov-Smirnov style
    // check at fixed quantiles) for each D, including the tabulated Gaussian inversion.
    for (DKind k : kAllD) {
        NormalDistribution d = NormalDistribution::from_m(k, 0.3);
        for (double u : {0.05, 0.25, 0.5, 0.75, 0.95, 0.999}) {
            Vec3 h = d.sample_h(u, 0.3);
            double t = safe_acos(h.z);
            double cdf = integrate_isotropic([&](double c) { return d.normalized(c); }, t, 20000);
            EXPECT_NEAR(cdf, u, 1e-7) << d.name() << " u=" << u;
        }
    }
}

TEST(MicrofacetSampling, ChiSquareSampleMatchesPdf) {
    struct Case {
        const char* spec;
        double theta_o, phi_o;
    };
    const Case cases[] = {
        {"microfacet d=beckmann m=0.3", 30, 0},
        {"microfacet d=tr m=0.2", 60, 0},
        {"microfacet d=blinn m=0.5", 10, 0},
        {"microfacet d=gaussian m=0.3", 45, 0},
        {"microfacet d=beckmann m=0.7 kd=0.3 rho_s=0.5", 75, 0},
        {"ward ax=0.1 ay=0.4", 40, 30},
        {"ward variant=original rho_d=0.4 rho_s=0.2 ax=0.3 ay=0.15", 20, 100},
    };
    const int kTests = sizeof(cases) / sizeof(cases[0]);
    const double alpha = 0.01, sidak = 1.0 - std::pow(1.0 - alpha, 1.0 / kTests);
    uint64_t seed = 12345;
    for (const Case& c : cases)
        expect_sampler_matches_pdf(*make_brdf(c.spec), spherical_direction(deg(c.theta_o), deg(c.phi_o)), false, sidak,
                                   seed++, 8, 1e-4, c.spec);
}

// The default sampler every other model inherits (brdf.cpp), and the specular-lobe-only
// samplers used for glossy reflection (sample_glossy), against their pdfs.
TEST(MicrofacetSampling, ChiSquareDefaultAndGlossySamplers) {
    struct Case {
        const char* spec;
        double theta_o, phi_o;
        bool glossy;
    };
    const Case cases[] = {
        {"lambert rho=0.7", 0, 0, false},
        {"phong_pov phong=0.5 phong_size=40 diffuse=0.5", 35, 0, false},
        {"phong_normalized kd=0.2 ks=0.6 n=200", 60, 45, false},
        {"oren_nayar rho=0.5 sigma=0.4", 80, 0, false},
        {"lafortune kd=0.1 lobe=-1,-1,1,40,0.5 lobe=0.8,0.8,0.9,6,0.2", 50, 200, false},
        {"microfacet d=beckmann m=0.2 kd=0.6 rho_s=0.3", 40, 0, true},
        {"microfacet form=survey d=tr m=0.1 kd=0.5", 70, 0, true},
        {"ward rho_d=0.5 rho_s=0.2 ax=0.05 ay=0.2", 30, 60, true},
    };
    const int kTests = sizeof(cases) / sizeof(cases[0]);
    const double alpha = 0.01, sidak = 1.0 - std::pow(1.0 - alpha, 1.0 / kTests);
    uint64_t seed = 777;
    // The default sampler's 1.5 deg lobe needs a finer quadrature of the cells.
    for (const Case& c : cases)
        expect_sampler_matches_pdf(*make_brdf(c.spec), spherical_direction(deg(c.theta_o), deg(c.phi_o)), c.glossy,
                                   sidak, seed++, c.glossy ? 8 : 32, 1e-3, c.spec);
    // The glossy samplers really drop the cosine branch: a direction far from the lobe has
    // zero glossy density but positive full density.
    BrdfPtr m = make_brdf("microfacet d=beckmann m=0.05 kd=0.6 rho_s=0.3");
    Vec3 wo = spherical_direction(deg(30), 0), far = spherical_direction(deg(60), deg(90));
    EXPECT_GT(m->pdf(wo, far), 0.1);
    EXPECT_LT(m->pdf_glossy(wo, far), 1e-30);
}

TEST(MicrofacetSampling, ChiSquareDetectsAWrongPdf) {
    // The test has power: a pdf for the wrong roughness is rejected.
    auto right = std::dynamic_pointer_cast<const Microfacet>(make_brdf("microfacet d=beckmann m=0.3"));
    auto wrong = std::dynamic_pointer_cast<const Microfacet>(make_brdf("microfacet d=beckmann m=0.33"));
    Vec3 wo = spherical_direction(deg(30), 0);
    Chi2 r = chi2_test([&](double u1, double u2) { return right->sample(wo, u1, u2); },
                       [&](const Vec3& wi) { return wrong->pdf(wo, wi); }, 100000, 99);
    EXPECT_LT(r.p, 1e-6);
}

TEST(MicrofacetSampling, SampleAndPdfAgreeAtSampledDirections) {
    auto m = std::dynamic_pointer_cast<const Microfacet>(make_brdf("microfacet d=gaussian m=0.2 kd=0.2 rho_s=0.8"));
    Vec3 wo = spherical_direction(deg(50), 1.0);
    Rng rng(7);
    for (int i = 0; i < 1000; ++i) {
        Vec3 wi = m->sample(wo, rng(), rng());
        if (wi.z <= 0) {
            EXPECT_EQ(wi.x, 0.0);
            continue;
        }
        EXPECT_NEAR(length(wi), 1.0, 1e-12);
        EXPECT_GT(m->pdf(wo, wi), 0.0);
        EXPECT_TRUE(std::isfinite(m->pdf(wo, wi)));
    }
    EXPECT_EQ(m->pdf(wo, Vec3(0, 0, -1)), 0.0);
    EXPECT_EQ(m->sample(Vec3(0, 0, -1), 0.5, 0.5).z, 0.0);  // viewer below: no sample
}

TEST(MicrofacetG, SmithLambdaTableMatchesClosedForm) {
    // The table used for Blinn and Gaussian, built for Beckmann (which has a closed form),
    // reproduces the exact Lambda: G1 = 1 / (1 + Lambda) within 1e-5 from normal to 89.9 deg.
    for (double m : {0.05, 0.3, 0.8}) {
        SmithLambdaTable t([m](double c) { return d_beckmann(c, m); }, m, std::min(kPi / 2, 8.0 * m));
        for (double deg_o = 0.0; deg_o <= 89.9; deg_o += 0.7) {
            Vec3 w = spherical_direction(deg(deg_o), 0.4);
            EXPECT_NEAR(g1_smith(t.lambda(w)), g1_smith(smith_lambda_beckmann(w, m)), 1e-5) << "m=" << m << " " << deg_o;
        }
    }
}

// Beckmann's Lambda is returned as 0 where a = cot(theta) / m > 6 (a fast exit): G and G1 keep
// the closed form's bits, for every angle (grazing to the normal) and roughness.
TEST(MicrofacetG, BeckmannNegligibleLambdaKeepsGBits) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int zeroed = 0;
    for (double m : {0.01, 0.05, 0.2, 0.5, 1.0, 3.0}) {
        NormalDistribution d(DKind::Beckmann, m);
        for (int i = 0; i < 20000; ++i) {
            // theta spread so that a = cot(theta) / m covers 0 .. 40 densely around 6
            const double a = 40.0 * u(rng) * u(rng);
            const double th = std::atan2(1.0, a * m);
            const Vec3 wo = spherical_direction(th, 6.0 * u(rng)), wi = spherical_direction(deg(89.9) * u(rng), 0.3);
            const double lo = smith_lambda_beckmann(wo, m), li = smith_lambda_beckmann(wi, m);
            const double fo = d.smith_lambda(wo), fi = d.smith_lambda(wi);
            if (fo != lo) {
                ASSERT_EQ(fo, 0.0);
                ++zeroed;
            }
            ASSERT_EQ(g1_smith(fo), g1_smith(lo)) << m << " " << th;
            ASSERT_EQ(g_smith(fo, fi), g_smith(lo, li)) << m << " " << th;
            ASSERT_EQ(g_smith(fi, fo), g_smith(li, lo)) << m << " " << th;
        }
    }
    EXPECT_GT(zeroed, 10000);
}
