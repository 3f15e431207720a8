// Exact profile tables (ss_profile.h, radial_profile.h): the file format and its loader, the
// evaluation, the renderer-facing ExactProfile, and the tables against closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "chandrasekhar_h.h"
#include "shading/finish/finish.h"
#include "shading/subsurface/media_presets.h"
#include "shading/subsurface/radial_profile.h"
#include "shading/subsurface/ss_profile.h"
#include "shading/subsurface/subsurface.h"
#include "shading/subsurface/transport_mc.h"
#include "shading/core/bytes.h"

using namespace shading;

namespace {

constexpr double kInfD = std::numeric_limits<double>::infinity();

// A small table, built once per process: g {0, 0.5} x eta {1, 1.5}, few photons (well under a
// second); every test below that uses it runs in a process of its own (ctest).
const ProfileTables& small_tables() {
    static std::shared_ptr<ProfileTables> t = [] {
        ProfileBuildSettings s;
        s.g = {0.0, 0.5};
        s.eta = {1.0, 1.5};
        s.photons = 4000;
        s.short_photons = 20000;
        s.threads = 2;
        return build_profile_tables(s);
    }();
    return *t;
}

// Chandrasekhar's H(1) for isotropic scattering (chandrasekhar_h.h, independent of the library).
double h_one(double w) { return chandrasekhar_h(1.0, w); }

// The checksum of the whole file (format 3), written out with the library's fnv1a64 on a copy
// whose checksum field is zero: not profile_file_checksum, so a change of its definition shows.
void patch_checksum(std::vector<std::uint8_t>& b) {
    std::vector<std::uint8_t> z = b;
    for (int k = 0; k < 8; ++k) z[24 + k] = 0;
    const std::uint64_t sum = fnv1a64(z.data(), z.size());
    for (int k = 0; k < 8; ++k) b[24 + k] = std::uint8_t(sum >> (8 * k));
}

std::string load_error(const std::vector<std::uint8_t>& b) {
    try {
        load_profile_tables(b.data(), b.size(), "t.ssp");
    } catch (const ProfileError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(ProfileTables, FileRoundTripIsExactAndStaleDetection) {
    const ProfileTables& t = small_tables();
    const std::vector<std::uint8_t> bytes = t.serialize();
    auto back = load_profile_tables(bytes.data(), bytes.size(), "t.ssp");
    EXPECT_EQ(back->serialize(), bytes);
    EXPECT_EQ(back->records.size(), t.records.size());
    EXPECT_EQ(back->settings.g, t.settings.g);
    EXPECT_FALSE(back->stale(t.settings));
    ProfileBuildSettings other = t.settings;
    other.photons += 1;
    EXPECT_TRUE(back->stale(other));
    other = t.settings;
    other.eta.push_back(2.0);
    EXPECT_TRUE(back->stale(other));
}

// The normal-incidence run's full paths grow with the slab's transport thickness d (1 - g):
// photons below 1.6 of them, (d' / 1.6)^2 times photons above, at most 8 times (a thick slab's
// transmitted exit distribution is photon noise otherwise: DIPOLE.md 10.3).
TEST(ProfileTables, ThickSlabsTakeMorePaths) {
    ProfileBuildSettings s;
    s.photons = 20000;
    EXPECT_EQ(s.normal_photons(kInfD, 0.9), 20000u);  // the half-space: as set
    EXPECT_EQ(s.normal_photons(1.0, 0.0), 20000u);
    EXPECT_EQ(s.normal_photons(16.0, 0.9), 20000u);  // d' 1.6: the first that grows
    EXPECT_EQ(s.normal_photons(32.0, 0.9), 80000u);  // d' 3.2: 4 times
    EXPECT_EQ(s.normal_photons(50.0, 0.9), 160000u);  // d' 5: 9.8, so 8, the most
    EXPECT_EQ(s.normal_photons(64.0, 0.9), 160000u);
    EXPECT_EQ(s.normal_photons(64.0, 0.0), 160000u);
    EXPECT_EQ(s.normal_photons(2.0, 0.0), 31250u);   // (2 / 1.6)^2 = 1.5625
    EXPECT_EQ(s.normal_photons(16.0, 0.95), 20000u);  // d' 0.8
}

// Thick slabs at low albedo transmit almost nothing: a face with a handful of noisy exits must
// still give a file its own loader accepts (it once stored an angle sample of 1.4e6 and a tail
// amplitude beyond the format's bound) and a finite, non-negative profile.
TEST(ProfileTables, NoiseOnlySlabFacesStillLoad) {
    ProfileBuildSettings s;
    s.g = {0.0};
    s.eta = {1.33};
    s.thickness = {16.0, 32.0, 64.0};
    s.photons = 2000;
    s.short_photons = 5000;
    s.threads = 2;
    auto t = build_profile_tables(s);
    const std::vector<std::uint8_t> bytes = t->serialize();
    EXPECT_EQ(load_error(bytes), "");
    auto back = load_profile_tables(bytes.data(), bytes.size(), "slabs.ssp");
    // Asked for again with the same settings, the file is not stale: a slab table has no
    // distance bands and no oblique exits whatever the settings say (before 2026-12-06 the
    // oblique azimuths made every `make brdf-data` rebuild the slab tables: 3.5 minutes).
    ProfileBuildSettings with_bands = s;
    with_bands.exit_bands = {0.25, 1.0};
    EXPECT_FALSE(back->stale(s));
    EXPECT_FALSE(back->stale(with_bands));
    ProfileBuildSettings other = s;
    other.seed = 2;
    EXPECT_TRUE(back->stale(other));
    for (double d : {16.0, 40.0, 64.0})
        for (int face : {0, 1})
            for (double a : {0.1, 0.5, 0.9}) {
                ChannelProfile c(*back, a, 0.0, 1.33, d, face);
                for (double r : {0.1, 1.0, 10.0}) {
                    const double v = c.rd(r);
                    EXPECT_TRUE(std::isfinite(v) && v >= 0) << "d " << d << " face " << face << " a " << a << " r " << r;
                }
                for (double mu : {0.2, 1.0}) EXPECT_TRUE(std::isfinite(c.exit_factor(mu))) << d << " " << face << " " << a;
            }
}

TEST(ProfileTables, LoaderNamesTheOffsetOfEveryKindOfDamage) {
    const std::vector<std::uint8_t> good = small_tables().serialize();
    struct Case {
        const char* what;
        std::function<void(std::vector<std::uint8_t>&)> damage;
        std::string expect;
    };
    auto set32 = [](std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
        for (int k = 0; k < 4; ++k) b[at + k] = std::uint8_t(v >> (8 * k));
    };
    auto setf64 = [](std::vector<std::uint8_t>& b, std::size_t at, double d) {
        std::uint64_t u;
        std::memcpy(&u, &d, 8);
        for (int k = 0; k < 8; ++k) b[at + k] = std::uint8_t(u >> (8 * k));
    };
    const std::uint32_t off = std::uint32_t(good[12]) | std::uint32_t(good[13]) << 8;
    const std::vector<Case> cases = {
        {"empty", [](auto& b) { b.clear(); }, "offset 0: expected a header of 168 bytes"},
        {"truncated header", [](auto& b) { b.resize(100); }, "offset 100: expected a header"},
        {"magic", [](auto& b) { b[0] = 'X'; }, "offset 0: expected the magic"},
        {"version", [&](auto& b) { set32(b, 8, 2); }, "offset 8: expected format version 6, found 2 (rebuild it: make brdf-data"},
        {"flags", [&](auto& b) { set32(b, 36, 4), patch_checksum(b); }, "offset 36: expected flags"},
        {"g count", [&](auto& b) { set32(b, 40, 0), patch_checksum(b); }, "offset 40: expected 1 to 64 g nodes, found 0"},
        {"albedo count", [&](auto& b) { set32(b, 52, 100000), patch_checksum(b); }, "offset 52: expected 4 to 1000 albedo nodes"},
        {"radius", [&](auto& b) { setf64(b, 80, -1.0), patch_checksum(b); }, "offset 80: expected the first radius"},
        {"g order", [&](auto& b) { setf64(b, 176, 0.0), patch_checksum(b); }, "offset 176: g node 1: expected increasing values"},
        {"eta range", [&](auto& b) { setf64(b, 184, 0.5), patch_checksum(b); }, "offset 184: eta node 0: expected a value in [1, 4]"},
        {"payload offset", [&](auto& b) { set32(b, 12, off + 16), patch_checksum(b); }, "offset 12: expected the payload offset"},
        {"payload size", [&](auto& b) { b.resize(b.size() - 4), patch_checksum(b); }, "expected the file to end after"},
        {"trailing", [&](auto& b) { b.push_back(0), patch_checksum(b); }, "expected the file to end after"},
        {"checksum", [&](auto& b) { b[off + 40] ^= 1; }, "offset 24: expected the file's checksum"},
        {"header field", [&](auto& b) { b[60] ^= 1; }, "offset 24: expected the file's checksum"},
        {"nan total",
         [&](auto& b) {
             const float nan = std::numeric_limits<float>::quiet_NaN();
             std::memcpy(&b[off], &nan, 4);
             patch_checksum(b);
         },
         "offset " + std::to_string(off) + ": g=0 eta=1 d=inf reflection albedo=0.095162582 total: expected a value in [0, 1.5], found nan"},
        {"negative band ratio",
         [&](auto& b) {
             const float neg = -1.0f;
             std::memcpy(&b[b.size() - 4 * (1 + 7 * 7 * 8)], &neg, 4);  // before the oblique exits
             patch_checksum(b);
         },
         "reflection albedo=0.999992861 band exit ratio 63: expected a value in [0, 100], found -1"},
        {"negative profile",
         [&](auto& b) {
             const float neg = -1.0f;
             std::memcpy(&b[b.size() - 4 * (1 + 8 + 64 + 7 * 7 * 8)], &neg, 4);  // before bands, their ratios, the oblique exits
             patch_checksum(b);
         },
         "radius node 50: expected a value in [0, 1e+30], found -1"},
        {"band edges", [&](auto& b) { set32(b, 76, 16), patch_checksum(b); }, "offset 76: expected 0 to 15 exit-distance band edges, found 16"},
        {"band edge order",
         [&](auto& b) { setf64(b, 168 + 8 * (2 + 2 + 1 + 8 + 1), 0.1), patch_checksum(b); },
         "exit-distance band edge node 1: expected increasing values, found 0.1 after 0.25"},
        {"oblique azimuths", [&](auto& b) { set32(b, 160, 1), patch_checksum(b); },
         "offset 160: expected 0, or 2 to 32 oblique exit azimuths, found 1"},
        {"oblique orders", [&](auto& b) { set32(b, 164, 0), patch_checksum(b); },
         "offset 164: expected 1 to 100000 oblique exit orders, found 0"},
        {"negative oblique exit",
         [&](auto& b) {
             const float neg = -2.0f;
             std::memcpy(&b[b.size() - 4], &neg, 4);
             patch_checksum(b);
         },
         "oblique exit sample 391: expected a value in [0, 1000000], found -2"},
    };
    for (const Case& c : cases) {
        std::vector<std::uint8_t> b = good;
        c.damage(b);
        const std::string err = load_error(b);
        EXPECT_NE(err.find(c.expect), std::string::npos) << c.what << ": " << err;
        EXPECT_EQ(err.rfind("t.ssp: offset ", 0), 0u) << c.what << ": " << err;
    }
    EXPECT_EQ(load_error(good), "");
}

TEST(ProfileTables, EveryChangedByteIsRefused) {
    // Format 3: the checksum covers the header too. Before, a changed byte 60 (radial nodes per
    // decade) loaded and moved every radial node: a silently wrong image (issue 29). Every byte
    // of the header, the axes and the padding, and every 97th of the payload, changed in turn:
    // magic and version name themselves, every other byte is a checksum mismatch at offset 24.
    const std::vector<std::uint8_t> good = small_tables().serialize();
    const std::size_t off = std::size_t(good[12]) | std::size_t(good[13]) << 8;
    std::size_t tried = 0;
    for (std::size_t i = 0; i < good.size(); i += i < off ? 1 : 97) {
        for (std::uint8_t bit : {std::uint8_t(1), std::uint8_t(0x80)}) {
            std::vector<std::uint8_t> b = good;
            b[i] ^= bit;
            const std::string err = load_error(b);
            ++tried;
            const char* want = i < 8 ? "t.ssp: offset 0: expected the magic" : i < 12 ? "t.ssp: offset 8: expected format version 6"
                                                                                      : "t.ssp: offset 24: expected the file's checksum";
            ASSERT_EQ(err.rfind(want, 0), 0u) << "byte " << i << " ^ " << int(bit) << ": " << err;
        }
    }
    EXPECT_GT(tried, 2 * off);
    EXPECT_EQ(profile_file_checksum(good.data(), good.size()),
              std::uint64_t(good[24]) | std::uint64_t(good[25]) << 8 | std::uint64_t(good[26]) << 16 |
                  std::uint64_t(good[27]) << 24 | std::uint64_t(good[28]) << 32 | std::uint64_t(good[29]) << 40 |
                  std::uint64_t(good[30]) << 48 | std::uint64_t(good[31]) << 56);
}

TEST(ProfileTables, ForeignTablesAreNotUsed) {
    // Another generator's tables, or slab tables given as the semi-infinite ones: an error
    // named for the file, never an image from them.
    std::vector<std::uint8_t> b = small_tables().serialize();
    b[32] = std::uint8_t(kProfileGeneratorVersion - 1);
    patch_checksum(b);
    auto old = load_profile_tables(b.data(), b.size(), "old.ssp");
    const Medium m = Medium::from_reduced(Rgb(1.0), Rgb(0.01), 1.3);
    try {
        ExactProfile p(m, old);
        FAIL() << "expected invalid_argument";
    } catch (const std::invalid_argument& e) {
        EXPECT_EQ(std::string(e.what()).rfind("old.ssp: built by profile generator " + std::to_string(kProfileGeneratorVersion - 1) +
                                                  ", this renderer reads generator " + std::to_string(kProfileGeneratorVersion) +
                                                  "'s: rebuild it",
                                              0),
                  0u)
            << e.what();
    }
    const std::shared_ptr<const ProfileTables> good(std::shared_ptr<const ProfileTables>(), &small_tables());
    EXPECT_THROW(ExactProfile(m, good, old), std::invalid_argument);
}

TEST(ProfileTables, ChannelEvaluationIsConsistent) {
    const ProfileTables& t = small_tables();
    for (double g : {0.0, 0.25, 0.5})
        for (double eta : {1.0, 1.2, 1.5})
            for (double ap : {0.01, 0.3, 0.9, 0.999, 1.0}) {
                const ChannelProfile p(t, ap, g, eta);
                ASSERT_TRUE(std::isfinite(p.total()) && p.total() > 0 && p.total() < 1);
                // the disc integral reaches the total, monotonically
                EXPECT_NEAR(p.disc(kInfD), p.total(), 1e-12);
                EXPECT_NEAR(p.disc(1e12), p.total(), 1e-3 * p.total() + 1e-12);
                double last = 0;
                for (double R : {1e-6, 1e-3, 0.01, 0.05, 0.1, 1.0, 10.0, 100.0, 1e4}) {
                    const double d = p.disc(R);
                    EXPECT_GE(d, last - 1e-15);
                    last = d;
                }
                // rd finite and non-negative at hard radii; annulus means match disc differences
                for (double r : {0.0, 1e-9, 0.005, 0.0101, 1.0, 999.0, 1e9, kInfD}) {
                    const double v = p.rd(r);
                    EXPECT_TRUE(std::isfinite(v) && v >= 0) << r;
                }
                EXPECT_NEAR(p.annulus_mean(0.5, 0.6) * kPi * (0.36 - 0.25), p.disc(0.6) - p.disc(0.5), 1e-12);
                const double r90 = p.radius_containing(0.9);
                EXPECT_NEAR(p.disc(r90), 0.9 * p.total(), 1e-9 * p.total());
                // the exit distribution integrates to about 1 (its samples are normalised by the
                // exits' own total, the interpolant's integral is the check): 2 int a mu dmu.
                // 5 %: two estimates from this small table's 24 000 paths (the shipped tables
                // agree within 1.3 %, sstool build's log).
                double s = 0;
                for (int i = 0; i < 2000; ++i) {
                    const double mu = (i + 0.5) / 2000;
                    s += 2 * p.exit_factor(mu) * mu / 2000;
                }
                if (ap >= 0.3) {
                    EXPECT_NEAR(s, 1.0, 0.05) << "g " << g << " eta " << eta << " a' " << ap;
                }
                EXPECT_NEAR(p.entry_factor(1.0), 1.0, 1e-12);
                EXPECT_GT(p.entry_factor(0.3), 0.5);
                EXPECT_EQ(p.exit_factor(0.0), 0.0);
            }
    // Monotone in albedo.
    EXPECT_LT(ChannelProfile(t, 0.5, 0.0, 1.5).total(), ChannelProfile(t, 0.9, 0.0, 1.5).total());
    // Out of range.
    EXPECT_THROW(ChannelProfile(t, 0.5, 0.7, 1.0), std::invalid_argument);
    EXPECT_THROW(ChannelProfile(t, 0.5, 0.0, 1.6), std::invalid_argument);
    EXPECT_THROW(ChannelProfile(t, 0.5, 0.0, 1.0, 2.0), std::invalid_argument);
}

TEST(ProfileTables, IndexMatchedIsotropicTablesGiveChandrasekharsTotalAndRadiance) {
    // Tables built from the Monte Carlo; single scattering from the exact formula (not the
    // tables). Stated tolerances: total within 1.5 %, normal radiance within 2 % of
    // pi L / E = w H(1)^2 / 8 (Chandrasekhar), the multiple part carried by exit_factor(1).
    ProfileBuildSettings set;  // g = 0, eta = 1 only: more photons, still about a second
    set.photons = 30000;
    set.short_photons = 150000;
    set.threads = 2;
    const auto t = *build_profile_tables(set);
    for (double w : {0.5, 0.9, 0.99}) {
        const ChannelProfile p(t, w, 0.0, 1.0);
        const double h = h_one(w);
        const double single_total = w * (1 - std::log(2.0)) / 2, single_radiance = w / 8;
        EXPECT_NEAR((p.total() + single_total) / (1 - h * std::sqrt(1 - w)), 1.0, 0.015) << w;
        EXPECT_NEAR((p.total() * p.exit_factor(1.0) + single_radiance) / (w * h * h / 8), 1.0, 0.02) << w;
    }
}

// The oblique exits against Chandrasekhar's half-space, relative.
constexpr double kObliqueChandrasekharTol = 0.03;

TEST(ProfileTables, ObliqueExitsGiveChandrasekharsRadianceAtEveryIncidence) {
    // Light entering at a slant, index matched, isotropic: the multiple-scattering radiance
    // total x entry_factor(mu0) x exit_factor_oblique(mu0, mu, phi) against Chandrasekhar's
    // pi L / E = w (H(mu) H(mu0) - 1) / (4 (mu + mu0)) (single scattering, w / (4 (mu + mu0)),
    // taken out), with H from chandrasekhar_h.h (independent of the library), at incidences on
    // and between the tables' nodes and three views in three azimuths (isotropic scattering:
    // no azimuth dependence). Tolerance stated before measuring: 3 % (the oblique runs' noise at
    // these photons, 15 000 + 75 000 per incidence). The normal-incidence exit distribution
    // alone (exit_factor) misses this by up to a fifth at mu0 0.2 (checked below: the point of it).
    ProfileBuildSettings set;
    set.photons = 30000;
    set.short_photons = 150000;
    set.oblique_fraction = 0.5;
    set.threads = 2;
    const auto t = *build_profile_tables(set);
    double worst_plain = 0, worst = 0;
    for (double w : {0.5, 0.9, 0.99}) {
        const ChannelProfile p(t, w, 0.0, 1.0);
        ASSERT_TRUE(p.oblique_exits());
        for (double mu0 : {0.2, 0.45, 0.55, 0.8})
            for (double mu : {1.0, 0.7, 0.4})
                for (double cos_phi : {1.0, 0.0, -1.0}) {
                    const double exact = w * (chandrasekhar_h(mu, w) * chandrasekhar_h(mu0, w) - 1) / (4 * (mu + mu0));
                    const double got = p.total() * p.entry_factor(mu0) * p.exit_factor_oblique(mu0, mu, cos_phi);
                    EXPECT_NEAR(got / exact, 1.0, kObliqueChandrasekharTol)
                        << "w " << w << " mu0 " << mu0 << " mu " << mu << " cos phi " << cos_phi;
                    worst = std::max(worst, std::fabs(got / exact - 1));
                    const double plain = p.total() * p.entry_factor(mu0) * p.exit_factor(mu);
                    worst_plain = std::max(worst_plain, std::fabs(plain / exact - 1));
                }
        // at normal incidence the oblique exits are the normal ones
        for (double mu : {1.0, 0.5, 0.1}) EXPECT_EQ(p.exit_factor_oblique(1.0, mu, 0.3), p.exit_factor(mu));
        EXPECT_EQ(p.exit_factor_oblique(0.5, 0.0, 1.0), 0.0);
    }
    std::printf("worst error: %.2f %% (the normal-incidence exit distribution's: %.1f %%)\n", 100 * worst, 100 * worst_plain);
    EXPECT_GT(worst_plain, 0.1);
    // Forward scattering (the small tables' g 0.5): light entering at a slant leaves more
    // toward where it was going.
    const ChannelProfile f(small_tables(), 0.9, 0.5, 1.0);
    EXPECT_GT(f.exit_factor_oblique(0.3, 0.5, 1.0), 1.2 * f.exit_factor_oblique(0.3, 0.5, -1.0));
}

TEST(ExactProfile, SceneUnitsGClampAndRange) {
    auto tables = std::make_shared<ProfileTables>(small_tables());
    Medium m;
    m.sigma_s = Rgb(2.0, 1.0, 0.0);
    m.sigma_a = Rgb(0.02, 0.1, 0.1);
    m.g = Rgb(0.3, 0.8, 0.0);  // 0.8: beyond the tables' 0.5
    m.eta = 1.3;
    m.mm_per_unit = 1.0;
    const ExactProfile a(m, tables);
    ASSERT_EQ(a.notes().size(), 1u);
    EXPECT_NE(a.notes()[0].find("g = 0.8 (g) is outside"), std::string::npos) << a.notes()[0];
    EXPECT_EQ(a.channel(2), nullptr);  // no scattering: nothing diffuses
    EXPECT_EQ(a.total().b, 0.0);
    EXPECT_EQ(a.rd(0.1).b, 0.0);
    m.mm_per_unit = 10.0;
    const ExactProfile b(m, tables);
    for (double r : {0.0, 0.01, 0.3, 2.0}) {
        EXPECT_NEAR(b.rd(r / 10).r, 100 * a.rd(r).r, 1e-9 * a.rd(r).r);
        EXPECT_NEAR(b.rd_disc(r / 10).g, a.rd_disc(r).g, 1e-12);
    }
    EXPECT_NEAR(b.mean_free_path() * 10, a.mean_free_path(), 1e-12);
    EXPECT_NEAR(b.cutoff() * 10, a.cutoff(), 1e-9 * a.cutoff());
    EXPECT_EQ(a.total().r, a.rd_disc(kInfD).r);
    // entry factor: Fresnel transmittance times the incidence factor; exit factor 0 below the horizon
    EXPECT_NEAR(a.entry_factor(1.0).r, fresnel_transmittance(1.0, 1.3), 1e-12);
    EXPECT_EQ(a.exit_factor(-0.1).r, 0.0);
    m.eta = 2.5;
    EXPECT_THROW(ExactProfile(m, tables), std::invalid_argument);
    m.eta = 1.3;
    m.sigma_a.r = -1;
    EXPECT_THROW(ExactProfile(m, tables), std::invalid_argument);
}

TEST(ExactProfile, UniformlyLitPlaneRendersTotalTimesExitFactor) {
    // Through Subsurface (near field + octree) exactly as the renderer calls it: a uniformly lit
    // plane gives E_t total exit_factor wherever the point sits. 1 % at h 0.1 and 0.5 (measured
    // 0.48 and 0.97 %; 0.98 % before the distance bands' correction); at h = 2 mfp' (the blue
    // channel: alpha' 0.7) 1.5 %: the far field's point sum at that spacing of a profile that
    // falls by e^-5 across the window's ramp, times a distance weight that rises toward the
    // entry point (measured 0.97 % with the bands' means read as point values, 1.16 % with the
    // curve keeping each band's mean).
    auto tables = std::make_shared<ProfileTables>(small_tables());
    Medium m = Medium::from_reduced(Rgb(1.0, 0.9, 0.7), Rgb(0.01, 0.1, 0.3), 1.5);
    auto p = std::make_shared<ExactProfile>(m, tables);
    SubsurfaceSettings set;
    auto s = std::make_shared<const Subsurface>(m, set, FdrModel::JensenFit, p);
    EXPECT_EQ(&s->model(), p.get());
    const Vec3 n(0, 0, 1);
    for (double h : {0.1, 0.5, 2.0}) {
        std::vector<SurfacePoint> pts;
        const int N = int(std::ceil(60.0 / h));
        for (int i = -N; i < N; ++i)
            for (int j = -N; j < N; ++j) pts.push_back({Vec3((i + 0.5) * h, (j + 0.5) * h, 0), n, h * h, Rgb(1.0)});
        const PointCloud c(pts, h, s->near_reflectance(h));
        for (double dx : {0.0, 0.25 * h, 0.5 * h}) {
            const Rgb L = s->radiance(c, Vec3(dx, 0.1 * h, 0), n, n, Rgb(1.0));
            const Rgb want = p->total() * p->exit_factor(1.0);
            for (int k = 0; k < 3; ++k) EXPECT_NEAR(L[k] / want[k], 1.0, h < 1 ? 0.01 : 0.015) << "h " << h << " channel " << k;
        }
    }
    // the transmittance model of this finish is the profile's entry factor / pi
    const auto fm = finish_model_with_subsurface(nullptr, s);
    const FinishModel* tm = finish_model_get(fm->transmittance_handle());
    ASSERT_NE(tm, nullptr);
    const Vec3 wi = normalize(Vec3(0.6, 0, 0.8));
    EXPECT_NEAR(tm->brdf->f(n, wi).g * kPi, p->entry_factor(0.8).g, 1e-12);
}

// The exit weight's mean against Rd 2 pi r: |mean - 1| at most this.
constexpr double kExitWeightMean = 2e-3;

TEST(ExactProfile, ExitWeightAveragesOneAgainstRdAndFollowsTheBands) {
    // RadialProfile::exit_weight: for every view, the weight's mean against Rd 2 pi r is 1 (a
    // uniformly lit half-space renders as without it), checked by a quadrature of its own
    // (midpoints, 4000 per octave of r); at each node it is the channel's band ratio, scaled
    // per band cosine (the two cosines' scales differ by well under 1e-4).
    auto tables = std::make_shared<ProfileTables>(small_tables());
    const Medium m = Medium::from_reduced(Rgb(1.0, 0.9, 0.7), Rgb(0.01, 0.1, 0.3), 1.5);
    const ExactProfile p(m, tables);
    for (double cos_o : {1.0, 0.6, 0.15}) {
        RadialWeight w;
        ASSERT_TRUE(p.exit_weight(cos_o, &w));
        ASSERT_GE(w.nodes, 8);
        for (int c = 0; c < 3; ++c) {
            double sum = 0;
            const double st = p.sigma_t_prime(c);
            for (double r = 1e-6 / st; r < 1e4 / st; r *= std::exp(std::log(2.0) / 4000)) {
                const double dr = r * (std::exp(std::log(2.0) / 4000) - 1), mid = r + 0.5 * dr;
                sum += p.rd(mid)[c] * w.at(c, mid) * 2 * kPi * mid * dr;
            }
            std::printf("cos %.2f channel %d: mean of the weight against Rd %.6f\n", cos_o, c, sum / p.total()[c]);
            EXPECT_NEAR(sum / p.total()[c], 1.0, kExitWeightMean) << "cos " << cos_o << " channel " << c;
            // the node values are the band ratios times one scale
            const ChannelProfile& ch = *p.channel(c);
            const double mi = std::sqrt(1 - (1 - cos_o * cos_o) / (1.5 * 1.5));
            int j = 0;
            while (j + 2 < ch.exit_band_nodes() && mi > ch.exit_band_cosine(j + 1)) ++j;
            const double t = std::clamp((mi - ch.exit_band_cosine(j)) / (ch.exit_band_cosine(j + 1) - ch.exit_band_cosine(j)), 0.0, 1.0);
            auto ratio = [&](int i) {
                const double rho = RadialWeight::node_x(i) * p.mean_free_path() * st;
                return ch.exit_band_ratio(rho, j) * (1 - t) + ch.exit_band_ratio(rho, j + 1) * t;
            };
            const double k = w.w[3][c] / ratio(3);
            for (int i = 0; i < w.nodes; i += 5) EXPECT_NEAR(w.w[i][c], k * ratio(i), 3e-4 * k) << i;
            EXPECT_NEAR(w.at(c, 0.0), w.w[0][c], 1e-12);
        }
    }
    // the dipole has none
    RadialWeight w;
    EXPECT_FALSE(DipoleRadialProfile(Dipole(m, FdrModel::JensenFit)).exit_weight(1.0, &w));
}

TEST(DipoleRadialProfile, KeepsTheDipoleExactly) {
    const Medium m = Medium::from_reduced(Rgb(2.19, 2.62, 3.0), Rgb(0.0021, 0.0041, 0.0071), 1.5);
    const Dipole d(m);
    const DipoleRadialProfile p(d);
    for (double r : {0.0, 0.1, 1.0, 10.0}) EXPECT_EQ(p.rd(r).g, d.rd(r).g);
    EXPECT_EQ(p.total().b, d.rd_total().b);
    EXPECT_EQ(p.exit_factor(0.7).r, fresnel_transmittance(0.7, 1.5));
    EXPECT_TRUE(p.includes_single_scattering());
    EXPECT_EQ(p.mean_free_path(), d.channel(2).zr);  // the smallest: blue scatters most
}

TEST(ProfileTables, InversionFindsTheReducedAlbedoOfATotal) {
    // alpha_prime_for_total inverts total(alpha') = tables + single: a round trip to 1e-8, and the
    // ends (0 for no reflection, 1 beyond the largest reachable total).
    const ProfileTables& t = small_tables();
    auto single = [](double ap) { return 0.15 * ap; };  // any increasing single-scattering term
    for (double g : {0.0, 0.5})
        for (double ap : {0.05, 0.4, 0.8, 0.99, 0.9999}) {
            const double total = ChannelProfile(t, ap, g, 1.2).total() + single(ap);
            EXPECT_NEAR(alpha_prime_for_total(t, total, g, 1.2, single), ap, 1e-8) << g << " " << ap;
        }
    EXPECT_EQ(alpha_prime_for_total(t, 0.0, 0.0, 1.0, single), 0.0);
    EXPECT_EQ(alpha_prime_for_total(t, 2.0, 0.0, 1.0, single), 1.0);
}

// ---------------------------------------------------------------- thin geometry: exact slab tables

namespace {

// Slab tables g 0, eta {1, 1.5}, thickness {0.5, 1, 2} mfp, few photons (well under a second).
std::shared_ptr<const ProfileTables> small_slab_tables() {
    static std::shared_ptr<const ProfileTables> t = [] {
        ProfileBuildSettings s;
        s.g = {0.0};
        s.eta = {1.0, 1.5};
        s.thickness = {0.5, 1.0, 2.0};
        s.photons = 3000;
        s.short_photons = 10000;
        s.threads = 2;
        return std::shared_ptr<const ProfileTables>(build_profile_tables(s));
    }();
    return t;
}

// Forward-scattering slabs as make brdf-data's second slab file is laid out: g from 0 up.
std::shared_ptr<const ProfileTables> small_forward_slab_tables() {
    static std::shared_ptr<const ProfileTables> t = [] {
        ProfileBuildSettings s;
        s.g = {0.0, 0.5};
        s.eta = {1.0, 1.3};
        s.thickness = {0.5, 1.0, 2.0};
        s.photons = 2000;
        s.short_photons = 5000;
        s.angle_nodes = 16;
        s.threads = 2;
        return std::shared_ptr<const ProfileTables>(build_profile_tables(s));
    }();
    return t;
}

std::shared_ptr<const ProfileTables> small_tables_ptr() {
    return std::shared_ptr<const ProfileTables>(std::shared_ptr<const ProfileTables>(), &small_tables());
}

// The automatic levels stop where the near field (wrong by up to half of it at a shadow edge)
// holds at most edge_fraction of what each channel shows: Rd plus the single scattering the
// finish adds (Subsurface::refinement_levels). Ketchup's green and blue (alpha' 0.067, 0.020)
// are nearly all single scattering; counted by Rd alone they drove its clouds down to
// spacings no pixel needed.
TEST(ExactProfile, RefinementLevelsCountTheSingleScatteringThePixelShows) {
    const Medium ketchup = media_preset("Ketchup");  // mm
    auto model = std::make_shared<const ExactProfile>(ketchup, small_tables_ptr());
    SubsurfaceSettings on, off;
    off.single_scatter = false;
    const Subsurface with(ketchup, on, FdrModel::JensenFit, model), without(ketchup, off, FdrModel::JensenFit, model);
    const double h0 = with.sample_spacing(40.0);
    const int k_with = with.refinement_levels(h0), k_without = without.refinement_levels(h0);
    const Rgb total = with.profile().total(), shown = total + with.single_scatter_shown();
    auto fits = [&](int k, const Rgb& of) {
        const Rgb near = with.profile().near_reflectance(std::ldexp(h0, -k));
        for (int c = 0; c < 3; ++c)
            if (near[c] > on.edge_fraction * of[c]) return false;
        return true;
    };
    // Each rule stops at the first level that meets it.
    EXPECT_TRUE(fits(k_with, shown));
    EXPECT_TRUE(k_with == 0 || !fits(k_with - 1, shown));
    EXPECT_TRUE(fits(k_without, total));
    EXPECT_TRUE(k_without == 0 || !fits(k_without - 1, total));
    // Blue's single scattering is ~100x its Rd: red (alpha' 0.75) decides now, levels sooner.
    EXPECT_GT(with.single_scatter_shown()[2], 30 * total[2]);
    EXPECT_LE(k_with + 3, k_without) << k_with << " " << k_without;
}

}  // namespace

// Which media the slab tables cover, and why not (the statistics' note).
TEST(ExactSlabs, CoverageAndItsReason) {
    const Medium m = Medium::from_reduced(Rgb(1.0, 2.0, 4.0), Rgb(0.05, 0.1, 0.4), 1.2, 1.0);
    ExactProfile covered(m, small_tables_ptr(), small_slab_tables());
    EXPECT_NE(covered.slab_tables(), nullptr);
    EXPECT_EQ(covered.slab_gap(), "");
    ExactProfile none(m, small_tables_ptr());
    EXPECT_EQ(none.slab_tables(), nullptr);
    EXPECT_EQ(none.slab_gap(), "subsurface_slabs.ssp: no slab tables\n  subsurface_slabs_forward.ssp: no slab tables");
    Medium aniso = m;
    aniso.sigma_s = Rgb(2.0, 4.0, 8.0);
    aniso.g = Rgb(0.5);
    ExactProfile outside(aniso, small_tables_ptr(), small_slab_tables());
    EXPECT_EQ(outside.slab_tables(), nullptr);
    EXPECT_NE(outside.slab_gap().find("subsurface_slabs.ssp: g = 0.5 is outside the tables' range [0, 0]"), std::string::npos)
        << outside.slab_gap();
    ExactProfile half_only(m, small_tables_ptr(), small_tables_ptr());  // semi-infinite tables as slabs
    EXPECT_EQ(half_only.slab_tables(), nullptr);
    EXPECT_NE(half_only.slab_gap().find("subsurface_slabs.ssp: the slab tables have no transmission face"), std::string::npos);
    // The forward-scattering file covers what the isotropic one does not; the isotropic one is
    // taken wherever it covers (more iors and photons).
    const auto forward = small_forward_slab_tables();
    ExactProfile fwd(aniso, small_tables_ptr(), small_slab_tables(), forward);
    EXPECT_EQ(fwd.slab_tables(), forward.get());
    EXPECT_EQ(fwd.slab_gap(), "");
    ExactProfile iso(m, small_tables_ptr(), small_slab_tables(), forward);
    EXPECT_EQ(iso.slab_tables(), small_slab_tables().get());
    Medium dense = aniso;  // ior 1.45: g 0.5 outside the isotropic file, the ior outside the forward one
    dense.eta = 1.45;
    ExactProfile neither(dense, small_tables_ptr(), small_slab_tables(), forward);
    EXPECT_EQ(neither.slab_tables(), nullptr);
    EXPECT_NE(neither.slab_gap().find("subsurface_slabs_forward.ssp: ior = 1.45 is outside the tables' range [1, 1.3]"),
              std::string::npos)
        << neither.slab_gap();
    EXPECT_NE(neither.slab_note().find("g = 0.5 is outside"), std::string::npos) << neither.slab_note();
}

// The forward file's thickness axis is in mean free paths, d' / (1 - alpha g) at each g node: a
// channel thicker than its own g's slabs reach takes the largest g node below it that holds it
// (similarity), never the multipole beside the tables (its step into the slab cache's
// interpolation read -12 to -18 % seen through Marble at g 0.9, 3-4 mfp').
TEST(ExactSlabs, AForwardChannelThickerThanItsGHoldsTakesASmallerG) {
    // alpha' 0.9, g 0.5: the node's albedo 0.947, so 1 mfp' is 1.9 mfp there; the tables end at
    // 2 mfp: d' = 1.5 lies beyond g 0.5's slabs, inside g 0's.
    const double g = 0.5, sp = 1.0, sa = 1.0 / 9.0;
    Medium m = Medium::from_reduced(Rgb(sp), Rgb(sa), 1.0, 1.0);
    m.sigma_s = Rgb(sp / (1.0 - g));
    m.g = Rgb(g);
    const auto forward = small_forward_slab_tables();
    const ExactProfile model(m, small_tables_ptr(), small_slab_tables(), forward);
    ASSERT_EQ(model.slab_tables(), forward.get());
    const Dipole dipole(m);
    const double st = model.sigma_t_prime(0), alpha_prime = model.channel(0)->alpha_prime();
    EXPECT_THROW(ChannelProfile(*forward, alpha_prime, g, 1.0, 1.5, 0), std::invalid_argument);
    int tabulated = -1;
    const SlabProfiles thick = make_exact_slab_profiles(model, dipole, 1.5 / st, Rgb(1.0), &tabulated);
    EXPECT_EQ(tabulated, 3);
    const ChannelProfile r(*forward, alpha_prime, 0.0, 1.0, 1.5, 0), t(*forward, alpha_prime, 0.0, 1.0, 1.5, 1);
    // Both faces: that g's, times the ratio of the channel's own g to the node's at the thickest
    // slab its own g holds, d* = 2 mfp x (1 - alpha g): continuous there.
    const double alpha = alpha_prime / (1.0 - g + alpha_prime * g), d_star = 2.0 * (1.0 - alpha * g);
    const ChannelProfile r_own(*forward, alpha_prime, g, 1.0, d_star * 0.9999, 0), t_own(*forward, alpha_prime, g, 1.0, d_star * 0.9999, 1);
    const ChannelProfile r_node(*forward, alpha_prime, 0.0, 1.0, d_star, 0), t_node(*forward, alpha_prime, 0.0, 1.0, d_star, 1);
    const double r_ratio = r_own.total() / r_node.total();
    const double t_ratio = (t_own.total() + t_own.single()) / (t_node.total() + t_node.single());
    EXPECT_GT(std::fabs(r_ratio - 1.0), 0.01);
    EXPECT_NEAR(thick.R_total[0] / (r.total() * r_ratio), 1.0, 2e-3);
    EXPECT_NEAR(thick.same->total()[0] / thick.R_total[0], 1.0, 0.005);
    EXPECT_NEAR(thick.T_total[0] / ((t.total() + t.single()) * t_ratio), 1.0, 2e-3);
    // ... continuous across d*: just under it the channel's own g, just over it the node, scaled
    const SlabProfiles under = make_exact_slab_profiles(model, dipole, d_star * 0.999 / st, Rgb(1.0));
    const SlabProfiles over = make_exact_slab_profiles(model, dipole, d_star * 1.001 / st, Rgb(1.0));
    EXPECT_NEAR(over.R_total[0] / under.R_total[0], 1.0, 0.003);
    EXPECT_NEAR(over.T_total[0] / under.T_total[0], 1.0, 0.005);
    // ... and so are the faces' exit distributions (its own g's at d*, not the node's)
    for (double cos_o : {1.0, 0.6, 0.3}) {
        Rgb same_under, through_under, same_over, through_over;
        under.exit(cos_o, &same_under, &through_under);
        over.exit(cos_o, &same_over, &through_over);
        EXPECT_NEAR(same_over[0] / same_under[0], 1.0, 0.003) << cos_o;
        EXPECT_NEAR(through_over[0] / through_under[0], 1.0, 0.003) << cos_o;
    }
    // Where its own g holds it, its own g.
    const SlabProfiles thin = make_exact_slab_profiles(model, dipole, 0.8 / st, Rgb(1.0), &tabulated);
    EXPECT_EQ(tabulated, 3);
    EXPECT_DOUBLE_EQ(thin.R_total[0], ChannelProfile(*forward, alpha_prime, g, 1.0, 0.8, 0).total());
    // Too thin for any g: the multipole.
    make_exact_slab_profiles(model, dipole, 0.1 / st, Rgb(1.0), &tabulated);
    EXPECT_EQ(tabulated, 0);
}

// A g or ior within a float's precision of a node is that node (POV hands them over as floats:
// g 0.9 arrived as 0.899999976 and took the 4-node stencil, whose g 0.95 node's slabs are twice
// as many mean free paths thick).
TEST(ExactSlabs, ANodeReadAsAFloatIsTheNode) {
    const auto forward = small_forward_slab_tables();
    const double at = ChannelProfile(*forward, 0.9, 0.5, 1.0, 0.9, 1).total();
    EXPECT_EQ(ChannelProfile(*forward, 0.9, double(0.5f - 3e-8f), 1.0, 0.9, 1).total(), at);
    EXPECT_EQ(ChannelProfile(*forward, 0.9, 0.5, double(1.3f), 0.9, 1).total(),
              ChannelProfile(*forward, 0.9, 0.5, 1.3, 0.9, 1).total());
    EXPECT_NE(ChannelProfile(*forward, 0.9, 0.49, 1.0, 0.9, 1).total(), at);
}

// Light through a slab a few diffusion lengths thick falls as e^(-kappa d), kappa the
// transport's decay rate: ln T is linear in d there and concave in ln d, so read linearly in ln d
// between the thickness nodes it came out low (by about 1.5 % x kappa d at the forward file's
// sqrt(2) spacing: Skin1's blue through 7.7 mfp' at g 0.9 read -8.8 % against the Monte Carlo).
// Tables whose transmitted totals are exactly c_k e^(-kappa_k d) at their nodes give that total
// between them; with linear weights in ln d this read -6 .. -8 % at the middle of the 1 .. 2 mfp
// interval. The reflected face (no such decay) is read as before.
constexpr double kSlabDecayTol = 1e-9;  // relative: the reading is exact for such records
// The exit factor between thickness nodes against tables that hold it at every node.
constexpr double kExitCurvatureTol = 1e-9;

TEST(ExactSlabs, TransmissionBetweenThicknessNodesFallsAsTheTransportDecays) {
    ProfileTables t = *small_slab_tables();  // g 0, eta {1, 1.5}, nodes 0.5, 1, 2 mfp
    ASSERT_EQ(t.settings.thickness.size(), 3u);
    ASSERT_EQ(t.faces, 2);
    const int ne = int(t.settings.eta.size());
    std::vector<double> kappa(std::size_t(t.settings.albedos));
    for (int k = 0; k < t.settings.albedos; ++k) kappa[std::size_t(k)] = transport_decay_rate(t.albedo(k), 0.0);
    for (int ie = 0; ie < ne; ++ie)
        for (int id = 0; id < 3; ++id)
            for (int k = 0; k < t.settings.albedos; ++k) {
                const std::size_t i = ((std::size_t(ie) * 3 + id) * 2 + 1) * t.settings.albedos + k;
                t.records.at(i).multi = 0.3 * t.albedo(k) * t.albedo(k) * std::exp(-kappa[std::size_t(k)] * t.settings.thickness[std::size_t(id)]);
            }
    double worst = 0;
    for (int k : {8, 20, 30}) {  // albedo nodes 0.87, 0.9955, 0.99975
        const double a = t.albedo(k), kap = kappa[std::size_t(k)];
        for (double d : {0.6, 1.2, std::sqrt(2.0), 1.8}) {
            const double want = 0.3 * a * a * std::exp(-kap * d);
            for (double eta : {1.0, 1.5}) {
                const double got = ChannelProfile(t, a, 0.0, eta, d, 1).total();
                worst = std::max(worst, std::fabs(got / want - 1.0));
                EXPECT_NEAR(got / want, 1.0, kSlabDecayTol) << "alpha " << a << " d " << d << " eta " << eta;
            }
        }
    }
    std::printf("worst relative error between the nodes: %.2g\n", worst);
    // ... and the old reading's error was real where kappa d is large: node 8's kappa is 0.6.
    EXPECT_GT(kappa[8], 0.5);
    // The reflected face keeps the plain reading (linear in ln d).
    const ChannelProfile r1(t, t.albedo(8), 0.0, 1.0, 1.0, 0), r2(t, t.albedo(8), 0.0, 1.0, 2.0, 0);
    const double r_mid = ChannelProfile(t, t.albedo(8), 0.0, 1.0, std::sqrt(2.0), 0).total();
    EXPECT_NEAR(r_mid, std::sqrt(r1.total() * r2.total()), 1e-12 * r_mid);
}

// The transmitted exit distribution between thickness nodes follows their curvature in ln d
// (cubic Lagrange over four nodes; these tables have three, so quadratic): records whose inside-radiance samples
// are quadratic in ln d read, between the nodes, as tables whose every node holds the samples at
// that thickness. The linear reading (before) is off by percents there: a forward lobe seen
// through a sheet falls faster than exponentially with its thickness (Skin1's red at g 0.9
// through 9.6 mfp read 2.007 at the normal against 1.910, and rendered +5.2 %).
TEST(ExactSlabs, ExitDistributionBetweenThicknessNodesFollowsTheirCurvature) {
    const ProfileTables base = *small_slab_tables();  // g 0, eta {1, 1.5}, nodes 0.5, 1, 2 mfp
    const int ne = int(base.settings.eta.size()), nd = 3, J = base.settings.angle_nodes, K = base.settings.albedos;
    ASSERT_EQ(int(base.settings.thickness.size()), nd);
    const std::vector<double>& dn = base.settings.thickness;
    auto sample = [&](int j, double ln_d) {
        const double x = double(j) / (J - 1);
        return 0.6 + 0.3 * x + (0.8 - 0.9 * ln_d + 1.2 * ln_d * ln_d) * x * x * x * x;
    };
    // tables whose transmitted records hold samples(j, node) at every albedo and eta
    auto with_samples = [&](const std::function<double(int, int)>& samples) {
        ProfileTables t = base;
        for (int ie = 0; ie < ne; ++ie)
            for (int id = 0; id < nd; ++id)
                for (int k = 0; k < K; ++k) {
                    FaceRecord& r = t.records.at(((std::size_t(ie) * nd + id) * 2 + 1) * K + k);
                    for (int j = 0; j < J; ++j) r.angle[std::size_t(j)] = samples(j, id);
                }
        return t;
    };
    const ProfileTables curved = with_samples([&](int j, int id) { return sample(j, std::log(dn[std::size_t(id)])); });
    double worst = 0, linear_least = 1;
    for (double d : {0.7, 1.3, 1.7}) {
        const ProfileTables flat = with_samples([&](int j, int) { return sample(j, std::log(d)); });
        // every node holding the two nodes about d mixed linearly in ln d (the reading before)
        const int i = d < 1.0 ? 0 : 1;
        const double f = std::log(d / dn[std::size_t(i)]) / std::log(dn[std::size_t(i) + 1] / dn[std::size_t(i)]);
        const ProfileTables linear = with_samples([&](int j, int) {
            return (1 - f) * sample(j, std::log(dn[std::size_t(i)])) + f * sample(j, std::log(dn[std::size_t(i) + 1]));
        });
        for (int k : {8, 30})
            for (double eta : {1.0, 1.5}) {
                const double a = base.albedo(k);
                const ChannelProfile got(curved, a, 0.0, eta, d, 1), want(flat, a, 0.0, eta, d, 1), old(linear, a, 0.0, eta, d, 1);
                double linear_worst = 0;
                for (double c : {1.0, 0.8, 0.5, 0.2}) {
                    const double v = got.exit_factor(c), w = want.exit_factor(c);
                    worst = std::max(worst, std::fabs(v / w - 1.0));
                    EXPECT_NEAR(v / w, 1.0, kExitCurvatureTol) << "d " << d << " cos " << c << " eta " << eta;
                    linear_worst = std::max(linear_worst, std::fabs(old.exit_factor(c) / w - 1.0));
                }
                linear_least = std::min(linear_least, linear_worst);
            }
    }
    std::printf("worst relative error of the exit factor between the nodes: %.2g (the linear reading: at least %.2g)\n", worst,
                linear_least);
    EXPECT_GT(linear_least, 0.01);  // the test tells the two readings apart
}

// Per channel: R and T from the tables where the thickness (transport mfp) lies in their nodes,
// the scaled multipole elsewhere. The profiles integrate (RdProfile's own quadrature of the
// multipole's T shape, independent of the tables' totals) to the totals within 0.5 %.
TEST(ExactSlabs, ProfilesCarryTheTablesTotals) {
    // sigma_t' = 1.05, 2.1, 4.4 per unit: d = 0.6 units is 0.63, 1.26, 2.64 mfp: the blue
    // channel is beyond the tables' last node (2 mfp) and takes the multipole.
    const Medium m = Medium::from_reduced(Rgb(1.0, 2.0, 4.0), Rgb(0.05, 0.1, 0.4), 1.2, 1.0);
    const ExactProfile model(m, small_tables_ptr(), small_slab_tables());
    const Dipole dipole(m);
    const Rgb scale(0.9, 0.8, 0.7);
    const double d = 0.6;
    int tabulated = -1;
    const SlabProfiles p = make_exact_slab_profiles(model, dipole, d, scale, &tabulated);
    EXPECT_EQ(tabulated, 2);
    const SlabProfiles multipole = make_slab_profiles(dipole, d, scale);
    for (int c = 0; c < 2; ++c) {
        const double st = model.sigma_t_prime(c);
        const ChannelProfile r(*small_slab_tables(), model.channel(c)->alpha_prime(), 0.0, 1.2, d * st, 0);
        const ChannelProfile t(*small_slab_tables(), model.channel(c)->alpha_prime(), 0.0, 1.2, d * st, 1);
        EXPECT_DOUBLE_EQ(p.R_total[c], r.total()) << c;
        EXPECT_NEAR(p.T_total[c], t.total() + t.single(), 1e-12) << c;
        EXPECT_GT(t.single(), 0.0) << c;
        EXPECT_NEAR(p.same->total()[c] / p.R_total[c], 1.0, 0.005) << c;
        EXPECT_NEAR(p.transmit->total()[c] / p.T_total[c], 1.0, 0.005) << c;
        EXPECT_NE(p.R_total[c], multipole.R_total[c]) << c;
    }
    EXPECT_DOUBLE_EQ(p.R_total[2], multipole.R_total[2]);
    EXPECT_DOUBLE_EQ(p.T_total[2], multipole.T_total[2]);
    // Without slab tables: the scaled multipole, every channel.
    const ExactProfile bare(m, small_tables_ptr());
    const SlabProfiles q = make_exact_slab_profiles(bare, dipole, d, scale, &tabulated);
    EXPECT_EQ(tabulated, 0);
    for (int c = 0; c < 3; ++c) EXPECT_DOUBLE_EQ(q.R_total[c], multipole.R_total[c]);
}
