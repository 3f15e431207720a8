// BrdfTable lookups (nodes, interpolation, phi folding, pole, grazing edge, reciprocity
// folding), no-data policies, albedo, and the .brdf loader's validation.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <new>
#include <random>
#include <regex>
#include <thread>

#include "shading/core/bytes.h"
#include "shading/brdf/models.h"
#include "shading/tables/table.h"
#include "table_files.h"

// The replacement operators below pair malloc with free on purpose; GCC's heuristic
// cannot see that both sides are replaced.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

// Largest single allocation while `g_track` is set: the loader must reject absurd headers
// before sizing anything from them. Replacing the global operator new is legal C++ and
// affects only this test binary.
static std::atomic<bool> g_track{false};
static std::atomic<size_t> g_max_alloc{0};
void* operator new(std::size_t n) {
    if (g_track.load(std::memory_order_relaxed)) {
        size_t m = g_max_alloc.load(std::memory_order_relaxed);
        while (n > m && !g_max_alloc.compare_exchange_weak(m, n)) {
        }
    }
    if (void* p = std::malloc(n ? n : 1)) return p;
    throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

using namespace shading;

namespace {

constexpr double kDeg = kDegree;  // short name for the many angles below

struct TestLambert final : Brdf {
    Rgb rho;
    explicit TestLambert(Rgb r) : rho(r) {}
    Rgb f(const Vec3& wo, const Vec3& wi) const override {
        return (wo.z <= 0 || wi.z <= 0) ? Rgb(0.0) : rho * kInvPi;
    }
    std::string describe() const override { return "test-lambert"; }
};

// Grid whose values are fn(node angles in degrees, channel).
TableGrid grid_from(const TableGeometry& g, const std::function<double(const double*, int)>& fn) {
    TableGrid grid(g);
    const TableGeometry& gg = grid.geom;
    uint32_t idx[4] = {0, 0, 0, 0};
    for (idx[0] = 0; idx[0] < gg.n[0]; ++idx[0])
        for (idx[1] = 0; idx[1] < gg.n[1]; ++idx[1])
            for (idx[2] = 0; idx[2] < gg.n[2]; ++idx[2])
                for (idx[3] = 0; idx[3] < (gg.axes() == 4 ? gg.n[3] : 1u); ++idx[3]) {
                    double deg[4];
                    for (int a = 0; a < 4; ++a) deg[a] = a < gg.axes() ? gg.axis_deg(a, idx[a]) : 0.0;
                    for (int c = 0; c < gg.channels; ++c)
                        grid.at(idx[0], idx[1], idx[2], idx[3], c) = float(fn(deg, c));
                }
    return grid;
}

std::unique_ptr<BrdfTable> table_from(const TableGeometry& g, const std::function<double(const double*, int)>& fn,
                                      bool fold = false) {
    BuildOptions bo;
    bo.fold = fold;
    bo.nodata = NoDataPolicy::Reject;
    return build_table(grid_from(g, fn), bo);
}

// Multilinear in (theta_i, theta_r, phi): trilinear interpolation reproduces it exactly.
double multilinear(const double* d, int c) {
    return 0.5 + 0.01 * d[0] + 0.02 * d[1] + 0.003 * d[2] + 1e-4 * d[0] * d[2] + 0.1 * c;
}

void expect_rgb_near(const Rgb& a, const Rgb& b, double tol) {
    EXPECT_NEAR(a.r, b.r, tol);
    EXPECT_NEAR(a.g, b.g, tol);
    EXPECT_NEAR(a.b, b.b, tol);
}

void expect_rgb_eq(const Rgb& a, const Rgb& b) {
    EXPECT_EQ(a.r, b.r);
    EXPECT_EQ(a.g, b.g);
    EXPECT_EQ(a.b, b.b);
}

std::vector<uint8_t> encoded(const BrdfTable& t) { return encode_table(t); }

using table_files::fix_checksum;
std::string load_error(const std::vector<uint8_t>& b, const LoadOptions& opt = {}) {
    return table_files::load_error(b, "t.brdf", opt);
}
void expect_error_format(const std::string& msg, uint64_t offset) { table_files::expect_error_at(msg, "t.brdf", offset); }

}  // namespace

// ---------------------------------------------------------------- geometry

TEST(TableGeometry, DefaultIsOneDegree) {
    TableGeometry g = TableGeometry::isotropic();
    EXPECT_EQ(g.n[0], 91u);
    EXPECT_EQ(g.n[1], 91u);
    EXPECT_EQ(g.n[2], 181u);
    EXPECT_EQ(g.values(), 91ull * 91 * 181 * 3);
    EXPECT_EQ(g.axis_deg(0, 90), 90.0);
    EXPECT_EQ(g.axis_deg(2, 180), 180.0);
    TableGeometry f = TableGeometry::isotropic(1.0, 3, true);
    EXPECT_EQ(f.values(), 91ull * 92 / 2 * 181 * 3);  // about half
    TableGeometry a = TableGeometry::anisotropic(10, 15, 1);
    EXPECT_EQ(a.n[0], 10u);
    EXPECT_EQ(a.n[1], 24u);
    EXPECT_DOUBLE_EQ(a.step_deg(3), 15.0);
    EXPECT_THROW(TableGeometry::isotropic(7.0), std::invalid_argument);  // does not divide 90
    EXPECT_THROW(TableGeometry::isotropic(0.0), std::invalid_argument);
    EXPECT_THROW(TableGeometry::isotropic(1.0, 2), std::invalid_argument);
}

// ---------------------------------------------------------------- lookups

TEST(BrdfTable, ExactAtNodes) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 2.0);
    auto g = TableGeometry::isotropic(5.0);
    TableGrid grid = grid_from(g, [&](const double*, int) { return u(rng); });
    std::vector<float> orig = grid.values;
    BuildOptions bo;
    auto t = build_table(std::move(grid), bo);
    // Away from the pole rows (theta = 0), which are averaged over phi by design.
    for (uint32_t i = 1; i < 19; i += 3)
        for (uint32_t r = 1; r < 19; r += 2)
            for (uint32_t p = 0; p < 37; p += 4)
                for (Interp in : {Interp::Linear, Interp::Nearest}) {
                    Rgb v = t->eval_iso(5.0 * i * kDeg, 5.0 * r * kDeg, 5.0 * p * kDeg, in);
                    size_t k = ((size_t(i) * 19 + r) * 37 + p) * 3;
                    EXPECT_NEAR(v.r, orig[k], 1e-6);
                    EXPECT_NEAR(v.g, orig[k + 1], 1e-6);
                    EXPECT_NEAR(v.b, orig[k + 2], 1e-6);
                    EXPECT_EQ(t->node(i, r, p, 0, 1), orig[k + 1]);
                }
}

TEST(BrdfTable, LinearBetweenNodes) {
    auto t = table_from(TableGeometry::isotropic(5.0), multilinear);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> ti(5.0, 90.0), tr(5.0, 90.0), ph(0.0, 180.0);  // off the pole cells
    for (int k = 0; k < 500; ++k) {
        double d[3] = {ti(rng), tr(rng), ph(rng)};
        Rgb v = t->eval_iso(d[0] * kDeg, d[1] * kDeg, d[2] * kDeg, Interp::Linear);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], multilinear(d, c), 2e-5) << d[0] << " " << d[1] << " " << d[2];
    }
    // Midway between two theta_i nodes: the mean of the two nodes.
    double mid = t->eval_iso(12.5 * kDeg, 40 * kDeg, 90 * kDeg, Interp::Linear).r;
    EXPECT_NEAR(mid, 0.5 * (t->node(2, 8, 18, 0, 0) + t->node(3, 8, 18, 0, 0)), 1e-6);
}

TEST(BrdfTable, NearestPicksClosestNode) {
    auto t = table_from(TableGeometry::isotropic(5.0), multilinear);
    Rgb v = t->eval_iso(12.4 * kDeg, 41.0 * kDeg, 93.0 * kDeg, Interp::Nearest);
    EXPECT_EQ(v.r, t->node(2, 8, 19, 0, 0));
    Rgb w = t->eval_iso(12.6 * kDeg, 43.0 * kDeg, 92.0 * kDeg, Interp::Nearest);
    EXPECT_EQ(w.r, t->node(3, 9, 18, 0, 0));
}

TEST(BrdfTable, PhiMirrorSymmetry) {
    auto t = table_from(TableGeometry::isotropic(5.0), multilinear);
    for (double phi : {0.0, 7.0, 93.3, 179.0, 180.0}) {
        Rgb a = t->eval_iso(33 * kDeg, 51 * kDeg, phi * kDeg);
        expect_rgb_eq(t->eval_iso(33 * kDeg, 51 * kDeg, -phi * kDeg), a);
        expect_rgb_near(t->eval_iso(33 * kDeg, 51 * kDeg, (360 - phi) * kDeg), a, 1e-9);
        expect_rgb_near(t->eval_iso(33 * kDeg, 51 * kDeg, (360 + phi) * kDeg), a, 1e-9);
        expect_rgb_near(t->eval_iso(33 * kDeg, 51 * kDeg, (phi - 720) * kDeg), a, 1e-9);
    }
    // phi just past 180 folds back: 181 reads like 179.
    expect_rgb_near(t->eval_iso(33 * kDeg, 51 * kDeg, 181 * kDeg), t->eval_iso(33 * kDeg, 51 * kDeg, 179 * kDeg), 1e-9);
    // Endpoints are exact nodes.
    EXPECT_NEAR(t->eval_iso(30 * kDeg, 50 * kDeg, kPi).r, t->node(6, 10, 36, 0, 0), 1e-6);
    EXPECT_NEAR(t->eval_iso(30 * kDeg, 50 * kDeg, 0.0).r, t->node(6, 10, 0, 0, 0), 1e-6);
    // Through f(): wo at azimuth +phi and -phi (relative to wi) read the same value.
    Vec3 wi = spherical_direction(33 * kDeg, 0.4);
    for (double phi : {0.3, 1.7, 3.0}) {
        Vec3 a = spherical_direction(51 * kDeg, 0.4 + phi), b = spherical_direction(51 * kDeg, 0.4 - phi);
        expect_rgb_near(t->f(a, wi), t->f(b, wi), 1e-9);
        expect_rgb_near(t->f(a, wi), t->eval_iso(33 * kDeg, 51 * kDeg, phi), 1e-9);
    }
}

TEST(BrdfTable, PoleDoesNotDependOnPhi) {
    // Raw data that (wrongly) varies with phi at theta_i = 0 and theta_r = 0.
    auto g = TableGeometry::isotropic(5.0);
    TableGrid grid = grid_from(g, [](const double* d, int c) { return 1.0 + 0.01 * d[2] + 0.001 * d[1] + 0.2 * c; });
    double row_mean = 0;
    for (uint32_t p = 0; p < 37; ++p) row_mean += grid.at(0, 8, p, 0, 0);
    row_mean /= 37;
    auto t = build_table(std::move(grid), BuildOptions{});
    for (Interp in : {Interp::Linear, Interp::Nearest}) {
        Rgb ref = t->eval_iso(0.0, 40 * kDeg, 0.0, in);
        EXPECT_NEAR(ref.r, row_mean, 1e-6);
        for (double phi : {0.1, 1.0, 2.0, 3.1}) {
            // Same values blended with different phi weights: equal up to rounding.
            expect_rgb_near(t->eval_iso(0.0, 40 * kDeg, phi, in), ref, 1e-12);
            expect_rgb_near(t->eval_iso(40 * kDeg, 0.0, phi, in), t->eval_iso(40 * kDeg, 0.0, 0.0, in), 1e-12);
        }
    }
    // Through f(): the normal as wi, wo anywhere on a cone; and the frame's azimuth is irrelevant.
    Vec3 n(0, 0, 1);
    Rgb ref = t->f(spherical_direction(40 * kDeg, 0.0), n);
    for (double az : {0.5, 2.0, 4.0, 6.0}) expect_rgb_near(t->f(spherical_direction(40 * kDeg, az), n), ref, 1e-12);
    // Continuous towards the pole: a direction 1e-7 rad from it reads almost the pole value
    // (the phi-dependent 5 deg row gets weight 1e-7 / 5 deg and differs by < 1 from it).
    for (double az : {0.0, 1.5, 3.0})
        expect_rgb_near(t->f(spherical_direction(40 * kDeg, az), spherical_direction(1e-7, az + 1.0)), ref, 2e-6);
}

TEST(BrdfTable, GrazingNinetyDegreesIsTheLastNode) {
    auto t = table_from(TableGeometry::isotropic(5.0), multilinear);
    for (Interp in : {Interp::Linear, Interp::Nearest}) {
        EXPECT_NEAR(t->eval_iso(90 * kDeg, 30 * kDeg, 90 * kDeg, in).r, t->node(18, 6, 18, 0, 0), 1e-6);
        EXPECT_NEAR(t->eval_iso(30 * kDeg, kPi / 2, 90 * kDeg, in).r, t->node(6, 18, 18, 0, 0), 1e-6);
        EXPECT_NEAR(t->eval_iso(kPi / 2, kPi / 2, kPi, in).r, t->node(18, 18, 36, 0, 0), 1e-6);
        // Rounding past 90 deg clamps to the edge instead of reading outside the table.
        EXPECT_NEAR(t->eval_iso(kPi / 2 + 1e-9, 30 * kDeg, 90 * kDeg, in).r, t->node(18, 6, 18, 0, 0), 1e-6);
    }
    // Between 85 and 90: linear in theta.
    double d[3] = {87.5, 30, 90};
    EXPECT_NEAR(t->eval_iso(87.5 * kDeg, 30 * kDeg, 90 * kDeg).r, multilinear(d, 0), 1e-5);
    // f(): on or below the horizon is zero (Brdf contract); just above reads the edge.
    Vec3 wo = spherical_direction(30 * kDeg, 0.0);
    EXPECT_EQ(t->f(wo, Vec3(1, 0, 0)).r, 0.0);
    EXPECT_EQ(t->f(wo, Vec3(0.6, 0, -0.8)).r, 0.0);
    EXPECT_NEAR(t->f(wo, normalize(Vec3(1, 0, 1e-12))).r, t->node(18, 6, 0, 0, 0), 1e-6);
}

TEST(BrdfTable, FoldedLookupsEqualUnfolded) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    auto g = TableGeometry::isotropic(5.0);
    // A reciprocal grid: v(i, r) = v(r, i).
    TableGrid grid(g);
    for (uint32_t i = 0; i < 19; ++i)
        for (uint32_t r = i; r < 19; ++r)
            for (uint32_t p = 0; p < 37; ++p)
                for (int c = 0; c < 3; ++c) grid.at(i, r, p, 0, c) = grid.at(r, i, p, 0, c) = float(u(rng));
    BuildOptions unfolded_opt, folded_opt;
    folded_opt.fold = true;
    auto full = build_table(grid, unfolded_opt);
    auto half = build_table(grid, folded_opt);
    EXPECT_TRUE(half->geometry().folded);
    EXPECT_EQ(half->values().size(), size_t(19 * 20 / 2 * 37 * 3));
    EXPECT_LT(half->bytes_used(), full->bytes_used() * 0.55);
    std::uniform_real_distribution<double> th(0, kPi / 2), ph(-kPi, 2 * kPi);
    for (int k = 0; k < 2000; ++k) {
        double a = th(rng), b = th(rng), p = ph(rng);
        for (Interp in : {Interp::Linear, Interp::Nearest}) {
            expect_rgb_eq(half->eval_iso(a, b, p, in), full->eval_iso(a, b, p, in));
            // Reciprocity: the same corners, summed in another order.
            expect_rgb_near(half->eval_iso(a, b, p, in), half->eval_iso(b, a, p, in), 1e-12);
        }
    }
    for (uint32_t i = 0; i < 19; ++i)
        for (uint32_t r = 0; r < 19; ++r) EXPECT_EQ(half->node(i, r, 5, 0, 2), full->node(i, r, 5, 0, 2));
    EXPECT_EQ(reciprocity(*full).max_abs, 0.0);
    ASSERT_TRUE(reciprocity(*full).applicable);
}

TEST(BrdfTable, FoldingSymmetrisesMeasuredAsymmetry) {
    auto g = TableGeometry::isotropic(10.0, 1);
    // f(i, r) = 1 + 0.01 theta_i: reciprocity error between (i, r) and (r, i) is 0.01 |ti - tr|.
    TableGrid grid = grid_from(g, [](const double* d, int) { return 1.0 + 0.01 * d[0]; });
    ReciprocityStats rs = reciprocity(grid);
    ASSERT_TRUE(rs.applicable);
    EXPECT_NEAR(rs.max_abs, 0.9, 1e-5);  // (0, 90) vs (90, 0)
    EXPECT_NEAR(rs.max_rel, 0.9 / 1.9, 1e-5);
    BuildOptions bo;
    bo.fold = true;
    auto t = build_table(std::move(grid), bo);
    EXPECT_NEAR(t->node(2, 6, 3, 0, 0), 1.0 + 0.01 * (20 + 60) / 2, 1e-6);
    EXPECT_NE(t->info().description.find("symmetrised"), std::string::npos);
}

TEST(BrdfTable, LambertIsRhoOverPiAndAlbedoRho) {
    const Rgb rho(0.2, 0.5, 0.8);
    TestLambert lam(rho);
    for (double step : {1.0, 5.0, 15.0}) {
        BuildOptions bo;
        bo.fold = step == 1.0;
        auto t = build_table(tabulate(lam, TableGeometry::isotropic(step)), bo);
        std::mt19937 rng(5);
        std::uniform_real_distribution<double> u(-1, 1);
        for (int k = 0; k < 200; ++k) {
            Vec3 wo = normalize(Vec3(u(rng), u(rng), std::fabs(u(rng)) + 1e-3));
            Vec3 wi = normalize(Vec3(u(rng), u(rng), std::fabs(u(rng)) + 1e-3));
            expect_rgb_near(t->f(wo, wi), rho * kInvPi, 1e-7);
        }
        ASSERT_EQ(t->albedo_nodes().size(), t->geometry().n[0]);
        for (const Rgb& a : t->albedo_nodes()) expect_rgb_near(a, rho, 1e-3);
        expect_rgb_near(t->directional_albedo(0.0), rho, 1e-6);
        expect_rgb_near(t->directional_albedo(1.3), rho, 1e-6);
    }
    // One channel stores the RGB mean.
    auto grey = build_table(tabulate(lam, TableGeometry::isotropic(5.0, 1)), BuildOptions{});
    EXPECT_NEAR(grey->eval_iso(0.3, 0.7, 1.0).g, 0.5 / kPi, 1e-7);
    EXPECT_NEAR(grey->directional_albedo(0.5).b, 0.5, 1e-6);
}

TEST(BrdfTable, AnisotropicLayout) {
    // f depends on the absolute azimuths (cos 2 phi terms), like brushed metal.
    auto fn = [](const double* d, int c) {
        return (1.0 + 0.3 * std::cos(2 * d[1] * kDeg) * std::sin(d[0] * kDeg)) *
               (1.0 + 0.5 * std::cos(2 * d[3] * kDeg) * std::sin(d[2] * kDeg)) * (0.1 + 0.05 * c);
    };
    auto t = table_from(TableGeometry::anisotropic(10.0, 15.0), fn);
    EXPECT_TRUE(t->anisotropic());
    // Exact at nodes (away from the poles).
    for (uint32_t i = 1; i < 10; i += 2)
        for (uint32_t p = 0; p < 24; p += 5)
            for (uint32_t r = 1; r < 10; r += 3)
                for (uint32_t q = 0; q < 24; q += 7) {
                    double d[4] = {10.0 * i, 15.0 * p, 10.0 * r, 15.0 * q};
                    Rgb v = t->eval_aniso(d[0] * kDeg, d[1] * kDeg, d[2] * kDeg, d[3] * kDeg, Interp::Linear);
                    EXPECT_NEAR(v.g, fn(d, 1), 1e-6);
                    Rgb w = t->eval_aniso(d[0] * kDeg, d[1] * kDeg, d[2] * kDeg, d[3] * kDeg, Interp::Nearest);
                    EXPECT_NEAR(w.g, fn(d, 1), 1e-6);
                }
    // Periodic azimuth: 352.5 deg lies halfway between the 345 node and the 0 (= 360) node.
    double a = t->eval_aniso(40 * kDeg, 352.5 * kDeg, 50 * kDeg, 30 * kDeg, Interp::Linear).r;
    EXPECT_NEAR(a, 0.5 * (t->node(4, 23, 5, 2, 0) + t->node(4, 0, 5, 2, 0)), 1e-6);
    expect_rgb_near(t->eval_aniso(0.7, -0.2, 0.5, 1.0, Interp::Linear),
                    t->eval_aniso(0.7, 2 * kPi - 0.2, 0.5, 1.0, Interp::Linear), 1e-9);
    // f() uses the absolute azimuths: rotating both directions changes the value.
    Vec3 wi = spherical_direction(0.6, 0.0), wo = spherical_direction(0.6, kPi);
    Vec3 wi2 = spherical_direction(0.6, kPi / 2), wo2 = spherical_direction(0.6, 3 * kPi / 2);
    EXPECT_GT(std::fabs(t->f(wo, wi).r - t->f(wo2, wi2).r), 1e-3);
    // Pole: at theta_i = 0, phi_i is undefined.
    expect_rgb_near(t->eval_aniso(0, 0.3, 0.5, 1.0, Interp::Linear), t->eval_aniso(0, 2.0, 0.5, 1.0, Interp::Linear),
                    1e-12);
    // Lambert in the 4-D layout integrates to rho as well.
    TestLambert lam(Rgb(0.3, 0.6, 0.9));
    auto lt = build_table(tabulate(lam, TableGeometry::anisotropic(10.0, 20.0)), BuildOptions{});
    for (const Rgb& v : lt->albedo_nodes()) expect_rgb_near(v, Rgb(0.3, 0.6, 0.9), 1e-3);
}

TEST(BrdfTable, ConcurrentLookupsAgree) {
    auto t = table_from(TableGeometry::isotropic(2.0), multilinear, true);
    std::vector<Vec3> dirs;
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 256; ++k) dirs.push_back(normalize(Vec3(u(rng), u(rng), std::fabs(u(rng)) + 0.01)));
    std::vector<double> serial;
    for (size_t k = 0; k + 1 < dirs.size(); ++k) serial.push_back(t->f(dirs[k], dirs[k + 1]).g);
    std::atomic<int> mismatches{0};
    std::vector<std::thread> threads;
    for (int th = 0; th < 4; ++th)
        threads.emplace_back([&] {
            for (int rep = 0; rep < 50; ++rep)
                for (size_t k = 0; k + 1 < dirs.size(); ++k)
                    if (t->f(dirs[k], dirs[k + 1]).g != serial[k]) ++mismatches;
        });
    for (auto& th : threads) th.join();
    EXPECT_EQ(mismatches.load(), 0);
}

// ---------------------------------------------------------------- no-data policies

TEST(NoData, FillAlongPhiThenTheta) {
    auto g = TableGeometry::isotropic(10.0, 1);
    TableGrid grid = grid_from(g, [](const double* d, int) { return 1.0 + 0.01 * d[2] + 0.1 * d[1]; });
    const float nan = std::numeric_limits<float>::quiet_NaN();
    grid.at(3, 4, 5, 0, 0) = nan;   // interior of a phi row: linear between phi 40 and 60
    grid.at(3, 4, 6, 0, 0) = -1.0f;  // negative = no data too: two missing in a row
    grid.at(2, 5, 0, 0, 0) = nan;   // phi = 0 end: copy of the nearest valid (phi = 10)
    for (uint32_t p = 0; p < 19; ++p) grid.at(5, 7, p, 0, 0) = nan;  // whole row: from theta_r 60/80
    TableGrid rejected = grid;
    EXPECT_EQ(apply_nodata_policy(grid, NoDataPolicy::Fill, "g"), 3u + 19u);
    EXPECT_NEAR(grid.at(3, 4, 5, 0, 0), 1.0 + 0.5 + 4.0, 1e-5);  // linear in phi: exact
    EXPECT_NEAR(grid.at(3, 4, 6, 0, 0), 1.0 + 0.6 + 4.0, 1e-5);
    EXPECT_NEAR(grid.at(2, 5, 0, 0, 0), grid.at(2, 5, 1, 0, 0), 0.0);
    for (uint32_t p = 0; p < 19; ++p) EXPECT_NEAR(grid.at(5, 7, p, 0, 0), 1.0 + 0.1 * p + 7.0, 1e-5);
    try {
        apply_nodata_policy(rejected, NoDataPolicy::Reject, "g");
        FAIL() << "reject did not throw";
    } catch (const TableError& e) {
        std::string m = e.what();
        // First bad value in payload order: cell (2, 5, 0) -> byte offset 4 * ((2*10 + 5)*19 + 0).
        EXPECT_NE(m.find("g: offset " + std::to_string(4 * ((2 * 10 + 5) * 19)) + ": expected a value >= 0"),
                  std::string::npos)
            << m;
        EXPECT_NE(m.find("found nan"), std::string::npos) << m;
    }
}

TEST(NoData, InfIsAnErrorAndAllMissingCannotBeFilled) {
    auto g = TableGeometry::isotropic(30.0, 1);
    TableGrid grid(g, 0.1f);
    grid.at(1, 1, 1, 0, 0) = std::numeric_limits<float>::infinity();
    EXPECT_THROW(apply_nodata_policy(grid, NoDataPolicy::Fill, "g"), TableError);
    TableGrid empty(g, std::numeric_limits<float>::quiet_NaN());
    EXPECT_THROW(apply_nodata_policy(empty, NoDataPolicy::Fill, "g"), TableError);
    // A BrdfTable can never hold no-data values.
    EXPECT_THROW(BrdfTable(g, std::vector<float>(g.values(), -1.0f)), std::invalid_argument);
}

// ---------------------------------------------------------------- file format

TEST(TableFile, RoundTripsEveryLayout) {
    std::vector<std::unique_ptr<BrdfTable>> tables;
    tables.push_back(table_from(TableGeometry::isotropic(5.0), multilinear));
    tables.push_back(table_from(TableGeometry::isotropic(5.0, 1), multilinear, true));
    tables.push_back(table_from(TableGeometry::anisotropic(15.0, 30.0),
                                [](const double* d, int c) { return 0.1 + 0.001 * (d[0] + d[1] + d[2] + d[3]) + c; }));
    for (const auto& t : tables) {
        std::vector<uint8_t> b = encoded(*t);
        EXPECT_EQ(std::memcmp(b.data(), "PVBRDF\0\0", 8), 0);
        EXPECT_EQ(b.size() % 4, 0u);
        auto u = load_table(b.data(), b.size(), "t.brdf");
        EXPECT_EQ(u->values(), t->values());
        EXPECT_EQ(u->geometry().describe(), t->geometry().describe());
        EXPECT_EQ(encoded(*u), b);  // stable: load + save is the identity
    }
    // Description and the no-data count survive.
    TableGrid grid(TableGeometry::isotropic(30.0), 0.25f);
    grid.at(1, 2, 3, 0, 1) = std::numeric_limits<float>::quiet_NaN();
    BuildOptions bo;
    bo.description = "unit test table";
    auto t = build_table(std::move(grid), bo);
    std::vector<uint8_t> b = encoded(*t);
    TableHeader h = parse_table_header(b.data(), b.size(), "t.brdf");
    EXPECT_EQ(h.description, "unit test table");
    EXPECT_EQ(h.nodata_filled, 1u);
    EXPECT_EQ(h.flags, kFlagNoDataFilled);
    EXPECT_EQ(h.payload_offset % 16, 0u);
    EXPECT_EQ(load_table(b.data(), b.size(), "t.brdf")->info().nodata_filled, 1u);
}

TEST(TableFile, FileHelpersRoundTrip) {
    auto t = table_from(TableGeometry::isotropic(10.0), multilinear, true);
    std::string path = ::testing::TempDir() + "table_test_roundtrip.brdf";
    save_table_file(*t, path);
    auto u = load_table_file(path);
    EXPECT_EQ(u->values(), t->values());
    std::remove(path.c_str());
    try {
        load_table_file(path);
        FAIL();
    } catch (const TableError& e) {
        EXPECT_EQ(std::string(e.what()), path + ": no such file");
    }
}

TEST(TableFile, WritesWholeBesideTheTargetAndNamesADirectory) {
    // write_file_bytes: a temporary file of its own in the same folder, renamed over the target;
    // nothing else is left in the folder, and an existing file is replaced whole.
    namespace fs = std::filesystem;
    const fs::path dir = fs::path(::testing::TempDir()) / "table_test_whole";
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string path = (dir / "t.brdf").string();
    write_file_bytes(path, std::vector<uint8_t>(1000, 7));
    write_file_bytes(path, std::vector<uint8_t>(10, 9));
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    EXPECT_EQ(names, std::vector<std::string>{"t.brdf"});
    EXPECT_EQ(read_file_bytes(path), std::vector<uint8_t>(10, 9));
    // A directory given as a file: named as one, with what to give instead (was "9223372036854775807
    // bytes (a directory?)" in the fork).
    try {
        read_file_bytes(dir.string());
        FAIL();
    } catch (const TableError& e) {
        EXPECT_EQ(std::string(e.what()), dir.string() + ": offset 0: expected a regular file, found a directory (give the path "
                                                        "of a file in it, not the folder)");
    }
    EXPECT_THROW(require_regular_file(dir.string(), "x.brdf"), TableError);
    EXPECT_NO_THROW(require_regular_file(path, "x.brdf"));
    // Writing into a missing folder fails naming the target, and leaves nothing behind.
    EXPECT_THROW(write_file_bytes((dir / "no" / "t.brdf").string(), {1, 2}), TableError);
    fs::remove_all(dir);
}

TEST(TableLoader, RejectsBrokenFiles) {
    auto t = table_from(TableGeometry::isotropic(10.0), multilinear);
    const std::vector<uint8_t> good = encoded(*t);
    const uint32_t off = good[12] | good[13] << 8;  // payload offset (< 64 KiB here)

    // Truncations: inside the header, and inside the payload.
    for (size_t len : {size_t(0), size_t(5), size_t(50), size_t(off) + 10, good.size() - 1}) {
        std::vector<uint8_t> b(good.begin(), good.begin() + len);
        std::string m = load_error(b);
        expect_error_format(m, len);
    }
    {  // trailing garbage
        std::vector<uint8_t> b = good;
        b.push_back(0);
        expect_error_format(load_error(b), good.size());
    }
    {  // wrong magic
        std::vector<uint8_t> b = good;
        b[1] = 'X';
        std::string m = load_error(b);
        expect_error_format(m, 0);
        EXPECT_NE(m.find("found \"PXBRDF\\x00\\x00\""), std::string::npos) << m;
    }
    {  // wrong version
        std::vector<uint8_t> b = good;
        b[8] = 2;
        std::string m = load_error(b);
        expect_error_format(m, 8);
        EXPECT_NE(m.find("expected version 1, found 2"), std::string::npos) << m;
    }
    {  // channels, layout (3 is the half/difference layout, 4 is unknown), units, flags, reserved
        for (auto [at, v] : {std::pair<int, int>{20, 2}, {16, 4}, {28, 7}, {24, 0x10}, {108, 1}}) {
            std::vector<uint8_t> b = good;
            b[at] = uint8_t(v);
            expect_error_format(load_error(b), at);
        }
    }
    {  // a step that disagrees with the node count
        std::vector<uint8_t> b = good;
        double step = 11.0;
        std::memcpy(&b[48 + 8], &step, 8);
        std::string m = load_error(b);
        expect_error_format(m, 56);
        EXPECT_NE(m.find("theta_r step 10 deg"), std::string::npos) << m;
    }
    {  // checksum mismatch: one payload bit flipped
        std::vector<uint8_t> b = good;
        b[off + 100] ^= 1;
        std::string m = load_error(b);
        expect_error_format(m, 88);
        EXPECT_NE(m.find("payload FNV-1a-64"), std::string::npos) << m;
    }
    {  // NaN cell (checksum fixed, so the value check is what fails)
        std::vector<uint8_t> b = good;
        float nan = std::numeric_limits<float>::quiet_NaN();
        std::memcpy(&b[off + 4 * 123], &nan, 4);
        fix_checksum(b);
        std::string m = load_error(b);
        expect_error_format(m, off + 4 * 123);
        EXPECT_NE(m.find("found nan"), std::string::npos) << m;
        // cell 123 / 3 = 41 -> theta_i 0, theta_r 20 (41 / 19 = 2), phi 30 (41 % 19 = 3); channel 0
        EXPECT_NE(m.find("theta_i=0 theta_r=20 phi=30 deg, channel 0"), std::string::npos) << m;
    }
    {  // negative cell: rejected by default, filled on request
        std::vector<uint8_t> b = good;
        size_t k = 3 * ((5 * 10 + 5) * 19 + 7);  // theta_i 50, theta_r 50, phi 70
        float neg = -0.5f;
        std::memcpy(&b[off + 4 * k], &neg, 4);
        fix_checksum(b);
        expect_error_format(load_error(b), off + 4 * k);
        LoadOptions fill;
        fill.nodata = NoDataPolicy::Fill;
        auto u = load_table(b.data(), b.size(), "t.brdf", fill);
        EXPECT_EQ(u->info().nodata_filled, 1u);
        // Filled linearly along phi: exact for this table (linear in phi at fixed theta).
        EXPECT_NEAR(u->node(5, 5, 7, 0, 0), t->node(5, 5, 7, 0, 0), 1e-5);
    }
    {  // infinity: never a no-data marker
        std::vector<uint8_t> b = good;
        float inf = std::numeric_limits<float>::infinity();
        std::memcpy(&b[off + 4 * 7], &inf, 4);
        fix_checksum(b);
        LoadOptions fill;
        fill.nodata = NoDataPolicy::Fill;
        expect_error_format(load_error(b, fill), off + 4 * 7);
    }
    // Finite but huge (1e38 rendered inf pixels, issue 29): refused above kMaxTableValue with the
    // offset; the bound itself loads.
    for (float big : {3.4e38f, 1e38f, 1e11f, 1.0000001e10f}) {
        std::vector<uint8_t> b = good;
        std::memcpy(&b[off + 4 * 9], &big, 4);
        fix_checksum(b);
        const std::string err = load_error(b);
        expect_error_format(err, off + 4 * 9);
        EXPECT_NE(err.find("expected a value <= 1e+10 (1/sr) at"), std::string::npos) << err;
    }
    {
        std::vector<uint8_t> b = good;
        const float at_bound = 1e10f;
        std::memcpy(&b[off + 4 * 9], &at_bound, 4);
        fix_checksum(b);
        EXPECT_EQ(load_error(b), "(no error)");
    }
}

TEST(TableLoader, AbsurdDimensionsFailBeforeAllocating) {
    auto t = table_from(TableGeometry::isotropic(30.0), multilinear);
    const std::vector<uint8_t> good = encoded(*t);
    auto set32 = [](std::vector<uint8_t>& b, size_t at, uint32_t v) { std::memcpy(&b[at], &v, 4); };
    struct Case {
        std::vector<uint8_t> bytes;
        uint64_t offset;
    };
    std::vector<Case> cases;
    {  // 2^31 x 2^31 x 2^31
        std::vector<uint8_t> b = good;
        set32(b, 32, 1u << 31);
        set32(b, 36, 1u << 31);
        set32(b, 40, 1u << 31);
        cases.push_back({b, 32});
    }
    {  // in range per axis, but 18 TB in total (anisotropic 9001 x 36000 x 9001 x 36000)
        std::vector<uint8_t> b = good;
        set32(b, 16, 2);
        set32(b, 32, 9001);
        set32(b, 36, 36000);
        set32(b, 40, 9001);
        set32(b, 44, 36000);
        double steps[4] = {0.01, 0.01, 0.01, 0.01};
        std::memcpy(&b[48], steps, 32);
        cases.push_back({b, 32});
    }
    {  // a payload size field that does not match the dimensions
        std::vector<uint8_t> b = good;
        uint64_t huge = uint64_t(1) << 60;
        std::memcpy(&b[80], &huge, 8);
        cases.push_back({b, 80});
    }
    for (const Case& c : cases) {
        g_max_alloc = 0;
        g_track = true;
        std::string m = load_error(c.bytes);
        g_track = false;
        expect_error_format(m, c.offset);
        EXPECT_LT(g_max_alloc.load(), size_t(1) << 16) << m;
    }
}

TEST(TableLoader, ErrorMessageNamesTheData) {
    std::vector<uint8_t> junk(200, 'x');
    try {
        load_table(junk.data(), junk.size(), "scenes/gold.brdf");
        FAIL();
    } catch (const TableError& e) {
        EXPECT_EQ(std::string(e.what()),
                  "scenes/gold.brdf: offset 0: expected magic \"PVBRDF\\x00\\x00\", found \"xxxxxxxx\"");
    }
}

TEST(TableFile, FoldedTableWithManyFilledCellsRoundTrips) {
    // The filled count is taken on the measured (unfolded) grid, so it may exceed the
    // folded table's cell count; the loader must accept what the writer wrote.
    Lambert l{Rgb(0.5)};
    TableGrid grid = tabulate(l, TableGeometry::isotropic(15.0));
    MeasurementSim sim;
    sim.noise = 0.0;
    sim.missing = 0.7;
    sim.seed = 3;
    uint64_t missing = simulate_measurement(grid, sim);
    BuildOptions opt;
    opt.fold = true;
    std::unique_ptr<BrdfTable> t = build_table(grid, opt);
    ASSERT_GT(missing, t->geometry().cells());
    std::vector<uint8_t> bytes = encode_table(*t);
    std::unique_ptr<BrdfTable> back = load_table(bytes.data(), bytes.size(), "folded-filled");
    EXPECT_EQ(back->info().nodata_filled, t->info().nodata_filled);
    EXPECT_NEAR(back->directional_albedo(0.5).g, 0.5, 0.01);
}
