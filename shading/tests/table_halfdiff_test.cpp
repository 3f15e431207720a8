// The half/difference table layout (layout 3, table.h): node rule, lookups (exact at nodes,
// continuous at theta_h = 0, theta_d = 0 and across the phi_d wrap, reciprocal, the same from
// world vectors as from the local frame, MERL's bins under nearest lookups), the albedo over
// the half vector, MERL imported without resampling, the no-data rule for cells below the
// horizon, and the loader's byte-offset errors for every header field of the layout.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <regex>

#include "shading/core/bytes.h"
#include "shading/finish/finish.h"
#include "shading/tables/merl.h"
#include "shading/brdf/model_spec.h"
#include "shading/brdf/models.h"
#include "shading/tables/table.h"
#include "table_files.h"

using namespace shading;

namespace {

constexpr double kDeg = kPi / 180.0;
const char* kNarrowConductor = "microfacet d=beckmann m=0.05 f=conductor n=0.143,0.374,1.442 k=3.983,2.385,1.603";

// A table whose every node holds a distinct, irregular value (per channel): lookups that
// mix up nodes, axes or the phi_d sign cannot agree with what they should read by chance.
std::unique_ptr<BrdfTable> scrambled(const TableGeometry& g, uint64_t seed = 7) {
    TableGrid grid(g);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(0.1, 2.0);
    for (float& v : grid.values) v = float(u(rng));
    BuildOptions bo;
    bo.nodata = NoDataPolicy::Reject;
    return build_table(std::move(grid), bo);
}

Vec3 random_up(std::mt19937_64& rng) {  // uniform on the upper hemisphere, not too grazing
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (;;) {
        const double z = u(rng), phi = 2 * kPi * u(rng), s = std::sqrt(1 - z * z);
        if (z > 0.02) return {s * std::cos(phi), s * std::sin(phi), z};
    }
}

double rel_diff(const Rgb& a, const Rgb& b) {
    double m = 0;
    for (int c = 0; c < 3; ++c) m = std::max(m, std::fabs(a[c] - b[c]) / std::max(1e-300, std::fabs(b[c])));
    return m;
}

std::string error_of(const std::vector<uint8_t>& b, const LoadOptions& opt = {}) {
    return table_files::load_error(b, "hd.brdf", opt);
}
void expect_error_at(const std::string& msg, uint64_t offset) { table_files::expect_error_at(msg, "hd.brdf", offset); }
using table_files::fix_checksum;

}  // namespace

// ---------------------------------------------------------------- geometry

TEST(HalfDiffGeometry, NodeRuleIsMerlBinCentres) {
    const TableGeometry g = TableGeometry::halfdiff(90, 90, 180);
    EXPECT_EQ(g.axes(), 3);
    EXPECT_EQ(g.cells(), 90u * 90u * 180u);
    EXPECT_EQ(g.values() * 4, 17496000u);  // MERL's grid in RGB float32: 17.5 MB
    // theta_h: ((i + 1/2) / 90)^2 * 90 deg, i.e. the centre of MERL's bin in sqrt(theta_h).
    EXPECT_DOUBLE_EQ(g.axis_deg(0, 0), 90.0 * std::pow(0.5 / 90, 2));
    EXPECT_DOUBLE_EQ(g.axis_deg(0, 89), 90.0 * std::pow(89.5 / 90, 2));
    EXPECT_DOUBLE_EQ(g.axis_deg(1, 0), 0.5);
    EXPECT_DOUBLE_EQ(g.axis_deg(1, 89), 89.5);
    EXPECT_DOUBLE_EQ(g.axis_deg(2, 0), 0.5);
    EXPECT_DOUBLE_EQ(g.axis_deg(2, 179), 179.5);
    EXPECT_DOUBLE_EQ(g.step_deg(0), 1.0);  // in sqrt(90 deg x theta_h)
    EXPECT_DOUBLE_EQ(g.step_deg(2), 1.0);
    EXPECT_TRUE(g.is_periodic(2));
    EXPECT_FALSE(g.is_periodic(0));
    EXPECT_STREQ(g.axis_name(0), "theta_h");
    EXPECT_STREQ(g.axis_name(2), "phi_d");
    EXPECT_NE(g.describe().find("half/difference 90x90x180"), std::string::npos) << g.describe();
    // Every node's pair has the node's own half/difference angles (merl.h's transform).
    uint32_t idx[4] = {0, 0, 0, 0};
    for (idx[0] = 0; idx[0] < 90; idx[0] += 7)
        for (idx[1] = 0; idx[1] < 90; idx[1] += 11)
            for (idx[2] = 0; idx[2] < 180; idx[2] += 13) {
                Vec3 wi, wo;
                g.halfdiff_node_pair(idx, wi, wo);
                HalfDiff hd = to_half_diff(wi, wo);
                EXPECT_NEAR(hd.theta_h / kDeg, g.axis_deg(0, idx[0]), 1e-9);
                EXPECT_NEAR(hd.theta_d / kDeg, g.axis_deg(1, idx[1]), 1e-9);
                EXPECT_NEAR(std::remainder(hd.phi_d / kDeg - g.axis_deg(2, idx[2]), 180.0), 0.0, 1e-9);
            }
}

TEST(HalfDiffGeometry, RangesAndFolding) {
    EXPECT_THROW(TableGeometry::halfdiff(1, 90, 180), std::invalid_argument);
    EXPECT_THROW(TableGeometry::halfdiff(90, 9001, 180), std::invalid_argument);
    EXPECT_THROW(TableGeometry::halfdiff(90, 90, 18001), std::invalid_argument);
    EXPECT_NO_THROW(TableGeometry::halfdiff(9000, 2, 18000));
    TableGeometry g = TableGeometry::halfdiff(8, 8, 8);
    g.folded = true;
    EXPECT_THROW(g.validate(), std::invalid_argument);
    TableGrid grid(TableGeometry::halfdiff(8, 8, 8), 0.1f);
    BuildOptions bo;
    bo.fold = true;
    EXPECT_THROW(build_table(std::move(grid), bo), std::invalid_argument);
}

// ---------------------------------------------------------------- lookups

TEST(HalfDiffLookup, ExactAtEveryNodeAboveTheHorizon) {
    const TableGeometry g = TableGeometry::halfdiff(24, 20, 36);
    auto t = scrambled(g);
    uint32_t idx[4] = {0, 0, 0, 0};
    uint64_t checked = 0;
    for (idx[0] = 0; idx[0] < g.n[0]; ++idx[0])
        for (idx[1] = 0; idx[1] < g.n[1]; ++idx[1])
            for (idx[2] = 0; idx[2] < g.n[2]; ++idx[2]) {
                Vec3 wi, wo;
                if (!g.halfdiff_node_pair(idx, wi, wo)) continue;
                const Rgb want(t->node(idx[0], idx[1], idx[2], 0, 0), t->node(idx[0], idx[1], idx[2], 0, 1),
                               t->node(idx[0], idx[1], idx[2], 0, 2));
                // float32 storage: agreement to the rounding of the node position (~1e-12)
                ASSERT_LT(rel_diff(t->f(wo, wi, Interp::Linear), want), 1e-9)
                    << idx[0] << " " << idx[1] << " " << idx[2];
                ASSERT_LT(rel_diff(t->f(wo, wi, Interp::Nearest), want), 1e-15);
                ++checked;
            }
    EXPECT_GT(checked, g.cells() / 2);
}

TEST(HalfDiffLookup, ReciprocalAndTheSameFromWorldVectors) {
    auto t = scrambled(TableGeometry::halfdiff(32, 24, 40));
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int k = 0; k < 2000; ++k) {
        const Vec3 wi = random_up(rng), wo = random_up(rng);
        const Rgb a = t->f(wo, wi), b = t->f(wi, wo);
        ASSERT_LT(rel_diff(a, b), 1e-12) << k;
        // The same pair in a rotated world frame (from_normal: a proper rotation).
        const Vec3 n = normalize(Vec3(u(rng), u(rng), u(rng)));
        const Frame fr = Frame::from_normal(n);
        const Rgb w = t->eval_halfdiff_dirs(n, fr.to_world(wi), fr.to_world(wo), Interp::Linear);
        ASSERT_LT(rel_diff(w, a), 1e-9) << k;
    }
}

TEST(HalfDiffLookup, ContinuousAtThetaHZeroThetaDZeroAndThePhiDWrap) {
    // Scrambled rows: nothing is constant in phi_d, so only the virtual poles can make the
    // lookup independent of the direction the pole is approached from. Next to a pole the
    // value moves like sqrt(theta_h) (the axis is uniform in sqrt(theta_h)), so the test is
    // that the largest difference over approach directions shrinks with the distance (by
    // about sqrt(1000) per factor 1000) and is below 1e-4 at theta ~ 1e-12.
    auto t = scrambled(TableGeometry::halfdiff(16, 12, 24));
    const Interp L = Interp::Linear;
    for (double td : {0.2, 0.7, 1.2}) {
        const Rgb at_pole = t->eval_halfdiff(0.0, td, 0.0, L);
        for (double pd : {0.9, 2.0, 3.1}) EXPECT_LT(rel_diff(t->eval_halfdiff(0.0, td, pd, L), at_pole), 1e-15);
        const Vec3 wi = spherical_direction(td, 0.3), mirror(-wi.x, -wi.y, wi.z);
        double prev = 1.0;
        for (double eps : {1e-6, 1e-9, 1e-12}) {
            double worst = 0;
            for (double a = 0; a < 2 * kPi; a += 0.25) {  // approaching the mirror direction
                const Vec3 wo = normalize(mirror + Vec3(std::cos(a), std::sin(a), 0) * eps);
                worst = std::max(worst, rel_diff(t->f(wo, wi), at_pole));
            }
            for (double pd = 0; pd < kPi; pd += 0.25)  // and in angles
                worst = std::max(worst, rel_diff(t->eval_halfdiff(eps, td, pd, L), at_pole));
            EXPECT_LT(worst, prev / 10) << "theta_d " << td << ", eps " << eps;
            prev = worst;
        }
        EXPECT_LT(prev, 1e-4) << td;
    }
    for (double th : {0.1, 0.6, 1.3}) {
        const Rgb at_pole = t->eval_halfdiff(th, 0.0, 0.0, L);
        double prev = 1.0;
        for (double eps : {1e-6, 1e-9, 1e-12}) {
            double worst = 0;
            for (double pd = 0; pd < kPi; pd += 0.25)
                worst = std::max(worst, rel_diff(t->eval_halfdiff(th, eps, pd, L), at_pole));
            EXPECT_LT(worst, prev / 100) << "theta_h " << th << ", eps " << eps;  // linear in theta_d
            prev = worst;
        }
        for (double td : {0.3, 1.0}) {  // phi_d = 0 and phi_d -> pi are the same pairs
            EXPECT_LT(rel_diff(t->eval_halfdiff(th, td, kPi - 1e-12, L), t->eval_halfdiff(th, td, 0.0, L)), 1e-9);
            EXPECT_LT(rel_diff(t->eval_halfdiff(th, td, -1e-12, L), t->eval_halfdiff(th, td, 1e-12, L)), 1e-9);
        }
    }
    // Beyond the last theta nodes the last values hold (no extrapolation, no NaN).
    const Rgb edge = t->eval_halfdiff(kPi / 2, kPi / 2, 1.0, L);
    for (int c = 0; c < 3; ++c) EXPECT_TRUE(std::isfinite(edge[c]) && edge[c] > 0);
    EXPECT_LT(rel_diff(t->eval_halfdiff(kPi / 2 - 1e-4, kPi / 2 - 1e-4, 1.0, L), edge), 1e-12);
}

TEST(HalfDiffLookup, WorseOffAnywhereIsNeverNaN) {
    auto t = scrambled(TableGeometry::halfdiff(8, 8, 8));
    const double bad[] = {std::numeric_limits<double>::quiet_NaN(), -1.0, 10.0, 1e300, -1e300};
    for (double a : bad)
        for (double b : bad)
            for (double c : bad)
                for (Interp in : {Interp::Linear, Interp::Nearest}) {
                    Rgb v = t->eval_halfdiff(a, b, c, in);
                    for (int k = 0; k < 3; ++k) ASSERT_TRUE(std::isfinite(v[k]) && v[k] > 0);
                }
    // wi = -wo on the horizon: h = 0.
    Rgb v = t->f(Vec3(-1, 0, 1e-300), Vec3(1, 0, 1e-300));
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(std::isfinite(v[k]) && v[k] >= 0);
    EXPECT_THROW(scrambled(TableGeometry::isotropic(30.0))->eval_halfdiff(0.1, 0.1, 0.1, Interp::Linear),
                 std::logic_error);
}

TEST(HalfDiffLookup, TabulatedNarrowLobeFollowsTheModel) {
    // Beckmann m = 0.05 conductor at the default nodes: lookups at random pairs inside the
    // lobe (f > 5 % of its peak at that theta_i) against the model itself. Tolerance stated
    // before measuring: 1 % max, 0.2 % rms; the 1 deg isotropic table is shown beside it.
    BrdfPtr model = make_brdf(kNarrowConductor);
    BuildOptions bo;
    auto hd = build_table(tabulate(*model, TableGeometry::halfdiff()), bo);
    bo.fold = true;
    auto iso = build_table(tabulate(*model, TableGeometry::isotropic(1.0)), bo);
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    double max_hd = 0, max_iso = 0, s2_hd = 0, s2_iso = 0;
    int count = 0;
    while (count < 4000) {
        const double ti = u(rng) * 80 * kDeg;
        const Vec3 wi = spherical_direction(ti, 0.0), mirror(-wi.x, -wi.y, wi.z);
        const Vec3 wo = normalize(mirror + Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5) * 0.3);
        if (!(wo.z > std::cos(80 * kDeg))) continue;
        const Rgb m = model->f(wo, wi);
        if (m.r < 0.05 * model->f(mirror, wi).r) continue;
        const double e_hd = rel_diff(hd->f(wo, wi), m), e_iso = rel_diff(iso->f(wo, wi), m);
        max_hd = std::max(max_hd, e_hd);
        max_iso = std::max(max_iso, e_iso);
        s2_hd += e_hd * e_hd;
        s2_iso += e_iso * e_iso;
        ++count;
    }
    std::printf("[ measured ] beckmann m=0.05 conductor, lobe lookups: halfdiff 256x128x32 max %.3g rms %.3g; "
                "isotropic 1 deg max %.3g rms %.3g\n",
                max_hd, std::sqrt(s2_hd / count), max_iso, std::sqrt(s2_iso / count));
    EXPECT_LT(max_hd, 0.01);
    EXPECT_LT(std::sqrt(s2_hd / count), 0.002);
    EXPECT_GT(std::sqrt(s2_iso / count), 5 * std::sqrt(s2_hd / count));  // why the layout exists
}

// ---------------------------------------------------------------- albedo

TEST(HalfDiffAlbedo, LambertAndAMicrofacetLobe) {
    TableGrid grid(TableGeometry::halfdiff(16, 8, 8), float(0.5 * kInvPi));
    auto lam = build_table(std::move(grid), BuildOptions{});
    ASSERT_EQ(lam->albedo_nodes().size(), 46u);
    EXPECT_DOUBLE_EQ(lam->albedo_node_deg(45), 90.0);
    for (size_t k = 0; k < lam->albedo_nodes().size(); ++k)
        EXPECT_NEAR(lam->albedo_nodes()[k].g, 0.5, 2e-4) << lam->albedo_node_deg(k);  // midpoint rule
    // A lobe against the finish's own quadrature of the model (an independent integration:
    // importance sampling in w_o). Tolerance 0.5 % below 75 deg.
    for (const char* spec : {kNarrowConductor, "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.7"}) {
        BrdfPtr model = make_brdf(spec);
        auto t = build_table(tabulate(*model, TableGeometry::halfdiff()), BuildOptions{});
        auto fm = make_finish_model(model);
        for (double th : {0.0, 30.0, 60.0, 74.0}) {
            const Rgb a = t->directional_albedo(th * kDeg), want = finish_model_albedo(*fm, std::cos(th * kDeg));
            EXPECT_LT(rel_diff(a, want), 5e-3) << spec << " theta " << th;
        }
    }
}

// ---------------------------------------------------------------- building and no data

TEST(HalfDiffBuild, OutsideCellsAreFilledNotCounted) {
    const TableGeometry g = TableGeometry::halfdiff(12, 12, 16);
    TableGrid grid = tabulate(Lambert(Rgb(0.4, 0.5, 0.6)), g);
    uint64_t outside = 0;
    for (float v : grid.values) outside += std::isnan(v);
    ASSERT_GT(outside, 0u);  // tabulate leaves the cells below the horizon to the fill
    BuildOptions bo;
    bo.nodata = NoDataPolicy::Reject;  // outside cells are geometry, not missing data
    auto t = build_table(grid, bo);
    EXPECT_EQ(t->info().nodata_filled, 0u);
    // Filled from constant neighbours: the constant again, in every cell (outside ones too).
    for (size_t k = 0; k < t->values().size(); ++k)
        ASSERT_NEAR(t->values()[k], (0.4 + 0.1 * double(k % 3)) * kInvPi, 1e-7) << k;
    // A missing cell inside the domain is no data: rejected, or filled and counted.
    uint32_t idx[4] = {2, 3, 5, 0};
    Vec3 wi, wo;
    ASSERT_TRUE(g.halfdiff_node_pair(idx, wi, wo));
    grid.at(2, 3, 5, 0, 1) = -1.0f;
    try {
        build_table(grid, bo);
        FAIL();
    } catch (const TableError& e) {
        EXPECT_NE(std::string(e.what()).find("theta_h="), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("phi_d="), std::string::npos) << e.what();
    }
    bo.nodata = NoDataPolicy::Fill;
    EXPECT_EQ(build_table(grid, bo)->info().nodata_filled, 1u);
}

TEST(HalfDiffBuild, ResamplesToAndFromTheIsotropicLayout) {
    BrdfPtr model = make_brdf("microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.7");
    auto iso = build_table(tabulate(*model, TableGeometry::isotropic(2.0)), BuildOptions{});
    auto hd = build_table(resample(*iso, TableGeometry::halfdiff(64, 45, 45)), BuildOptions{});
    auto back = build_table(resample(*hd, TableGeometry::isotropic(2.0)), BuildOptions{});
    double worst = 0;
    uint32_t wi_ = 0, wr = 0, wp = 0;
    for (uint32_t i = 0; i < 31; ++i)  // theta_i, theta_r <= 60 deg
        for (uint32_t r = 0; r < 31; ++r)
            for (uint32_t p = 0; p < 91; ++p)
                for (int c = 0; c < 3; ++c) {
                    double e = std::fabs(double(back->node(i, r, p, 0, c)) / iso->node(i, r, p, 0, c) - 1);
                    if (e > worst) { worst = e; wi_ = i; wr = r; wp = p; }
                }
    std::printf("[ measured ] m=0.3 table, 2 deg -> halfdiff 64x45x45 -> 2 deg: max rel change %.3g at %u %u %u\n", worst, wi_, wr, wp);
    EXPECT_LT(worst, 0.02);
}

// ---------------------------------------------------------------- MERL

namespace {
// MERL raw samples: a model at the bin centres / scale, -1 below the horizon (like MERL).
std::vector<double> merl_raw(const Brdf& model, const MerlDims& d) {
    const TableGeometry g = TableGeometry::halfdiff(d.theta_h, d.theta_d, d.phi_d);
    const uint64_t n = d.per_channel();
    std::vector<double> raw(3 * n);
    uint32_t idx[4];
    for (uint64_t k = 0; k < n; ++k) {
        g.unravel(k, idx);
        Vec3 wi, wo;
        const bool up = g.halfdiff_node_pair(idx, wi, wo);
        const Rgb f = model.f(wo, wi);
        for (int c = 0; c < 3; ++c) raw[c * n + k] = up ? f[c] / MerlBrdf::kScale[c] : -1.0;
    }
    return raw;
}
}  // namespace

TEST(HalfDiffMerl, BinsAreStoredAsTheyAreAndNearestIsTheReferenceLookup) {
    const MerlDims d;  // 90 x 90 x 180
    BrdfPtr model = make_brdf("microfacet d=beckmann m=0.1 f=dielectric eta=1.5 kd=0.3 rho_s=0.7");
    std::vector<double> raw = merl_raw(*model, d);
    // An irregular perturbation, so that equal neighbours cannot hide a shifted index.
    for (size_t k = 0; k < raw.size(); ++k)
        if (raw[k] >= 0) raw[k] *= 1.0 + 0.01 * std::sin(double(k) * 0.7);
    MerlBrdf merl(d, raw, "synthetic.binary");
    MerlConvertOptions opt;
    opt.nodata = NoDataPolicy::Reject;  // only below-horizon bins lack data
    auto t = merl_to_halfdiff(merl, opt);
    EXPECT_EQ(t->geometry().describe(), TableGeometry::halfdiff(90, 90, 180).describe());
    EXPECT_EQ(t->info().nodata_filled, 0u);
    const uint64_t n = d.per_channel();
    uint64_t below = 0;
    for (uint64_t k = 0; k < n; ++k)
        for (int c = 0; c < 3; ++c) {
            if (raw[c * n + k] < 0) {
                below += c == 0;
                continue;
            }
            ASSERT_EQ(t->values()[k * 3 + c], float(raw[c * n + k] * MerlBrdf::kScale[c])) << k << " " << c;
        }
    std::printf("[ measured ] MERL 90x90x180: %llu of %llu bins below the horizon, filled; the rest stored exactly\n",
                (unsigned long long)below, (unsigned long long)n);
    EXPECT_GT(below, 0u);
    std::mt19937_64 rng(5);
    for (int k = 0; k < 20000; ++k) {
        const Vec3 wi = random_up(rng), wo = random_up(rng);
        const Rgb want = merl.f(wo, wi), got = t->f(wo, wi, Interp::Nearest);
        for (int c = 0; c < 3; ++c) ASSERT_EQ(got[c], double(float(want[c]))) << k;
    }
    // 1 channel: the mean of the scaled channels.
    opt.channels = 1;
    auto grey = merl_to_halfdiff(merl, opt);
    EXPECT_FLOAT_EQ(grey->node(40, 30, 20, 0, 0), float((t->node(40, 30, 20, 0, 0) + t->node(40, 30, 20, 0, 1) +
                                                         t->node(40, 30, 20, 0, 2)) / 3.0));
    opt.fold = true;
    EXPECT_THROW(merl_to_halfdiff(merl, opt), std::invalid_argument);
}

TEST(HalfDiffMerl, MissingBinsAboveTheHorizonFollowThePolicy) {
    const MerlDims d{16, 16, 32};
    std::vector<double> raw = merl_raw(Lambert(Rgb(0.3, 0.4, 0.5)), d);
    const TableGeometry g = TableGeometry::halfdiff(16, 16, 32);
    const uint32_t idx[4] = {3, 4, 5, 0};
    Vec3 wi, wo;
    ASSERT_TRUE(g.halfdiff_node_pair(idx, wi, wo));
    const uint64_t k = (3 * 16 + 4) * 32 + 5, n = d.per_channel();
    raw[2 * n + k] = -1.0;  // blue missing in an above-horizon bin
    MerlBrdf merl(d, raw, "hole.binary");
    MerlConvertOptions opt;
    opt.nodata = NoDataPolicy::Reject;
    try {
        merl_to_halfdiff(merl, opt);
        FAIL();
    } catch (const TableError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("hole.binary: offset " + std::to_string(12 + 8 * (2 * n + k)) + ":"), std::string::npos) << m;
        EXPECT_NE(m.find("channel B"), std::string::npos) << m;
        EXPECT_NE(m.find("found -1"), std::string::npos) << m;
    }
    opt.nodata = NoDataPolicy::Fill;
    auto t = merl_to_halfdiff(merl, opt);
    EXPECT_EQ(t->info().nodata_filled, 1u);
    EXPECT_NEAR(t->node(3, 4, 5, 0, 2), 0.5 * kInvPi, 1e-7);  // filled from equal neighbours
    EXPECT_THROW(merl_to_halfdiff(MerlBrdf(MerlDims{1, 4, 4}, std::vector<double>(48, 1.0), "x"), opt),
                 std::invalid_argument);
}

// ---------------------------------------------------------------- the file

TEST(HalfDiffFile, RoundTripsAndTheFinishReadsItFromWorldVectors) {
    auto t = scrambled(TableGeometry::halfdiff(10, 9, 14, 3));
    std::vector<uint8_t> b = encode_table(*t);
    TableHeader h = parse_table_header(b.data(), b.size(), "hd.brdf");
    EXPECT_EQ(h.geom.layout, TableLayout::HalfDiff);
    auto u = load_table(b.data(), b.size(), "hd.brdf");
    EXPECT_EQ(u->values(), t->values());
    EXPECT_EQ(encode_table(*u), b);
    auto grey = scrambled(TableGeometry::halfdiff(10, 9, 14, 1));
    std::vector<uint8_t> bg = encode_table(*grey);
    EXPECT_EQ(load_table(bg.data(), bg.size(), "hd.brdf")->values(), grey->values());

    // The finish path: halfdiff_table set, pi f cos_i from world vectors.
    std::shared_ptr<const BrdfTable> shared(std::move(u));
    auto fm = make_finish_model(shared, Interp::Linear);
    ASSERT_EQ(fm->halfdiff_table, shared.get());
    EXPECT_EQ(fm->iso_table, nullptr);
    const Vec3 n = normalize(Vec3(0.2, 0.9, -0.3)), l = normalize(Vec3(0.5, 0.8, 0.1)), v = normalize(Vec3(-0.3, 0.7, -0.6));
    const Frame fr = Frame::from_normal(n);
    const Rgb want = shared->f(fr.to_local(v), fr.to_local(l)) * (kPi * dot(n, l));
    EXPECT_LT(rel_diff(finish_light_weight(*fm, n, v, l, Rgb(1.0)), want), 1e-9);
    EXPECT_EQ(finish_light_weight(*fm, n, v, -l, Rgb(1.0)).r, 0.0);
}

TEST(HalfDiffFile, EveryMalformedHeaderFieldNamesItsOffset) {
    auto t = scrambled(TableGeometry::halfdiff(10, 9, 14));
    const std::vector<uint8_t> good = encode_table(*t);
    ASSERT_EQ(error_of(good), "(no error)");
    auto with_u32 = [&](size_t at, uint32_t v) { return table_files::with_value(good, at, v); };
    auto with_f64 = [&](size_t at, double v) { return table_files::with_value(good, at, v); };
    auto with_u64 = [&](size_t at, uint64_t v) { return table_files::with_value(good, at, v); };
    struct Case {
        std::vector<uint8_t> bytes;
        uint64_t offset;
        const char* says;
    };
    const Case cases[] = {  // one row per damaged header field: rows alike by design
        {with_u32(8, 2), 8, "version 1"},
        {with_u32(12, 128), 12, "payload offset"},
        {with_u32(16, 4), 16, "3 (half/difference)"},
        {with_u32(20, 2), 20, "1 or 3 channels"},
        {with_u32(24, 1), 24, "half/difference table (reciprocal by construction)"},
        {with_u32(24, 8), 24, "flags within"},
        {with_u32(28, 0), 28, "units 1"},
        {with_u32(32, 1), 32, "theta_h node count in [2, 9000]"},
        {with_u32(32, 9001), 32, "theta_h node count in [2, 9000]"},
        {with_u32(36, 0), 36, "theta_d node count in [2, 9000]"},
        {with_u32(40, 18001), 40, "phi_d node count in [2, 18000]"},
        {with_u32(44, 2), 44, "half/difference tables have three axes"},
        {with_f64(48, 1.0), 48, "theta_h step 9 deg"},
        {with_f64(56, std::numeric_limits<double>::quiet_NaN()), 56, "theta_d step 10 deg"},
        {with_f64(64, 180.0 / 15), 64, "phi_d step"},
        {with_f64(72, 1.0), 72, "unused step 0 deg"},
        {with_u64(80, 4), 80, "payload size"},
        {with_u64(88, 0), 88, "payload FNV-1a-64"},
        {with_u64(96, 10 * 9 * 14 + 1), 96, "at most 1260 filled no-data cells"},
        {with_u32(104, 5000), 104, "description of at most 4096 bytes"},
        {with_u32(108, 1), 108, "reserved field 0"},
    };
    for (const Case& c : cases) {
        const std::string m = error_of(c.bytes);
        expect_error_at(m, c.offset);
        EXPECT_NE(m.find(c.says), std::string::npos) << m;
    }
    // Sizes: truncated, trailing bytes.
    std::vector<uint8_t> b(good.begin(), good.end() - 4);
    expect_error_at(error_of(b), good.size() - 4);
    b = good;
    b.push_back(0);
    expect_error_at(error_of(b), good.size());
    // A value: NaN names the node in the layout's own angles; fill accepts it.
    b = good;
    const uint32_t off = good[12] | good[13] << 8;
    const size_t k = 3 * ((2 * 9 + 3) * 14 + 4) + 1;  // theta_h node 2, theta_d 3, phi_d 4, G
    const float nan = std::numeric_limits<float>::quiet_NaN();
    std::memcpy(&b[off + 4 * k], &nan, 4);
    fix_checksum(b);
    const std::string m = error_of(b);
    expect_error_at(m, off + 4 * k);
    EXPECT_NE(m.find("theta_h=5.625 theta_d=35 phi_d=57.8571429 deg, channel 1"), std::string::npos) << m;
    LoadOptions fill;
    fill.nodata = NoDataPolicy::Fill;
    EXPECT_EQ(error_of(b, fill), "(no error)");
}
