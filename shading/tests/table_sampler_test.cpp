// The renderer's per-light table lookup from cosines (acos_approx, eval_iso_cos) and the
// table's own importance sampler (TableSampler): chi-square of sample() against pdf(),
// unbiasedness against an independent integration, support, memory and sharing.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "sampling_check.h"
#include "shading/finish/finish.h"
#include "shading/brdf/model_spec.h"
#include "shading/tables/table.h"
#include "shading/tables/table_sampler.h"

using namespace shading;
using namespace shading_test;

namespace {

double deg(double d) { return d * kDegree; }

// The white-furnace BRDF of issue 16: Beckmann m = 0.3, height-correlated Smith, F = 1.
const char* kFurnaceSpec = "microfacet d=beckmann m=0.3";

std::shared_ptr<const BrdfTable> make_table(const std::string& spec, double step, bool fold, int channels = 3,
                                            Interp interp = Interp::Linear) {
    BuildOptions o;
    o.fold = fold;
    o.interp = interp;
    return build_table(tabulate(*make_brdf(spec), TableGeometry::isotropic(step, channels)), o);
}

// Directional albedo of the interpolated table by a dense midpoint rule over the hemisphere
// (0.1 x 0.1 deg cells, exact cos sin weights per band): shares nothing with the sampler.
Rgb midpoint_albedo(const BrdfTable& t, const Vec3& wo) {
    const int nt = 900, np = 1800;
    Rgb sum;
    for (int i = 0; i < nt; ++i) {
        const double a = deg(i * 0.1), b = deg((i + 1) * 0.1);
        const double band = 0.5 * (sqr(std::sin(b)) - sqr(std::sin(a))) * (2 * kPi / np);
        const double th = 0.5 * (a + b);
        Rgb ring;
        for (int k = 0; k < np; ++k) ring += t.f(wo, spherical_direction(th, (k + 0.5) * 2 * kPi / np));
        sum += ring * band;
    }
    return sum;
}

}  // namespace

// ---------------------------------------------------------------- lookups from cosines

TEST(AcosApprox, WithinBoundMonotoneAndExactAtTheEnds) {
    double prev = acos_approx(-1.0), worst = 0;
    EXPECT_EQ(prev, kPi);
    const int n = 2000000;
    for (int i = 1; i <= n; ++i) {
        const double x = -1.0 + 2.0 * i / n, v = acos_approx(x);
        worst = std::max(worst, std::abs(v - std::acos(x)));
        ASSERT_LE(v, prev) << x;  // decreasing: interpolation weights never run backwards
        prev = v;
    }
    EXPECT_LT(worst, 1e-10);
    EXPECT_EQ(acos_approx(1.0), 0.0);
    EXPECT_EQ(acos_approx(0.0), kPi / 2);
    EXPECT_EQ(acos_approx(-0.0), kPi / 2);
    EXPECT_EQ(acos_approx(1.5), 0.0);  // clamped
    EXPECT_EQ(acos_approx(-7.0), kPi);
    EXPECT_EQ(acos_approx(std::nan("")), kPi / 2);
    // Both halves meet: acos(-x) = pi - acos(x) to the last bit.
    for (double x : {1e-300, 1e-9, 0.3, 0.7071, 0.999999}) EXPECT_EQ(acos_approx(-x), kPi - acos_approx(x)) << x;
}

TEST(AcosApprox, PairGivesTheBitsOfTwoCalls) {
    // acos_approx2 (two lanes of one SSE2 register) against acos_approx, bit for bit, over
    // the whole domain and its edges: signed zeros, +-1, beyond +-1, infinities and NaN.
    std::vector<double> xs = {0.0, -0.0, 1.0, -1.0, 1.0 + 1e-16, -1.0 - 1e-16, 1.5, -7.0, 1e-300, -1e-300,
                              std::nextafter(1.0, 0.0), std::nextafter(-1.0, 0.0), 0.5, -0.5, 0.7071067811865476,
                              HUGE_VAL, -HUGE_VAL, std::nan("")};
    Rng rng(77);
    for (int i = 0; i < 200000; ++i) xs.push_back(2.2 * rng() - 1.1);
    for (size_t i = 0; i < xs.size(); ++i) {
        const double x = xs[i], y = xs[(i * 7919 + 13) % xs.size()];
        double ax, ay;
        acos_approx2(x, y, &ax, &ay);
        const double ex = acos_approx(x), ey = acos_approx(y);
        ASSERT_EQ(std::memcmp(&ax, &ex, sizeof ax), 0) << x << " " << ax << " " << ex;
        ASSERT_EQ(std::memcmp(&ay, &ey, sizeof ay), 0) << y << " " << ay << " " << ey;
    }
}

TEST(Atan2Upper, WithinRelativeBoundOfLibmEverywhereAbove) {
    // atan2_upper (vec.h) against libm's atan2 for y >= 0: relative error <= 1e-15 (stated
    // bound; the fit's own is 3e-16, the rest is the rounding of the reduction), absolute
    // 4e-16 near pi, over random pairs, tiny and huge ratios, both signs of x and the
    // special pairs. The half/difference axis theta_h is sqrt-spaced: its first node is at
    // ~6e-6 rad, so a relative bound is what keeps small angles on their cells.
    constexpr double kRelBound = 1e-15;
    Rng rng(91);
    double worst = 0;
    auto check = [&](double y, double x) {
        const double got = atan2_upper(y, x), want = std::atan2(y, x);
        const double err = std::fabs(got - want);
        ASSERT_LE(err, kRelBound * want + 4e-16) << y << " " << x << " " << got << " " << want;
        if (want > 1e-300) worst = std::max(worst, err / want);
    };
    for (int i = 0; i < 400000; ++i) {
        const double y = rng(), x = 2.0 * rng() - 1.0;
        check(y, x);
        check(y * 1e-9, x);                      // small angles (and near pi for x < 0)
        check(y, x * 1e-9);                      // near pi/2
        check(std::ldexp(y, -int(60 * rng())), 1.0);
    }
    for (double y : {0.0, 1e-300, 1e-20, 0.5, 1.0, 1e20})
        for (double x : {1.0, -1.0, 1e-300, -1e-300, 0.41421356237309503, -0.41421356237309503, 1e20, -1e20}) check(y, x);
    std::printf("[ measured ] atan2_upper vs libm atan2: worst relative error %.2e\n", worst);
    EXPECT_EQ(atan2_upper(0.0, 0.0), 0.0);
    EXPECT_EQ(atan2_upper(0.0, -1.0), kPi);
    EXPECT_EQ(atan2_upper(1.0, 1.0), kPi / 4);
    EXPECT_TRUE(std::isnan(atan2_upper(std::nan(""), 1.0)));
    EXPECT_TRUE(std::isnan(atan2_upper(1.0, std::nan(""))));
}

TEST(Atan2Upper, PairGivesTheBitsOfTwoCalls) {
    // atan2_upper2 (two lanes of one SSE2 register, branches as masks) against atan2_upper,
    // bit for bit: random pairs of both signs of x, each side of the reduction (|u| = tan(pi/8))
    // and of y = |x|, tiny and huge ratios, signed zeros, infinities and NaN (the scalar
    // fallback), each lane paired with the others.
    std::vector<double> ys = {0.0, 1e-300, 1e-20, 0.5, 1.0, 1e20, HUGE_VAL, std::nan("")};
    std::vector<double> xs = {1.0, -1.0, 0.0, -0.0, 1e-300, -1e-300, 0.41421356237309503, -0.41421356237309503,
                              std::nextafter(0.41421356237309503, 1.0), 1e20, -1e20, HUGE_VAL, -HUGE_VAL,
                              std::nan("")};
    Rng rng(93);
    for (int i = 0; i < 100000; ++i) {
        const double y = rng(), x = 2.0 * rng() - 1.0;
        ys.push_back(y);
        xs.push_back(x);
        ys.push_back(y * 1e-9);
        xs.push_back(i % 2 ? y : -y);  // y = |x|: neither y < |x| nor y > |x|
    }
    const size_t n = std::max(ys.size(), xs.size());
    for (size_t i = 0; i < n; ++i) {
        const double y0 = ys[i % ys.size()], x0 = xs[i % xs.size()];
        const double y1 = ys[(i * 7919 + 13) % ys.size()], x1 = xs[(i * 104729 + 7) % xs.size()];
        double a0, a1;
        atan2_upper2(y0, x0, y1, x1, &a0, &a1);
        const double e0 = atan2_upper(y0, x0), e1 = atan2_upper(y1, x1);
        ASSERT_EQ(std::memcmp(&a0, &e0, sizeof a0), 0) << y0 << " " << x0 << " " << a0 << " " << e0;
        ASSERT_EQ(std::memcmp(&a1, &e1, sizeof a1), 0) << y1 << " " << x1 << " " << a1 << " " << e1;
    }
}

TEST(TableLookup, CosineLookupFindsTheRowsAndWeightsOfItsDefinition) {
    // prepare_iso_cos (both axes located at once on the renderer's path) against the layout
    // written out here: theta = acos_approx(cos) in degrees over the step, clamped to
    // [0, n - 1], cell (min(floor x, n - 2), +1), weight x minus the cell; folded rows in
    // numpy.triu_indices order. Includes lights at the pole, at grazing, along and against
    // the viewer's azimuth, and out-of-range and NaN cosines.
    for (bool fold : {false, true})
        for (double step : {1.0, 2.0, 5.0}) {
            auto t = make_table("microfacet d=beckmann m=0.2 f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8", step, fold);
            const TableGeometry& g = t->geometry();
            const uint32_t nt = g.n[0], np = g.n[2];
            auto axis = [&](double c, uint32_t n, double step_deg) {
                double x = acos_approx(c) * (180.0 / kPi) * (1.0 / step_deg);
                x = x > 0 ? std::min(x, double(n - 1)) : 0.0;
                const uint32_t i0 = std::min(uint32_t(x), n - 2);
                return std::make_pair(i0, x - double(i0));
            };
            auto row = [&](uint32_t i, uint32_t r, uint32_t p) {
                uint64_t cell;
                if (!fold) {
                    cell = (uint64_t(i) * nt + r) * np + p;
                } else {
                    const uint64_t a = std::min(i, r), b = std::max(i, r);
                    cell = (a * nt - a * (a - 1) / 2 + (b - a)) * np + p;  // triu pairs before (a, b)
                }
                return t->values().data() + cell * 3;
            };
            Rng rng(5);
            std::vector<std::pair<double, double>> cases = {{1.0, 1.0}, {1.0, -1.0}, {0.0, 0.3}, {1e-12, -1.0},
                                                            {1.5, 2.0}, {-0.2, -3.0}, {std::nan(""), 0.5},
                                                            {0.5, std::nan("")}, {0.999999, 0.999999}};
            for (int k = 0; k < 20000; ++k) cases.push_back({rng(), 2 * rng() - 1});
            const BrdfTable::AxisPos tr = t->locate_theta_r_cos(0.8, Interp::Linear);
            for (auto [ci, cp] : cases) {
                BrdfTable::IsoRead rd;
                t->prepare_iso_cos(ci, tr, cp, Interp::Linear, &rd);
                const auto [i0, ti] = axis(std::clamp(ci, 0.0, 1.0), nt, step);
                const auto [p0, tp] = axis(cp, np, step);
                ASSERT_EQ(rd.t_i, ti) << ci;
                ASSERT_EQ(rd.t_phi, tp) << cp;
                ASSERT_EQ(rd.t_r, tr.t);
                ASSERT_EQ(rd.dphi, 3u);
                ASSERT_EQ(rd.row[0], row(i0, tr.i0, p0)) << ci << " " << cp;
                ASSERT_EQ(rd.row[1], row(i0 + 1, tr.i0, p0));
                ASSERT_EQ(rd.row[2], row(i0, tr.i1, p0));
                ASSERT_EQ(rd.row[3], row(i0 + 1, tr.i1, p0));
                // The read: the eight corners' weighted sum, per channel (a coloured table, so
                // a channel mix-up shows).
                const Rgb got = BrdfTable::read_iso(rd);
                for (int c = 0; c < 3; ++c) {
                    double want = 0;
                    for (int corner = 0; corner < 8; ++corner) {
                        const int bi = corner & 1, br = (corner >> 1) & 1, bp = (corner >> 2) & 1;
                        const double w = (bi ? ti : 1 - ti) * (br ? tr.t : 1 - tr.t) * (bp ? tp : 1 - tp);
                        want += w * row(i0 + bi, br ? tr.i1 : tr.i0, p0 + bp)[c];
                    }
                    ASSERT_NEAR(got[c], want, 1e-12 * (1 + std::fabs(want))) << c << " " << ci << " " << cp;
                }
            }
        }
}

TEST(TableLookup, CosineLookupEqualsTheAngleLookup) {
    Rng rng(2024);
    for (bool fold : {false, true})
        for (int channels : {1, 3}) {
            auto t = make_table("microfacet d=beckmann m=0.2 f=dielectric eta=1.5 kd=0.3 rho_s=0.7", 2.0, fold, channels);
            double scale = 0;
            for (float v : t->values()) scale = std::max(scale, double(v));
            for (int s = 0; s < 20000; ++s) {
                const double ti = rng() * kPi / 2, tr = rng() * kPi / 2, phi = rng() * kPi;
                const Rgb want = t->eval_iso(ti, tr, phi, Interp::Linear);
                const Rgb got = t->eval_iso_cos(std::cos(ti), std::cos(tr), std::cos(phi), Interp::Linear);
                // 1e-10 rad on a 2 deg cell moves the weights by 3e-9.
                for (int c = 0; c < 3; ++c) ASSERT_NEAR(got[c], want[c], 1e-8 * scale) << ti << " " << tr << " " << phi;
            }
        }
}

// ---------------------------------------------------------------- the sampler

TEST(TableSampler, ChiSquareSampleMatchesPdf) {
    struct Case {
        const char* spec;
        double step;
        bool fold;
        int channels;
        double theta_o, phi_o;
    };
    // Histogram cells are unions of table cells (5 deg for 1 and 5 deg tables, 10 deg for the
    // 2 deg table) or quarters of them (10 deg table), so the pdf is smooth inside every
    // quadrature sub-cell; viewers on nodes, between nodes, at the pole and near grazing.
    const Case cases[] = {
        {kFurnaceSpec, 1.0, true, 3, 30.4, 0},
        {kFurnaceSpec, 1.0, true, 3, 60.0, 0},
        {kFurnaceSpec, 1.0, true, 3, 0.0, 0},
        {kFurnaceSpec, 1.0, true, 3, 85.7, 20},
        {"microfacet d=tr m=0.1 f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8 kd=0.2 rho_s=0.8", 1.0, false, 3, 45.5, 0},
        {"microfacet d=beckmann m=0.05 f=dielectric eta=1.5", 1.0, true, 3, 20.2, 0},  // cells of zero
        {"ward alpha=0.1 rho_d=0.2 rho_s=0.5", 2.0, false, 3, 70.3, 0},
        {"phong_pov phong=0.6 phong_size=20 diffuse=0.3", 5.0, false, 1, 37.0, 0},
        // Histogram cells a quarter of a table cell: the density inside a cell (cos-weighted)
        // is tested too, not only the cells' probabilities.
        {"microfacet d=beckmann m=0.4 kd=0.3 rho_s=0.7", 10.0, true, 3, 33.0, 0},
    };
    const int kTests = sizeof(cases) / sizeof(cases[0]);
    const double alpha = 0.01, sidak = 1.0 - std::pow(1.0 - alpha, 1.0 / kTests);
    uint64_t seed = 4242;
    for (const Case& c : cases) {
        auto t = make_table(c.spec, c.step, c.fold, c.channels);
        const Vec3 wo = spherical_direction(deg(c.theta_o), deg(c.phi_o));
        const int kT = c.step == 2.0 ? 9 : 18, kP = 4 * kT, kSub = c.step >= 5.0 ? 1 : 5;
        Chi2 r = chi2_test([&](double u1, double u2) { return t->sample(wo, u1, u2); },
                           [&](const Vec3& wi) { return t->pdf(wo, wi); }, 200000, seed++, kSub, kT, kP,
                           Quadrature::Gauss);
        EXPECT_GT(r.p, sidak) << c.spec << " theta_o=" << c.theta_o << ": chi2=" << r.chi2 << " dof=" << r.dof;
        EXPECT_GT(r.dof, 20) << c.spec;
        // Nearly every sample is valid (a half vector whose reflection is below the horizon is
        // "no sample"), and the pdf integrates to the valid fraction.
        EXPECT_GT(r.valid_fraction, 0.999) << c.spec;
        EXPECT_NEAR(r.pdf_mass, r.valid_fraction, 2e-3) << c.spec;
    }
}

TEST(TableSampler, ChiSquareDetectsAWrongPdf) {
    // The test has power: samples of the m = 0.3 table against the pdf of an m = 0.32 table.
    auto right = make_table(kFurnaceSpec, 1.0, true), wrong = make_table("microfacet d=beckmann m=0.32", 1.0, true);
    const Vec3 wo = spherical_direction(deg(30.4), 0);
    Chi2 r = chi2_test([&](double u1, double u2) { return right->sample(wo, u1, u2); },
                       [&](const Vec3& wi) { return wrong->pdf(wo, wi); }, 200000, 99, 5, 18, 72, Quadrature::Gauss);
    EXPECT_LT(r.p, 1e-6);
}

TEST(TableSampler, EstimatorIsUnbiased) {
    // White furnace of the table: the mean of f cos / pdf over sampled directions is the
    // directional albedo of the interpolated table (a midpoint rule, independent of the
    // sampler), within 0.3 %; and it agrees with the table's own albedo nodes.
    auto t = make_table(kFurnaceSpec, 1.0, true);
    Rng rng(11);
    for (double th : {0.0, 25.5, 60.0, 80.3}) {
        const Vec3 wo = spherical_direction(deg(th), deg(10.0));
        const int n = 200000;
        Rgb sum;
        double sum2 = 0;
        for (int s = 0; s < n; ++s) {
            const Vec3 wi = t->sample(wo, rng(), rng());
            if (!(wi.z > 0)) continue;
            const Rgb v = t->f(wo, wi) * (wi.z / t->pdf(wo, wi));
            sum += v;
            sum2 += sqr(v.g);
        }
        const Rgb est = sum / n, want = midpoint_albedo(*t, wo);
        const double sd = std::sqrt(std::max(0.0, sum2 / n - sqr(est.g)) / n);
        EXPECT_NEAR(est.g / want.g, 1.0, 3e-3) << "theta_o " << th << " (standard error " << sd / want.g << ")";
        EXPECT_LT(sd / want.g, 1e-3) << "theta_o " << th;  // importance sampling: small variance
        EXPECT_NEAR(t->directional_albedo(deg(th)).g / want.g, 1.0, 3e-3) << th;
    }
}

TEST(TableSampler, SamplesOnlyWhereTheTableIsPositive) {
    // A narrow lobe (m = 0.05) leaves most of a 1 deg table exactly zero: no sample may land
    // where f = 0, and the pdf is zero there but positive wherever f is.
    auto t = make_table("microfacet d=beckmann m=0.05", 1.0, true);
    const Vec3 wo = spherical_direction(deg(40.5), 0);
    Rng rng(5);
    int zeros = 0, checked = 0;
    for (int s = 0; s < 50000; ++s) {
        const Vec3 wi = t->sample(wo, rng(), rng());
        ASSERT_GT(wi.z, 0.0);
        EXPECT_NEAR(length(wi), 1.0, 1e-12);
        ASSERT_GT(t->pdf(wo, wi), 0.0);
        zeros += t->f(wo, wi).g == 0.0;
    }
    EXPECT_EQ(zeros, 0);
    for (int s = 0; s < 200000; ++s) {
        const Vec3 wi = spherical_direction(std::acos(rng()), 2 * kPi * rng());
        const bool f_pos = t->f(wo, wi).max_component() > 0, p_pos = t->pdf(wo, wi) > 0;
        if (f_pos) {
            ASSERT_TRUE(p_pos) << wi.x << " " << wi.y << " " << wi.z;
        }
        checked += !p_pos;
    }
    EXPECT_GT(checked, 100000);  // most of the hemisphere has no lobe: the sampler knows
    EXPECT_EQ(t->pdf(wo, Vec3(0, 0, -1)), 0.0);
    EXPECT_EQ(t->sample(Vec3(0, 0, -1), 0.5, 0.5).z, 0.0);  // viewer below: no sample
}

TEST(TableSampler, BuiltOnceSharedAndCounted) {
    const size_t before = TableSampler::memory().live;
    size_t bytes = 0;
    {
        auto t = make_table(kFurnaceSpec, 1.0, true);
        EXPECT_EQ(t->sampler_bytes(), 0u);  // nothing until glossy rays ask
        const TableSampler* s = t->sampler();
        ASSERT_NE(s, nullptr);
        EXPECT_EQ(t->sampler(), s);
        bytes = t->sampler_bytes();
        // 91 theta_o nodes x 90 x 180 cells x 4 bytes, plus the rows: 5.9 MB (the values are
        // the table's own).
        const size_t per_node = 90 * 180 * 4 + 90 * 4;
        EXPECT_EQ(s->viewer_nodes(), 91);
        EXPECT_GT(bytes, 91u * per_node);
        EXPECT_LT(bytes, 91u * per_node + 10000);
        EXPECT_LT(double(bytes), 0.7 * double(t->values().size() * sizeof(float)));
        EXPECT_EQ(TableSampler::memory().live, before + bytes);
        EXPECT_GE(TableSampler::memory().peak, before + bytes);
        // A finish on the table samples through the same sampler.
        auto m = make_finish_model(t, Interp::Nearest);
        EXPECT_EQ(m->brdf->pdf(Vec3(0, 0, 1), normalize(Vec3(0.1, 0.2, 1))),
                  t->pdf(Vec3(0, 0, 1), normalize(Vec3(0.1, 0.2, 1))));
        EXPECT_EQ(t->sampler_bytes(), bytes);
    }
    EXPECT_EQ(TableSampler::memory().live, before);
    // Anisotropic tables have one too: 19 theta_o x 12 phi_o viewer nodes of a 5 deg table.
    BuildOptions o;
    auto a = build_table(tabulate(*make_brdf("ward ax=0.1 ay=0.3"), TableGeometry::anisotropic(5.0, 5.0)), o);
    ASSERT_NE(a->sampler(), nullptr);
    EXPECT_EQ(a->sampler()->viewer_nodes(), 19 * 12);
}

TEST(TableSampler, ConcurrentFirstUseBuildsOne) {
    auto t = make_table(kFurnaceSpec, 2.0, true);
    std::vector<const TableSampler*> seen(4, nullptr);
    std::vector<std::thread> threads;
    std::atomic<int> go{0};
    for (int i = 0; i < 4; ++i)
        threads.emplace_back([&, i] {
            while (go.load() == 0) {
            }
            seen[i] = t->sampler();
            (void)t->sample(spherical_direction(deg(20 + i), 0), 0.3, 0.6);
        });
    go = 1;
    for (auto& th : threads) th.join();
    for (int i = 1; i < 4; ++i) EXPECT_EQ(seen[i], seen[0]);
}

TEST(TableSampler, FinishReflectionOfATableIsItsAlbedo) {
    // finish_reflection_sample on a table finish (the renderer's glossy rays): 400 hit points
    // x 64 stratified rays average to the table's directional albedo.
    auto t = make_table(kFurnaceSpec, 1.0, true);
    auto m = make_finish_model(t, Interp::Linear);
    m->reflection_samples = 64;
    const Vec3 n = normalize(Vec3(0.2, 0.3, 1.0));
    for (double th : {0.0, 45.0, 75.0}) {
        const Vec3 eye = Frame::from_normal(n).to_world(spherical_direction(deg(th), 0.0));
        Rgb sum;
        for (int p = 0; p < 400; ++p) {
            const std::uint64_t seed = finish_sample_seed(Vec3(p, 0.5, 1), Vec3(0, 0, -1));
            for (int k = 0; k < 64; ++k) {
                Vec3 dir;
                Rgb w;
                if (finish_reflection_sample(*m, n, eye, Rgb(1.0), seed, k, &dir, &w)) sum += w;
            }
        }
        const Rgb est = sum / 400.0, want = t->directional_albedo(deg(th));
        EXPECT_NEAR(est.g, want.g, 3e-3 * want.g) << th;
    }
}

// ---------------------------------------------------------------- half/difference tables

namespace {
std::shared_ptr<const BrdfTable> make_halfdiff(const std::string& spec, uint32_t nh, uint32_t nd, uint32_t np) {
    return build_table(tabulate(*make_brdf(spec), TableGeometry::halfdiff(nh, nd, np)), BuildOptions());
}
}  // namespace

namespace {
// The white-furnace estimator of the table's albedo at wo with its own sampler and with the
// generic mixture (Brdf::sample, for scale) from the same n uniform pairs: sums of the
// weights and of the green channel's squares.
struct Estimate {
    int n;
    Rgb sum, sum_generic;
    double sq = 0, sq_generic = 0;
};
Estimate estimate_with_generic(const BrdfTable& t, const Vec3& wo, uint64_t seed, int n) {
    Rng rng(seed);
    Estimate e{n, Rgb(), Rgb()};
    for (int s = 0; s < n; ++s) {
        const double u1 = rng(), u2 = rng();
        const Vec3 wi = t.sample(wo, u1, u2);
        if (wi.z > 0) {
            const Rgb v = t.f(wo, wi) * (wi.z / t.pdf(wo, wi));
            e.sum += v;
            e.sq += sqr(v.g);
        }
        const Vec3 wg = t.Brdf::sample(wo, u1, u2);
        if (wg.z > 0) {
            const Rgb v = t.f(wo, wg) * (wg.z / t.Brdf::pdf(wo, wg));
            e.sum_generic += v;
            e.sq_generic += sqr(v.g);
        }
    }
    return e;
}

// One viewer of a table's own sampler: sample() against pdf() by chi-square (Sidak-corrected
// level `sidak`, `sub` quadrature points per histogram cell and axis), the valid fraction
// (at least `valid_min`) and the pdf's mass, then the white-furnace estimator from 100000
// pairs: unbiased against the midpoint rule (5e-3), with a variance under 0.2 x the generic
// mixture's (whose own estimate is checked too when `generic_tol` > 0). Returns the variance.
double check_own_sampler(const BrdfTable& t, const Vec3& wo, uint64_t seed, double sidak, int sub, double valid_min,
                         double generic_tol, const std::string& what) {
    Chi2 r = chi2_test([&](double u1, double u2) { return t.sample(wo, u1, u2); },
                       [&](const Vec3& wi) { return t.pdf(wo, wi); }, 200000, seed, sub, 18, 72, Quadrature::Gauss);
    EXPECT_GT(r.p, sidak) << what << ": chi2=" << r.chi2 << " dof=" << r.dof;
    EXPECT_GT(r.valid_fraction, valid_min) << what;
    EXPECT_NEAR(r.pdf_mass, r.valid_fraction, 3e-3) << what;
    const Estimate e = estimate_with_generic(t, wo, seed + 1000, 100000);
    const int n = e.n;
    const Rgb want = midpoint_albedo(t, wo);
    EXPECT_NEAR((e.sum / n).g / want.g, 1.0, 5e-3) << what;
    if (generic_tol > 0) EXPECT_NEAR((e.sum_generic / n).g / want.g, 1.0, generic_tol) << what;
    const double var = e.sq / n - sqr((e.sum / n).g), var_generic = e.sq_generic / n - sqr((e.sum_generic / n).g);
    EXPECT_LT(var, 0.2 * var_generic) << what << ": " << var << " vs " << var_generic;
    std::printf("%s: variance %.3g, generic mixture %.3g\n", what.c_str(), var, var_generic);
    return var;
}
}  // namespace

TEST(TableSampler, HalfDiffTableSampledFromItsOwnValues) {
    // A narrow lobe (m = 0.05) in the layout made for it: the sampler works on a grid over the
    // half vector (table_sampler.h); sample() and pdf() agree (chi-square), nearly every sample
    // is valid, and the estimator of the directional albedo is unbiased against a midpoint rule
    // with a variance far below the generic mixture's.
    auto t = make_halfdiff("microfacet d=beckmann m=0.05 f=dielectric eta=1.5 kd=0.2 rho_s=0.8", 128, 64, 16);
    const double sidak = 1.0 - std::pow(1.0 - 0.01, 1.0 / 2.0);
    uint64_t seed = 777;
    for (double th : {20.2, 55.5})
        check_own_sampler(*t, spherical_direction(deg(th), deg(15.0)), seed++, sidak, 5, 0.999, 3e-2,
                          "halfdiff sampler, theta_o " + std::to_string(th));
    EXPECT_EQ(t->sample(Vec3(0, 0, -1), 0.5, 0.5).z, 0.0);
}

TEST(TableSampler, HalfVectorGridReachesEveryDirectionAndSpendsLittleWhereTheTableIsZero) {
    // A narrow lobe (m = 0.05) leaves most of a half/difference table nearly zero: the pdf is positive
    // wherever f is (the estimator is unbiased), and samples where f = 0 (each a zero weight
    // that adds its rate to the relative variance) are rare: the floors of table_sampler.h.
    auto t = build_table(tabulate(*make_brdf("microfacet d=beckmann m=0.05"), TableGeometry::halfdiff(128, 64, 16)), BuildOptions());
    const Vec3 wo = spherical_direction(deg(40.5), 0);
    Rng rng(5);
    int zeros = 0, none = 0;
    const int n = 200000;
    for (int s = 0; s < n; ++s) {
        const Vec3 wi = t->sample(wo, rng(), rng());
        if (!(wi.z > 0)) {
            ++none;
            continue;
        }
        EXPECT_NEAR(length(wi), 1.0, 1e-12);
        ASSERT_GT(t->pdf(wo, wi), 0.0);
        zeros += t->f(wo, wi).g < 1e-6 * t->f(wo, normalize(Vec3(-wo.x, -wo.y, wo.z))).g;
    }
    EXPECT_LT(zeros + none, n / 5000) << zeros << " samples where f < 1e-6 of its peak, " << none << " without a direction";
    int zero_pdf = 0;
    for (int s = 0; s < 200000; ++s) {
        const Vec3 wi = spherical_direction(std::acos(rng()), 2 * kPi * rng());
        const bool f_pos = t->f(wo, wi).max_component() > 0, p_pos = t->pdf(wo, wi) > 0;
        if (f_pos) {
            ASSERT_TRUE(p_pos) << wi.x << " " << wi.y << " " << wi.z;
        }
        zero_pdf += !p_pos;
    }
    EXPECT_EQ(zero_pdf, 0);  // the floors keep the whole hemisphere reachable
    EXPECT_EQ(t->pdf(wo, Vec3(0, 0, -1)), 0.0);
    EXPECT_EQ(t->sample(Vec3(0, 0, -1), 0.5, 0.5).z, 0.0);  // viewer below: no sample
}

// ---------------------------------------------------------------- anisotropic tables

TEST(TableSampler, AnisotropicTableSampledFromItsOwnValues) {
    // An anisotropic lobe (Ward, alpha 0.1 x 0.3) as a 5 deg anisotropic table: sample() and
    // pdf() agree (chi-square), nearly every sample is valid, and the estimator of the albedo is
    // unbiased against a midpoint rule with a variance far below the generic mixture's.
    BuildOptions o;
    auto t = build_table(tabulate(*make_brdf("ward ax=0.1 ay=0.3 rho_d=0.1 rho_s=0.6"), TableGeometry::anisotropic(5.0, 5.0)), o);
    const double sidak = 1.0 - std::pow(1.0 - 0.01, 1.0 / 3.0);
    uint64_t seed = 31;
    for (auto [th, ph] : {std::pair{22.0, 17.0}, std::pair{50.0, 100.0}, std::pair{71.0, 250.0}})
        check_own_sampler(*t, spherical_direction(deg(th), deg(ph)), seed++, sidak, 3, 0.995, 0.0,
                          "anisotropic sampler, theta_o " + std::to_string(th) + " phi_o " + std::to_string(ph));
}
