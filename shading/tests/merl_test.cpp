// MERL .binary import: the bin functions, the half/difference transform, the file layout
// and scales, the round trip "analytic model -> generated .binary -> parse -> merl_to_table"
// against the model, the no-data policies and the loader's errors on broken files.
//
// The generated files are written by this test's own little-endian encoder with the
// literal MERL scales (1/1500, 1.15/1500, 1.66/1500) and the documented sample order, so a
// loader that disagrees with the format (scale, channel order, axis order, sqrt mapping)
// fails here; MicrofacetToleranceCatchesWrongFiles shows the tolerances are tight enough.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <regex>
#include <string>
#include <vector>

#include "shading/tables/merl.h"
#include "shading/brdf/model_spec.h"
#include "shading/brdf/models.h"
#include "shading/tables/table.h"
#include "table_files.h"

using namespace shading;

namespace {

constexpr double kDeg = kPi / 180.0;
// The scales of the format, written out here rather than taken from the library.
const double kFileScale[3] = {1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0};

// ---------------------------------------------------------------- generated files

void put_le32(std::vector<uint8_t>& out, int32_t v) {
    uint32_t u;
    std::memcpy(&u, &v, 4);
    for (int k = 0; k < 4; ++k) out.push_back(uint8_t(u >> (8 * k)));
}
void put_le64(std::vector<uint8_t>& out, double v) {
    uint64_t u;
    std::memcpy(&u, &v, 8);
    for (int k = 0; k < 8; ++k) out.push_back(uint8_t(u >> (8 * k)));
}
double get_le64(const std::vector<uint8_t>& b, uint64_t at) {
    uint64_t u = 0;
    for (int k = 7; k >= 0; --k) u = u << 8 | b.at(at + k);
    double d;
    std::memcpy(&d, &u, 8);
    return d;
}

// A .binary image: three int32 dims, then the raw channel-major doubles.
std::vector<uint8_t> encode_binary(int32_t nh, int32_t nd, int32_t np, const std::vector<double>& raw) {
    std::vector<uint8_t> out;
    out.reserve(12 + 8 * raw.size());
    put_le32(out, nh);
    put_le32(out, nd);
    put_le32(out, np);
    for (double v : raw) put_le64(out, v);
    return out;
}
std::vector<uint8_t> encode_binary(const MerlDims& d, const std::vector<double>& raw) {
    return encode_binary(int32_t(d.theta_h), int32_t(d.theta_d), int32_t(d.phi_d), raw);
}

uint64_t sample_index(const MerlDims& d, uint32_t ih, uint32_t id, uint32_t ip) {
    return (uint64_t(ih) * d.theta_d + id) * d.phi_d + ip;
}

// Deliberately wrong files, to show the round-trip tolerances would catch such mistakes.
enum class Mutation {
    None,
    GreenScaleOfRed,  // G written with the R scale (as if one scale were used for all)
    SwapThetaAxes,    // theta_d bins stored where theta_h bins belong and vice versa
    LinearThetaH,     // theta_h bins without the sqrt mapping
    SwapRedBlue,      // the R and B blocks in each other's place (each with its own scale)
};

// Raw samples of `model` at the centres of the bins (in the coordinates the lookup bins
// in: sqrt(theta_h), theta_d, phi_d), divided by the file scales, phi_h = 0.
std::vector<double> raw_from_model(const Brdf& model, const MerlDims& d, Mutation mut = Mutation::None) {
    const uint64_t n = d.per_channel();
    std::vector<double> raw(3 * n);
    for (uint32_t ih = 0; ih < d.theta_h; ++ih)
        for (uint32_t id = 0; id < d.theta_d; ++id)
            for (uint32_t ip = 0; ip < d.phi_d; ++ip) {
                HalfDiff hd;
                double u = (ih + 0.5) / d.theta_h;
                hd.theta_h = (mut == Mutation::LinearThetaH ? u : u * u) * (kPi / 2);
                hd.theta_d = (id + 0.5) / d.theta_d * (kPi / 2);
                hd.phi_d = (ip + 0.5) / d.phi_d * kPi;
                hd.phi_h = 0.0;
                Vec3 wi, wo;
                from_half_diff(hd, wi, wo);
                Rgb f = model.f(wo, wi);
                uint64_t k = mut == Mutation::SwapThetaAxes ? sample_index(d, id, ih, ip) : sample_index(d, ih, id, ip);
                for (int c = 0; c < 3; ++c) {
                    const int block = mut == Mutation::SwapRedBlue ? 2 - c : c;
                    const double scale = mut == Mutation::GreenScaleOfRed && c == 1 ? kFileScale[0] : kFileScale[c];
                    raw[block * n + k] = f[c] / scale;
                }
            }
    return raw;
}

// A constant BRDF rho/pi in every bin (a Lambertian MERL file).
std::vector<double> raw_lambert(const Rgb& rho, const MerlDims& d) {
    const uint64_t n = d.per_channel();
    std::vector<double> raw(3 * n);
    for (int c = 0; c < 3; ++c)
        for (uint64_t k = 0; k < n; ++k) raw[c * n + k] = rho[c] * kInvPi / kFileScale[c];
    return raw;
}

// Node directions exactly as merl_to_table documents them: wi at azimuth 0, wo at phi.
void node_dirs(const TableGeometry& g, uint32_t i, uint32_t r, uint32_t p, Vec3& wi, Vec3& wo) {
    wi = spherical_direction(g.axis_deg(0, i) * kDeg, 0.0);
    wo = spherical_direction(g.axis_deg(1, r) * kDeg, g.axis_deg(2, p) * kDeg);
}

// theta_d of a pair from geometry alone: the angle between wi and wo is 2 theta_d.
double theta_d_deg_of(const Vec3& wi, const Vec3& wo) { return safe_acos(dot(wi, wo)) / 2.0 / kDeg; }

struct RelError {
    double max_rel = 0, rms_rel = 0;
    double bias[3] = {0, 0, 0};  // mean signed relative error per channel
    uint64_t count = 0;
    double worst_deg[3] = {0, 0, 0};
    int worst_channel = 0;
};
// |table node - model| / model over the nodes with theta_i, theta_r <= max_theta_deg.
RelError compare_nodes(const BrdfTable& t, const Brdf& model, double max_theta_deg) {
    const TableGeometry& g = t.geometry();
    RelError e;
    double sum2 = 0, sum[3] = {0, 0, 0};
    uint64_t per_channel = 0;
    for (uint32_t i = 0; i < g.n[0]; ++i)
        for (uint32_t r = 0; r < g.n[1]; ++r) {
            if (g.axis_deg(0, i) > max_theta_deg + 1e-9 || g.axis_deg(1, r) > max_theta_deg + 1e-9) continue;
            for (uint32_t p = 0; p < g.n[2]; ++p) {
                Vec3 wi, wo;
                node_dirs(g, i, r, p, wi, wo);
                Rgb m = model.f(wo, wi);
                ++per_channel;
                for (int c = 0; c < g.channels; ++c) {
                    double mc = g.channels == 1 ? m.average() : m[c];
                    double signed_rel = (t.node(i, r, p, 0, c) - mc) / mc, rel = std::fabs(signed_rel);
                    sum[c] += signed_rel;
                    sum2 += rel * rel;
                    ++e.count;
                    if (rel > e.max_rel) {
                        e.max_rel = rel;
                        e.worst_deg[0] = g.axis_deg(0, i);
                        e.worst_deg[1] = g.axis_deg(1, r);
                        e.worst_deg[2] = g.axis_deg(2, p);
                        e.worst_channel = c;
                    }
                }
            }
        }
    e.rms_rel = std::sqrt(sum2 / double(e.count));
    for (int c = 0; c < g.channels; ++c) e.bias[c] = sum[c] / double(per_channel);
    return e;
}
std::string describe(const RelError& e) {
    char buf[300];
    std::snprintf(buf, sizeof buf,
                  "max rel %.4g at (theta_i %g, theta_r %g, phi %g) channel %d, rms rel %.4g, mean signed rel "
                  "R %.3g G %.3g B %.3g, %llu values",
                  e.max_rel, e.worst_deg[0], e.worst_deg[1], e.worst_deg[2], e.worst_channel, e.rms_rel, e.bias[0],
                  e.bias[1], e.bias[2], (unsigned long long)e.count);
    return buf;
}

// The error message's "NAME: offset N: expected X, found Y" parts.
struct ErrorParts {
    bool ok = false;
    std::string name, expected, found;
    uint64_t offset = 0;
};
ErrorParts split_error(const std::string& msg) {
    static const std::regex re(R"(^(.*): offset ([0-9]+): expected (.*), found (.*)$)");
    std::smatch m;
    ErrorParts p;
    if (!std::regex_match(msg, m, re)) return p;
    p.ok = true;
    p.name = m[1];
    p.offset = std::stoull(m[2]);
    p.expected = m[3];
    p.found = m[4];
    return p;
}

using table_files::table_error_of;

const char* kMicrofacetSpec = "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.2 rho_s=0.8";

}  // namespace

// ---------------------------------------------------------------- bins

TEST(MerlBins, ThetaHIsSqrtMappedLowerBinClamped) {
    EXPECT_EQ(merl_theta_h_bin(0.0, 90), 0u);
    EXPECT_EQ(merl_theta_h_bin(-0.1, 90), 0u);
    EXPECT_EQ(merl_theta_h_bin(std::numeric_limits<double>::quiet_NaN(), 90), 0u);
    // Bin k covers theta_h in [(k/90)^2, ((k+1)/90)^2) x 90 deg.
    for (uint32_t k = 0; k < 90; ++k) {
        double lo = double(k) / 90, hi = double(k + 1) / 90;
        double mid = 0.5 * (lo + hi);
        EXPECT_EQ(merl_theta_h_bin(mid * mid * kPi / 2, 90), k) << k;
        EXPECT_EQ(merl_theta_h_bin(std::nextafter(hi * hi * kPi / 2, 0.0) * (1 - 1e-12), 90), k) << k;
    }
    // 1 deg: sqrt(1/90) * 90 = 9.49 -> 9 (a linear mapping would give 1).
    EXPECT_EQ(merl_theta_h_bin(1.0 * kDeg, 90), 9u);
    // 22.5 deg: sqrt(1/4) * 90 = 45.
    EXPECT_EQ(merl_theta_h_bin(22.5 * kDeg + 1e-12, 90), 45u);
    EXPECT_EQ(merl_theta_h_bin(kPi / 2, 90), 89u);
    EXPECT_EQ(merl_theta_h_bin(2.0, 90), 89u);
    EXPECT_EQ(merl_theta_h_bin(1e300, 90), 89u);
    // Other dimensions use the same formula with their own count.
    EXPECT_EQ(merl_theta_h_bin(kPi / 8 + 1e-12, 10), 5u);  // sqrt(1/4) * 10
    EXPECT_EQ(merl_theta_h_bin(1.0, 1), 0u);
}

TEST(MerlBins, ThetaDIsLinearLowerBinClamped) {
    EXPECT_EQ(merl_theta_d_bin(0.0, 90), 0u);
    EXPECT_EQ(merl_theta_d_bin(-0.5, 90), 0u);
    EXPECT_EQ(merl_theta_d_bin(std::numeric_limits<double>::quiet_NaN(), 90), 0u);
    for (uint32_t k = 0; k < 90; ++k) EXPECT_EQ(merl_theta_d_bin((k + 0.5) * kDeg, 90), k) << k;
    EXPECT_EQ(merl_theta_d_bin(45.999 * kDeg, 90), 45u);
    EXPECT_EQ(merl_theta_d_bin(kPi / 2, 90), 89u);
    EXPECT_EQ(merl_theta_d_bin(3.0, 90), 89u);
    EXPECT_EQ(merl_theta_d_bin(kPi / 4, 10), 5u);
    EXPECT_EQ(merl_theta_d_bin(kPi / 4 - 1e-9, 10), 4u);
}

TEST(MerlBins, PhiDFoldsToHalfTurn) {
    EXPECT_EQ(merl_phi_d_bin(0.0, 180), 0u);
    for (uint32_t k = 0; k < 180; ++k) {
        double phi = (k + 0.5) * kDeg;
        EXPECT_EQ(merl_phi_d_bin(phi, 180), k) << k;
        // Reciprocity: phi_d - pi (as atan2 returns it, in (-pi, 0)) shares the bin.
        EXPECT_EQ(merl_phi_d_bin(phi - kPi, 180), k) << k;
    }
    EXPECT_EQ(merl_phi_d_bin(-kPi / 2, 180), 90u);
    EXPECT_EQ(merl_phi_d_bin(-0.5 * kDeg, 180), 179u);
    EXPECT_EQ(merl_phi_d_bin(-kPi, 180), 0u);
    EXPECT_EQ(merl_phi_d_bin(kPi, 180), 179u);  // atan2's +pi: clamped to the last bin
    EXPECT_EQ(merl_phi_d_bin(kPi - 1e-9, 180), 179u);
    EXPECT_EQ(merl_phi_d_bin(kPi / 2, 4), 2u);
}

// The formulas of MERL's BRDFRead.cpp, written as there (degrees, 360/2 phi bins).
TEST(MerlBins, MatchReferenceReaderOnRandomAngles) {
    auto ref_th = [](double th) {
        if (th <= 0.0) return 0;
        int t = int(std::sqrt(th / (kPi / 2) * 90 * 90));
        return t < 0 ? 0 : t < 89 ? t : 89;
    };
    auto ref_td = [](double td) {
        int t = int(td / (kPi * 0.5) * 90);
        return t < 0 ? 0 : t < 89 ? t : 89;
    };
    auto ref_pd = [](double pd) {
        if (pd < 0.0) pd += kPi;
        int t = int(pd / kPi * 360 / 2);
        return t < 0 ? 0 : t < 179 ? t : 179;
    };
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> th(-0.1, kPi / 2 + 0.1), pd(-kPi, kPi);
    for (int k = 0; k < 200000; ++k) {
        double a = th(rng), b = th(rng), c = pd(rng);
        ASSERT_EQ(int(merl_theta_h_bin(a, 90)), ref_th(a)) << a;
        ASSERT_EQ(int(merl_theta_d_bin(b, 90)), ref_td(b)) << b;
        ASSERT_EQ(int(merl_phi_d_bin(c, 180)), ref_pd(c)) << c;
    }
}

// ---------------------------------------------------------------- half/difference angles

TEST(MerlHalfDiff, KnownConfigurations) {
    // In-plane pair: wi at +a from the normal towards +x, wo at b towards -x (y exactly 0).
    // h lies at (a - b) / 2 towards +x, the pair straddles it by (a + b) / 2.
    const double a = 50.5 * kDeg, b = 20.5 * kDeg;
    Vec3 wi(std::sin(a), 0, std::cos(a)), wo(-std::sin(b), 0, std::cos(b));
    HalfDiff hd = to_half_diff(wi, wo);
    EXPECT_NEAR(hd.theta_h, 15.0 * kDeg, 1e-12);
    EXPECT_NEAR(hd.phi_h, 0.0, 1e-12);
    EXPECT_NEAR(hd.theta_d, 35.5 * kDeg, 1e-12);
    EXPECT_NEAR(hd.phi_d, 0.0, 1e-12);  // d rotated into the +x half
    // Swapping the roles puts d on the other side: phi_d = +-pi, the same bin after folding.
    HalfDiff sw = to_half_diff(wo, wi);
    EXPECT_NEAR(sw.theta_h, hd.theta_h, 1e-12);
    EXPECT_NEAR(sw.theta_d, hd.theta_d, 1e-12);
    EXPECT_NEAR(std::fabs(sw.phi_d), kPi, 1e-12);

    // Retro-reflection wi = wo: theta_h = theta, phi_h = phi, theta_d = 0.
    Vec3 w = spherical_direction(37 * kDeg, 123 * kDeg);
    hd = to_half_diff(w, w);
    EXPECT_NEAR(hd.theta_h, 37 * kDeg, 1e-12);
    EXPECT_NEAR(hd.phi_h, 123 * kDeg, 1e-12);
    EXPECT_NEAR(hd.theta_d, 0.0, 1e-7);

    // Out-of-plane pair: theta_h from h.z, theta_d from the angle between the directions,
    // both computed without the library's rotations.
    Vec3 wi2 = spherical_direction(30 * kDeg, 0.0), wo2 = spherical_direction(60 * kDeg, 100 * kDeg);
    Vec3 h = normalize(wi2 + wo2);
    hd = to_half_diff(wi2, wo2);
    EXPECT_NEAR(hd.theta_h, std::acos(h.z), 1e-12);
    EXPECT_NEAR(hd.phi_h, std::atan2(h.y, h.x), 1e-12);
    EXPECT_NEAR(hd.theta_d, std::acos(dot(wi2, wo2)) / 2, 1e-12);
}

TEST(MerlHalfDiff, InversesOnRandomPairs) {
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    auto random_dir = [&]() {  // uniform over the upper hemisphere
        double z = u(rng), phi = 2 * kPi * u(rng), s = std::sqrt(std::max(0.0, 1 - z * z));
        return Vec3(s * std::cos(phi), s * std::sin(phi), z);
    };
    double worst_dir = 0, worst_angle = 0;
    for (int k = 0; k < 100000; ++k) {
        Vec3 wi = random_dir(), wo = random_dir();
        HalfDiff hd = to_half_diff(wi, wo);
        // Invariants computed independently of the rotations.
        ASSERT_NEAR(hd.theta_h, std::acos(std::min(1.0, normalize(wi + wo).z)), 1e-7);
        ASSERT_NEAR(std::cos(2 * hd.theta_d), dot(wi, wo), 1e-12);
        Vec3 wi2, wo2;
        from_half_diff(hd, wi2, wo2);
        double e = std::max(length(wi2 - wi), length(wo2 - wo));
        worst_dir = std::max(worst_dir, e);
        ASSERT_LT(e, 1e-9) << k;

        // And the other way round, from random angles (theta_d < pi/2 so h is defined).
        HalfDiff a;
        a.theta_h = u(rng) * kPi / 2;
        a.phi_h = (2 * u(rng) - 1) * kPi * 0.999;
        a.theta_d = u(rng) * kPi / 2 * 0.999;
        a.phi_d = (2 * u(rng) - 1) * kPi * 0.999;
        if (a.theta_h < 1e-4 || a.theta_d < 1e-4) continue;  // azimuths undefined there
        from_half_diff(a, wi2, wo2);
        ASSERT_NEAR(length(wi2), 1.0, 1e-12);
        ASSERT_NEAR(length(wo2), 1.0, 1e-12);
        HalfDiff b = to_half_diff(wi2, wo2);
        double ea = std::max({std::fabs(b.theta_h - a.theta_h), std::fabs(b.phi_h - a.phi_h),
                              std::fabs(b.theta_d - a.theta_d), std::fabs(b.phi_d - a.phi_d)});
        worst_angle = std::max(worst_angle, ea);
        ASSERT_LT(ea, 1e-9) << k;
    }
    std::printf("[ measured ] half/diff round trip: max direction error %.3g, max angle error %.3g rad\n", worst_dir,
                worst_angle);
}

// ---------------------------------------------------------------- layout and scales

TEST(MerlLayout, ScalesAndSampleOrder) {
    for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(MerlBrdf::kScale[c], kFileScale[c]) << c;

    // Every raw sample holds its own position in the file: channel c, index k -> c * 1e7 + k.
    const MerlDims d;  // the standard 90 x 90 x 180
    const uint64_t n = d.per_channel();
    std::vector<double> raw(3 * n);
    for (int c = 0; c < 3; ++c)
        for (uint64_t k = 0; k < n; ++k) raw[c * n + k] = c * 1e7 + double(k);
    std::vector<uint8_t> bytes = encode_binary(d, raw);
    ASSERT_EQ(bytes.size(), 12u + 8u * 3u * 90u * 90u * 180u);
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), "index.binary");
    EXPECT_TRUE(merl->dims().standard());
    EXPECT_EQ(merl->nodata_bins(), 0u);

    struct Case {
        uint32_t ih, id, ip;
    } cases[] = {{0, 0, 0}, {3, 40, 17}, {12, 5, 90}, {45, 30, 179}, {60, 2, 1}, {89, 0, 100}, {1, 88, 45}};
    for (const Case& cs : cases) {
        HalfDiff hd;
        double u = (cs.ih + 0.5) / 90;
        hd.theta_h = u * u * kPi / 2;
        hd.theta_d = (cs.id + 0.5) * kDeg;
        hd.phi_d = (cs.ip + 0.5) * kDeg;
        hd.phi_h = 0.7;  // isotropic: phi_h does not enter the bin
        Vec3 wi, wo;
        from_half_diff(hd, wi, wo);
        const uint64_t k = (uint64_t(cs.ih) * 90 + cs.id) * 180 + cs.ip;
        MerlBrdf::Bin b = merl->bin(wi, wo);
        EXPECT_EQ(b.theta_h, cs.ih);
        EXPECT_EQ(b.theta_d, cs.id);
        EXPECT_EQ(b.phi_d, cs.ip);
        EXPECT_EQ(b.index, k);
        Rgb v = merl->value(b);
        for (int c = 0; c < 3; ++c) {
            EXPECT_DOUBLE_EQ(v[c], (c * 1e7 + double(k)) * kFileScale[c]) << "bin " << cs.ih << "," << cs.id << "," << cs.ip;
            EXPECT_EQ(merl->file_offset(b, c), 12 + 8 * (c * n + k));
            EXPECT_EQ(get_le64(bytes, merl->file_offset(b, c)), c * 1e7 + double(k));
        }
        if (wi.z > 0 && wo.z > 0) {
            Rgb f = merl->f(wo, wi);
            for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(f[c], v[c]);
        }
    }
    // Below the surface: no reflection, whatever the bin holds.
    Rgb below = merl->f(Vec3(0, 0, 1), Vec3(0.6, 0, -0.8));
    EXPECT_EQ(below.r, 0.0);
    EXPECT_EQ(below.g, 0.0);
    EXPECT_EQ(below.b, 0.0);
}

// ---------------------------------------------------------------- round trips

TEST(MerlRoundTrip, LambertIsExactAtEveryNode) {
    const Rgb rho(0.8, 0.5, 0.2);  // distinct channels: a scale swap shows
    Lambert model(rho);
    const MerlDims d;
    std::vector<uint8_t> bytes = encode_binary(d, raw_lambert(rho, d));
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), "lambert.binary");
    ASSERT_TRUE(merl->dims().standard());

    MerlConvertOptions opt;
    opt.step_deg = 2.0;
    auto t = merl_to_table(*merl, opt);
    const TableGeometry& g = t->geometry();
    ASSERT_EQ(g.n[0], 46u);
    ASSERT_EQ(g.n[2], 91u);
    ASSERT_EQ(g.channels, 3);
    EXPECT_EQ(t->info().nodata_filled, 0u);
    // Every node, grazing ones included: the stored float is rho/pi up to float rounding.
    for (uint32_t i = 0; i < g.n[0]; ++i)
        for (uint32_t r = 0; r < g.n[1]; ++r)
            for (uint32_t p = 0; p < g.n[2]; ++p)
                for (int c = 0; c < 3; ++c)
                    ASSERT_FLOAT_EQ(t->node(i, r, p, 0, c), float(rho[c] * kInvPi)) << i << " " << r << " " << p << " " << c;
    RelError e = compare_nodes(*t, model, 90.0);
    std::printf("[ measured ] Lambert round trip (2 deg, all nodes): %s\n", describe(e).c_str());
    EXPECT_LT(e.max_rel, 1e-7);
    // Albedo of the table: rho (the pole rows and the interpolation keep a constant exact).
    Rgb a = t->directional_albedo(30 * kDeg);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], rho[c], 1e-4) << c;

    // One channel: the mean of R, G, B.
    opt.channels = 1;
    opt.step_deg = 5.0;
    auto t1 = merl_to_table(*merl, opt);
    ASSERT_EQ(t1->geometry().channels, 1);
    EXPECT_FLOAT_EQ(t1->node(3, 7, 11, 0, 0), float(rho.average() * kInvPi));
    // Reciprocity folding is lossless for a constant.
    opt.channels = 3;
    opt.fold = true;
    auto tf = merl_to_table(*merl, opt);
    EXPECT_TRUE(tf->geometry().folded);
    EXPECT_FLOAT_EQ(tf->node(9, 4, 20, 0, 2), float(rho.b * kInvPi));
}

TEST(MerlRoundTrip, LambertThroughTempFile) {
    const Rgb rho(0.3, 0.6, 0.9);
    const MerlDims d;
    std::string path = ::testing::TempDir() + "merl_test_lambert.binary";
    write_file_bytes(path, encode_binary(d, raw_lambert(rho, d)));
    auto merl = MerlBrdf::load_file(path);
    std::remove(path.c_str());
    EXPECT_EQ(merl->name(), path);
    EXPECT_NE(merl->describe().find("90x90x180"), std::string::npos) << merl->describe();
    MerlConvertOptions opt;
    opt.step_deg = 5.0;
    auto t = merl_to_table(*merl, opt);
    RelError e = compare_nodes(*t, Lambert(rho), 90.0);
    EXPECT_LT(e.max_rel, 1e-7) << describe(e);
    // Lookups between nodes (interpolated) stay exact for a constant.
    Rgb v = t->eval_iso(33.3 * kDeg, 71.1 * kDeg, 2.0);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(v[c], rho[c] * kInvPi, 1e-7);
}

namespace {
// The microfacet file is 35 MB and takes a moment to generate: built once.
const std::vector<uint8_t>& microfacet_file() {
    static const std::vector<uint8_t> bytes = [] {
        MerlDims d;
        return encode_binary(d, raw_from_model(*make_brdf(kMicrofacetSpec), d));
    }();
    return bytes;
}
// Bounds on the relative node error away from grazing (theta_i, theta_r <= 70 deg) at a
// 5 deg step. The lookup returns the bin's sample wherever the node falls in the bin
// (1 deg in theta_d, up to ~1.2 deg in theta_h), so the error is half a bin's change of
// the model. Measured: max 0.081 at the mirror node (70, 70, 180) (1/cos^2 and Fresnel
// grow fast there; 0.016 with theta <= 45, 0.048 with theta <= 60), rms 0.0059, mean
// signed error 1.1e-4 per channel. The wrong files of MicrofacetToleranceCatchesWrongFiles
// (a channel scale off by 15%, swapped or linear theta_h axes, swapped channel blocks)
// fail max and rms each, and the wrong scale also shows as a 0.15 bias.
constexpr double kMicrofacetMaxRel = 0.12;
constexpr double kMicrofacetRmsRel = 0.012;
constexpr double kMicrofacetBias = 0.01;
constexpr double kAwayFromGrazingDeg = 70.0;

RelError microfacet_round_trip_error(const std::vector<uint8_t>& bytes, const std::string& name) {
    auto model = make_brdf(kMicrofacetSpec);
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), name);
    MerlConvertOptions opt;
    opt.step_deg = 5.0;
    auto t = merl_to_table(*merl, opt);
    return compare_nodes(*t, *model, kAwayFromGrazingDeg);
}
}  // namespace

TEST(MerlRoundTrip, MicrofacetWithinToleranceAwayFromGrazing) {
    RelError e = microfacet_round_trip_error(microfacet_file(), "microfacet.binary");
    std::printf("[ measured ] microfacet round trip (5 deg, theta <= 70): %s\n", describe(e).c_str());
    EXPECT_LT(e.max_rel, kMicrofacetMaxRel) << describe(e);
    EXPECT_LT(e.rms_rel, kMicrofacetRmsRel) << describe(e);
    for (int c = 0; c < 3; ++c) EXPECT_LT(std::fabs(e.bias[c]), kMicrofacetBias) << describe(e);

    // The specular peak is really there (the test is not passing on the diffuse base alone):
    // at the mirror node theta_i = theta_r = 60 the lobe is several times the base 0.2/pi.
    auto merl = MerlBrdf::parse(microfacet_file().data(), microfacet_file().size(), "microfacet.binary");
    MerlConvertOptions opt;
    opt.step_deg = 5.0;
    auto t = merl_to_table(*merl, opt);
    EXPECT_GT(t->node(12, 12, 36, 0, 0), 3.0 * 0.2 * kInvPi);
    EXPECT_LT(t->node(12, 12, 0, 0, 0), 1.5 * 0.2 * kInvPi);  // back-scatter side: mostly the base

    // Grazing nodes are finite and non-negative (they read the bins' samples).
    const TableGeometry& g = t->geometry();
    for (uint32_t r = 0; r < g.n[1]; ++r)
        for (uint32_t p = 0; p < g.n[2]; ++p)
            for (int c = 0; c < 3; ++c) {
                float v = t->node(g.n[0] - 1, r, p, 0, c);
                ASSERT_TRUE(std::isfinite(v) && v >= 0) << r << " " << p;
            }
}

// Exactly: every node off the pole rows stores the file's sample of the bin that the
// reference lookup selects for it (bins from the tested bin functions and angles), scaled
// by that channel's scale, as a float.
TEST(MerlRoundTrip, NodesHoldTheSelectedBinsSampleExactly) {
    const MerlDims d;
    const uint64_t n = d.per_channel();
    const std::vector<uint8_t>& bytes = microfacet_file();
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), "microfacet.binary");
    MerlConvertOptions opt;
    opt.step_deg = 5.0;
    auto t = merl_to_table(*merl, opt);
    const TableGeometry& g = t->geometry();
    uint64_t checked = 0;
    for (uint32_t i = 1; i < g.n[0]; ++i)  // i, r = 0: pole rows, averaged over phi by BrdfTable
        for (uint32_t r = 1; r < g.n[1]; ++r)
            for (uint32_t p = 0; p < g.n[2]; ++p) {
                Vec3 wi, wo;
                node_dirs(g, i, r, p, wi, wo);
                HalfDiff hd = to_half_diff(wi, wo);
                const uint64_t k = sample_index(d, merl_theta_h_bin(hd.theta_h, 90), merl_theta_d_bin(hd.theta_d, 90),
                                                merl_phi_d_bin(hd.phi_d, 180));
                for (int c = 0; c < 3; ++c) {
                    const float want = float(get_le64(bytes, 12 + 8 * (c * n + k)) * kFileScale[c]);
                    ASSERT_EQ(t->node(i, r, p, 0, c), want) << i << " " << r << " " << p << " channel " << c;
                    ++checked;
                }
            }
    EXPECT_EQ(checked, uint64_t(3) * 18 * 18 * 37);
}

TEST(MerlRoundTrip, MicrofacetToleranceCatchesWrongFiles) {
    auto model = make_brdf(kMicrofacetSpec);
    const MerlDims d;
    struct Case {
        Mutation mut;
        const char* what;
    } cases[] = {{Mutation::GreenScaleOfRed, "green written with the red scale"},
                 {Mutation::SwapThetaAxes, "theta_h and theta_d axes swapped"},
                 {Mutation::LinearThetaH, "theta_h bins without the sqrt mapping"},
                 {Mutation::SwapRedBlue, "R and B blocks swapped"}};
    for (const Case& cs : cases) {
        std::vector<uint8_t> bytes = encode_binary(d, raw_from_model(*model, d, cs.mut));
        RelError e = microfacet_round_trip_error(bytes, cs.what);
        std::printf("[ measured ] wrong file (%s): %s\n", cs.what, describe(e).c_str());
        EXPECT_GT(e.max_rel, 1.5 * kMicrofacetMaxRel) << cs.what << ": " << describe(e);
        EXPECT_GT(e.rms_rel, 3 * kMicrofacetRmsRel) << cs.what << ": " << describe(e);
    }
}

// ---------------------------------------------------------------- no data

TEST(MerlNoData, CountsAndLookupsReadZero) {
    const MerlDims d{2, 3, 4};
    const uint64_t n = d.per_channel();
    std::vector<double> raw(3 * n, 750.0);
    raw[0 * n + 5] = -1.0;                                       // bin 5: R missing
    raw[1 * n + 5] = -0.5;                                       // bin 5: G missing too
    raw[2 * n + 7] = std::numeric_limits<double>::quiet_NaN();  // bin 7: B NaN
    raw[1 * n + 23] = -1e-300;                                   // bin 23: G tiny negative
    std::vector<uint8_t> bytes = encode_binary(d, raw);
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), "small.binary");
    EXPECT_FALSE(merl->dims().standard());
    EXPECT_EQ(merl->nodata_bins(), 3u);
    EXPECT_NE(merl->describe().find("non-standard"), std::string::npos) << merl->describe();

    MerlBrdf::Bin b;
    b.index = 5;
    Rgb v = merl->value(b);
    EXPECT_LT(v.r, 0);
    EXPECT_LT(v.g, 0);
    EXPECT_DOUBLE_EQ(v.b, 750.0 * kFileScale[2]);
    b.index = 7;
    EXPECT_TRUE(std::isnan(merl->value(b).b));

    // f(): channels without data read 0, the others their value. Find a pair in bin 5
    // (theta_h bin 0, theta_d bin 1, phi_d bin 1 for 2 x 3 x 4) from the bin centres.
    HalfDiff hd;
    hd.theta_h = 0.25 * 0.25 * kPi / 2;  // sqrt-space centre of bin 0 of 2
    hd.theta_d = 1.5 / 3 * kPi / 2;
    hd.phi_d = 1.5 / 4 * kPi;
    Vec3 wi, wo;
    from_half_diff(hd, wi, wo);
    ASSERT_EQ(merl->bin(wi, wo).index, 5u);
    Rgb f = merl->f(wo, wi);
    EXPECT_EQ(f.r, 0.0);
    EXPECT_EQ(f.g, 0.0);
    EXPECT_DOUBLE_EQ(f.b, 750.0 * kFileScale[2]);
}

namespace {
// A Lambertian file whose bins with theta_d >= 81 deg have no data in `channels`
// (like the grazing-difference bins real measurements lack).
constexpr uint32_t kNoDataFromThetaDBin = 81;
std::vector<double> lambert_with_hole(const Rgb& rho, const MerlDims& d, std::initializer_list<int> channels) {
    std::vector<double> raw = raw_lambert(rho, d);
    const uint64_t n = d.per_channel();
    for (uint32_t ih = 0; ih < d.theta_h; ++ih)
        for (uint32_t id = kNoDataFromThetaDBin; id < d.theta_d; ++id)
            for (uint32_t ip = 0; ip < d.phi_d; ++ip)
                for (int c : channels) raw[c * n + sample_index(d, ih, id, ip)] = -1.0;
    return raw;
}
// Table nodes whose theta_d (from the angle between wi and wo alone) is in the hole.
// Nodes within 1e-6 deg of the bin edge would be ambiguous: the count fails if any exists.
uint64_t nodes_in_hole(const TableGeometry& g, bool& ambiguous) {
    uint64_t count = 0;
    ambiguous = false;
    for (uint32_t i = 0; i < g.n[0]; ++i)
        for (uint32_t r = 0; r < g.n[1]; ++r)
            for (uint32_t p = 0; p < g.n[2]; ++p) {
                Vec3 wi, wo;
                node_dirs(g, i, r, p, wi, wo);
                double td = theta_d_deg_of(wi, wo);
                if (std::fabs(td - kNoDataFromThetaDBin) < 1e-6) ambiguous = true;
                count += td > kNoDataFromThetaDBin;
            }
    return count;
}
}  // namespace

TEST(MerlNoData, FillPolicyFillsTheHoleFromTheTable) {
    const Rgb rho(0.8, 0.5, 0.2);
    const MerlDims d;
    std::vector<uint8_t> bytes = encode_binary(d, lambert_with_hole(rho, d, {0, 1, 2}));
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), "hole.binary");
    EXPECT_EQ(merl->nodata_bins(), uint64_t(90) * (90 - kNoDataFromThetaDBin) * 180);

    MerlConvertOptions opt;
    opt.step_deg = 5.0;
    opt.nodata = NoDataPolicy::Fill;
    auto t = merl_to_table(*merl, opt);
    bool ambiguous = false;
    uint64_t expect = nodes_in_hole(t->geometry(), ambiguous);
    ASSERT_FALSE(ambiguous);
    ASSERT_GT(expect, 0u);
    EXPECT_EQ(t->info().nodata_filled, expect);
    std::printf("[ measured ] no-data fill: %llu of %llu nodes filled\n", (unsigned long long)expect,
                (unsigned long long)t->geometry().cells());
    // Filled from a constant neighbourhood: the constant again, at every node.
    RelError e = compare_nodes(*t, Lambert(rho), 90.0);
    EXPECT_LT(e.max_rel, 1e-6) << describe(e);

    // Only blue missing: R and G untouched, B filled; 1 channel: the mean is missing too.
    bytes = encode_binary(d, lambert_with_hole(rho, d, {2}));
    merl = MerlBrdf::parse(bytes.data(), bytes.size(), "blue-hole.binary");
    t = merl_to_table(*merl, opt);
    EXPECT_EQ(t->info().nodata_filled, expect);
    e = compare_nodes(*t, Lambert(rho), 90.0);
    EXPECT_LT(e.max_rel, 1e-6) << describe(e);
    opt.channels = 1;
    t = merl_to_table(*merl, opt);
    EXPECT_EQ(t->info().nodata_filled, expect);
    EXPECT_FLOAT_EQ(t->node(18, 18, 0, 0, 0), float(rho.average() * kInvPi));
}

TEST(MerlNoData, RejectPolicyNamesTheSampleOffset) {
    const Rgb rho(0.8, 0.5, 0.2);
    const MerlDims d;
    const uint64_t n = d.per_channel();
    std::vector<uint8_t> bytes = encode_binary(d, lambert_with_hole(rho, d, {1}));  // green only
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), "hole.binary");
    MerlConvertOptions opt;
    opt.step_deg = 5.0;
    opt.nodata = NoDataPolicy::Reject;
    std::string msg = table_error_of([&] { merl_to_table(*merl, opt); });
    ErrorParts p = split_error(msg);
    ASSERT_TRUE(p.ok) << msg;
    EXPECT_EQ(p.name, "hole.binary");
    EXPECT_EQ(p.found, "-1") << msg;
    EXPECT_NE(p.expected.find("reject"), std::string::npos) << msg;
    EXPECT_NE(p.expected.find("channel G"), std::string::npos) << msg;
    // The offset is a sample of the green block of the file, and that sample is the marker.
    ASSERT_GE(p.offset, 12u);
    ASSERT_EQ((p.offset - 12) % 8, 0u) << msg;
    const uint64_t sample = (p.offset - 12) / 8;
    EXPECT_EQ(sample / n, 1u) << msg;
    ASSERT_LE(p.offset + 8, bytes.size());
    EXPECT_EQ(get_le64(bytes, p.offset), -1.0) << msg;
    // It is the bin of the first node (table order theta_i, theta_r, phi) in the hole,
    // located from the geometry alone.
    const TableGeometry g = TableGeometry::isotropic(5.0, 3);
    bool found = false;
    for (uint32_t i = 0; i < g.n[0] && !found; ++i)
        for (uint32_t r = 0; r < g.n[1] && !found; ++r)
            for (uint32_t q = 0; q < g.n[2] && !found; ++q) {
                Vec3 wi, wo;
                node_dirs(g, i, r, q, wi, wo);
                double td = theta_d_deg_of(wi, wo);
                if (td <= kNoDataFromThetaDBin) continue;
                found = true;
                const uint64_t k = sample % n;
                const uint32_t ih = uint32_t(k / (90 * 180)), id = uint32_t(k / 180 % 90);
                EXPECT_EQ(id, uint32_t(td)) << msg;
                double th = std::acos(normalize(wi + wo).z);
                EXPECT_EQ(ih, uint32_t(std::sqrt(th / (kPi / 2)) * 90)) << msg;
                std::string node = "theta_i=" + std::to_string(int(g.axis_deg(0, i))) +
                                   " theta_r=" + std::to_string(int(g.axis_deg(1, r)));
                EXPECT_NE(msg.find(node), std::string::npos) << msg << " / " << node;
            }
    EXPECT_TRUE(found);
    // Without holes, Reject converts.
    bytes = encode_binary(d, raw_lambert(rho, d));
    merl = MerlBrdf::parse(bytes.data(), bytes.size(), "full.binary");
    EXPECT_NO_THROW(merl_to_table(*merl, opt));
}

// ---------------------------------------------------------------- broken files

TEST(MerlParse, WrongDimensionsNameTheHeaderOffset) {
    struct Case {
        int32_t dims[3];
        uint64_t offset;
        const char* found;
    } cases[] = {{{0, 90, 180}, 0, "0"},       {{-90, 90, 180}, 0, "-90"}, {{90, 4097, 180}, 4, "4097"},
                 {{90, 90, 0}, 8, "0"},        {{90, 90, -1}, 8, "-1"},    {{90, -2147483647 - 1, 180}, 4, "-2147483648"}};
    for (const Case& cs : cases) {
        std::vector<uint8_t> bytes = encode_binary(cs.dims[0], cs.dims[1], cs.dims[2], std::vector<double>(64, 1.0));
        std::string msg = table_error_of([&] { MerlBrdf::parse(bytes.data(), bytes.size(), "dims.binary"); });
        ErrorParts p = split_error(msg);
        ASSERT_TRUE(p.ok) << msg;
        EXPECT_EQ(p.name, "dims.binary");
        EXPECT_EQ(p.offset, cs.offset) << msg;
        EXPECT_EQ(p.found, cs.found) << msg;
        EXPECT_NE(p.expected.find("dimension"), std::string::npos) << msg;
    }
}

TEST(MerlParse, TruncatedAndTrailingBytesNameTheOffset) {
    // Shorter than the header.
    std::vector<uint8_t> head = encode_binary(90, 90, 180, {});
    for (size_t len : {size_t(0), size_t(7), size_t(11)}) {
        std::string msg = table_error_of([&] { MerlBrdf::parse(head.data(), len, "short.binary"); });
        ErrorParts p = split_error(msg);
        ASSERT_TRUE(p.ok) << msg;
        EXPECT_EQ(p.offset, len) << msg;
    }
    // Standard header, payload cut: the offset is where the data ended.
    const MerlDims d;
    std::vector<uint8_t> full = encode_binary(d, raw_lambert(Rgb(0.5), d));
    const uint64_t total = 12 + 8 * 3 * d.per_channel();
    ASSERT_EQ(full.size(), total);
    for (uint64_t len : {uint64_t(12), uint64_t(112), total / 2 + 3, total - 1}) {
        std::string msg = table_error_of([&] { MerlBrdf::parse(full.data(), size_t(len), "cut.binary"); });
        ErrorParts p = split_error(msg);
        ASSERT_TRUE(p.ok) << msg;
        EXPECT_EQ(p.name, "cut.binary");
        EXPECT_EQ(p.offset, len) << msg;
        EXPECT_NE(p.expected.find(std::to_string(total) + " bytes"), std::string::npos) << msg;
        EXPECT_EQ(p.found, "end of data") << msg;
    }
    // A small file's header on a standard-size body (wrong dims for the data): trailing bytes.
    std::vector<uint8_t> wrong = full;
    const int32_t small[3] = {90, 90, 90};
    std::memcpy(wrong.data() + 8, &small[2], 4);  // little-endian hosts (as the test encoder)
    ASSERT_EQ(wrong[8], 90);
    const uint64_t small_total = 12 + 8 * 3 * 90 * 90 * 90;
    std::string msg = table_error_of([&] { MerlBrdf::parse(wrong.data(), wrong.size(), "wrongdims.binary"); });
    ErrorParts p = split_error(msg);
    ASSERT_TRUE(p.ok) << msg;
    EXPECT_EQ(p.offset, small_total) << msg;
    EXPECT_NE(p.found.find(std::to_string(total - small_total) + " trailing bytes"), std::string::npos) << msg;
    // Trailing bytes after a correct file.
    full.push_back(0);
    full.push_back(0);
    msg = table_error_of([&] { MerlBrdf::parse(full.data(), full.size(), "long.binary"); });
    p = split_error(msg);
    ASSERT_TRUE(p.ok) << msg;
    EXPECT_EQ(p.offset, total) << msg;
    EXPECT_EQ(p.found, "2 trailing bytes") << msg;
}

TEST(MerlParse, InfiniteSampleNamesItsOffset) {
    const MerlDims d{3, 3, 6};
    const uint64_t n = d.per_channel();
    for (double bad : {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()}) {
        std::vector<double> raw(3 * n, 100.0);
        raw[2 * n + 17] = bad;
        raw[2 * n + 40] = bad;  // only the first is named
        std::vector<uint8_t> bytes = encode_binary(d, raw);
        std::string msg = table_error_of([&] { MerlBrdf::parse(bytes.data(), bytes.size(), "inf.binary"); });
        ErrorParts p = split_error(msg);
        ASSERT_TRUE(p.ok) << msg;
        EXPECT_EQ(p.offset, 12 + 8 * (2 * n + 17)) << msg;
        EXPECT_EQ(p.found, bad > 0 ? "inf" : "-inf") << msg;
    }
    // NaN and negative samples are no-data markers, not errors.
    std::vector<double> raw(3 * n, 100.0);
    raw[4] = std::numeric_limits<double>::quiet_NaN();
    raw[n + 4] = -1.0;
    std::vector<uint8_t> bytes = encode_binary(d, raw);
    std::unique_ptr<MerlBrdf> merl;
    ASSERT_NO_THROW(merl = MerlBrdf::parse(bytes.data(), bytes.size(), "nan.binary"));
    EXPECT_EQ(merl->nodata_bins(), 1u);
}

TEST(MerlParse, NonStandardDimensionsUseTheSameFormulas) {
    // 4 x 3 x 8 bins: sample k holds k. A pair at the centre of bin (2, 1, 5) reads it.
    const MerlDims d{4, 3, 8};
    const uint64_t n = d.per_channel();
    std::vector<double> raw(3 * n);
    for (uint64_t k = 0; k < 3 * n; ++k) raw[k] = double(k);
    std::vector<uint8_t> bytes = encode_binary(d, raw);
    auto merl = MerlBrdf::parse(bytes.data(), bytes.size(), "4x3x8.binary");
    EXPECT_EQ(merl->dims().theta_h, 4u);
    EXPECT_EQ(merl->dims().theta_d, 3u);
    EXPECT_EQ(merl->dims().phi_d, 8u);
    HalfDiff hd;
    hd.theta_h = (2.5 / 4) * (2.5 / 4) * kPi / 2;
    hd.theta_d = 1.5 / 3 * kPi / 2;
    hd.phi_d = 5.5 / 8 * kPi;
    MerlBrdf::Bin b = merl->bin(hd);
    EXPECT_EQ(b.index, (2u * 3 + 1) * 8 + 5);
    Rgb v = merl->value(b);
    for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(v[c], double(c * n + b.index) * kFileScale[c]);
}

TEST(MerlParse, MissingFileIsATableError) {
    std::string msg = table_error_of([] { MerlBrdf::load_file(::testing::TempDir() + "no_such_dir/none.binary"); });
    EXPECT_NE(msg.find("none.binary"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("NO EXCEPTION"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("WRONG EXCEPTION"), std::string::npos) << msg;
}
