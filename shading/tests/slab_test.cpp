// Thin geometry: the multipole slab profiles (slab.h) and their use by Subsurface.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <vector>

#include "shading/subsurface/slab.h"
#include "shading/subsurface/subsurface.h"

using namespace shading;

namespace {

// A medium of reduced albedo ap in transport units (sigma_t' = 1 per scene unit), index eta.
Medium unit_medium(double ap, double eta) {
    return Medium::from_reduced(Rgb(ap), Rgb(1.0 - ap), eta, 1.0);
}

// The independent reference for the totals: the laterally integrated diffusion equation
// D phi'' - sigma_a phi = -P delta(z - z0) on [-zb, d + zb] with phi = 0 at both ends, solved by
// second-order finite differences (n cells, the source spread over the cell that holds z0
// linearly, Thomas algorithm); the fluxes leaving through z = 0 and z = d are D |phi'| there,
// from the one-sided second-order differences at the nodes nearest to 0 and d.
struct OneD {
    double R, T;
};
OneD diffusion_1d(double sigma_a, double sigma_t_prime, double zb, double z0, double d, double P, int n) {
    const double D = 1.0 / (3.0 * sigma_t_prime), a = -zb, b = d + zb, h = (b - a) / n;
    // nodes z_i = a + i h, i = 0..n; unknowns 1..n-1
    std::vector<double> lo(n + 1, 0), di(n + 1, 0), up(n + 1, 0), rhs(n + 1, 0), phi(n + 1, 0);
    for (int i = 1; i < n; ++i) {
        lo[i] = -D / (h * h);
        up[i] = -D / (h * h);
        di[i] = 2 * D / (h * h) + sigma_a;
    }
    // delta source: weights (1 - t, t) to the two nodes around z0, divided by h
    const double u = (z0 - a) / h;
    const int k = int(std::floor(u));
    const double t = u - k;
    rhs[k] += P * (1 - t) / h;
    rhs[k + 1] += P * t / h;
    for (int i = 2; i < n; ++i) {
        const double m = lo[i] / di[i - 1];
        di[i] -= m * up[i - 1];
        rhs[i] -= m * rhs[i - 1];
    }
    phi[n - 1] = rhs[n - 1] / di[n - 1];
    for (int i = n - 2; i >= 1; --i) phi[i] = (rhs[i] - up[i] * phi[i + 1]) / di[i];
    // phi'(z) by the derivative of the quadratic through the three nodes around z
    auto slope = [&](double z) {
        int j = int(std::round((z - a) / h));
        j = std::max(1, std::min(n - 1, j));
        const double s = (z - (a + j * h)) / h;
        return ((phi[j + 1] - phi[j - 1]) / 2 + s * (phi[j + 1] - 2 * phi[j] + phi[j - 1])) / h;
    };
    return {D * slope(0.0), -D * slope(d)};
}

}  // namespace

// Donner & Jensen's image sums, integrated over the plane numerically (RdProfile's quadrature),
// and the library's closed-form totals, against the finite-difference solution of the 1-D
// problem: tolerance 0.3 % of the semi-infinite total (stated before measuring; the FD error at
// 20000 cells is ~1e-5).
TEST(SlabProfile, TotalsMatchTheOneDimensionalDiffusionSolution) {
    double worst_closed = 0, worst_profile = 0;
    for (double ap : {0.3, 0.9, 0.99, 1.0})
        for (double eta : {1.0, 1.33, 1.5})
            for (double d : {0.25, 1.0, 4.0, 16.0}) {
                const Dipole dip(unit_medium(ap, eta));
                const DipoleChannel& ch = dip.channel(0);
                const SlabChannel s = SlabChannel::make(ch, d);
                const OneD ref = diffusion_1d(ch.sigma_a, ch.sigma_t_prime, s.zb, s.z0, d, s.power, 20000);
                const SlabProfiles p = make_slab_profiles(dip, d);
                const double scale = ch.rd_total();
                const double e[4] = {s.R_total() - ref.R, s.T_total() - ref.T, p.same->total().r - ref.R,
                                     p.transmit->total().r - ref.T};
                for (int k = 0; k < 4; ++k) {
                    double& w = k < 2 ? worst_closed : worst_profile;
                    w = std::max(w, std::fabs(e[k]) / scale);
                    EXPECT_LT(std::fabs(e[k]), 3e-3 * scale) << "ap " << ap << " eta " << eta << " d " << d << " term " << k
                                                            << " ref R " << ref.R << " T " << ref.T;
                }
            }
    std::printf("slab totals vs 1-D diffusion: closed form %.2e, integrated profiles %.2e (of R_inf)\n", worst_closed,
                worst_profile);
}

// The image sum's tails as integrals against the plain sum of 200,000 pairs either side (the
// pairs' differences fall as |z|^-3 without absorption: its own truncation is ~1e-12 of R):
// within 1e-6 of the profile at r = 0 (stated before measuring), thin to thick, with and
// without absorption, near and far from the entry point.
constexpr double kImageTailTol = 1e-6;  // of the profile at r = 0 (docs/claims.md)
TEST(SlabProfile, ImageTailsMatchTheLongDirectSum) {
    auto term = [](double r, double z, double s) {
        const double q = std::sqrt(r * r + z * z);
        return z * (1.0 + s * q) * std::exp(-s * q) / (q * q * q);
    };
    double worst = 0;
    for (double ap : {0.3, 0.9, 0.99, 1.0})
        for (double eta : {1.0, 1.5})
            for (double d : {0.05, 0.25, 1.0, 4.0}) {
                const SlabChannel c = SlabChannel::make(Dipole(unit_medium(ap, eta)).channel(0), d);
                ASSERT_LE(c.pairs, 6);
                const double L = d + 2 * c.zb;
                for (int opposite = 0; opposite < 2; ++opposite) {
                    const double at0 = opposite ? c.T(0.0) : c.R(0.0);
                    for (double r : {0.0, 0.1, 1.0, 5.0, 20.0}) {
                        if (!(r < c.cutoff)) continue;
                        double sum = 0;
                        for (int i = -200000; i <= 200000; ++i) {
                            const double zr = 2.0 * i * L + c.z0, zv = 2.0 * i * L - c.z0 - 2.0 * c.zb;
                            sum += opposite ? term(r, d - zr, c.sigma_tr) - term(r, d - zv, c.sigma_tr)
                                            : term(r, zr, c.sigma_tr) - term(r, zv, c.sigma_tr);
                        }
                        const double direct = std::max(0.0, c.power / (4.0 * kPi) * sum);
                        const double got = opposite ? c.T(r) : c.R(r);
                        worst = std::max(worst, std::fabs(got - direct) / at0);
                        EXPECT_NEAR(got, direct, kImageTailTol * at0) << "ap " << ap << " eta " << eta << " d " << d << " r " << r
                                                             << (opposite ? " T" : " R");
                    }
                }
            }
    std::printf("image tails vs the 200,000-pair sum: worst %.2e of the profile at 0\n", worst);
}

// Literal numbers: without absorption the 1-D solution is linear, R = P b / L, T = P a / L.
TEST(SlabProfile, NonAbsorbingSlabSplitsItsPowerLinearly) {
    const Dipole dip(unit_medium(1.0, 1.0));  // A = 1: zb = 2/3, D = 1/3
    const SlabChannel s = SlabChannel::make(dip.channel(0), 1.0);
    const double z0 = 1.0 - 1.0 / std::expm1(1.0), P = -std::expm1(-1.0), L = 1.0 + 4.0 / 3.0, a = z0 + 2.0 / 3.0;
    EXPECT_NEAR(s.z0, z0, 1e-15);  // 0.418023...
    EXPECT_NEAR(s.power, 0.6321205588285577, 1e-15);
    EXPECT_NEAR(s.R_total(), P * (L - a) / L, 1e-12);
    EXPECT_NEAR(s.T_total(), P * a / L, 1e-12);
    EXPECT_NEAR(s.R_total() + s.T_total(), P, 1e-12);  // nothing absorbed
}

// Thick slabs are the half-space: the profile is Jensen's Rd to 1e-9, nothing is transmitted.
TEST(SlabProfile, ThickSlabIsTheDipole) {
    const Dipole dip(Medium::from_reduced(Rgb(2.19, 2.62, 3.00), Rgb(0.0021, 0.0041, 0.0071), 1.5, 1.0));  // marble, mm
    const double d = 2000.0;  // 4400 mean free paths, 230 diffusion lengths
    const SlabProfiles p = make_slab_profiles(dip, d);
    for (double r : {0.0, 0.05, 0.5, 5.0, 50.0}) {
        const Rgb a = p.same->exact(r), b = dip.rd(r);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(a[c], b[c], 1e-9 * b[c]) << r;
    }
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(p.R_total[c], dip.channel(c).rd_total(), 1e-12);
        EXPECT_LT(p.T_total[c], 1e-60);
    }
}

// The threshold: the totals within 0.5 % of the half-space at it, not 10 % below it.
TEST(SlabProfile, ThresholdIsWhereTheSlabBecomesTheHalfSpace) {
    for (double ap : {0.5, 0.99}) {
        const Dipole dip(unit_medium(ap, 1.3));
        const double t = slab_threshold(dip);
        auto err = [&](double d) {
            const SlabChannel s = SlabChannel::make(dip.channel(0), d);
            const double inf = dip.channel(0).rd_total();
            return (std::fabs(s.R_total() - inf) + s.T_total()) / inf;
        };
        EXPECT_LE(err(t), 0.005);
        EXPECT_GT(err(t / 1.1), 0.005);
        std::printf("alpha' %.2f eta 1.3: slab threshold %.2f transport mfp\n", ap, t);
    }
}

// R alone: reflect_threshold, where R is within 0.5 % of R_inf (not 10 % below it), well
// before the slab threshold at high albedo (T lingers), and never after it.
TEST(SlabProfile, ReflectThresholdIsWhereRAloneBecomesTheHalfSpaces) {
    for (double ap : {0.5, 0.99, 0.998}) {
        const Dipole dip(unit_medium(ap, 1.3));
        const double t = reflect_threshold(dip);
        auto err = [&](double d) {
            const double inf = dip.channel(0).rd_total();
            return std::fabs(SlabChannel::make(dip.channel(0), d).R_total() - inf) / inf;
        };
        EXPECT_LE(err(t), 0.005);
        EXPECT_GT(err(t / 1.1), 0.005);
        EXPECT_LE(t, slab_threshold(dip));
        if (ap > 0.99) {
            EXPECT_LT(t, 0.7 * slab_threshold(dip));
        }
        std::printf("alpha' %.3f eta 1.3: reflect threshold %.2f, slab threshold %.2f transport mfp\n", ap, t,
                    slab_threshold(dip));
    }
}

// ---------------------------------------------------------------- a sheet in a Subsurface

namespace {

// The box [-L, L]^2 x [0, d]: crossings of axis lines, its thickness along -n, irradiance E(n).
class SheetSampler : public SurfaceSampler {
public:
    SheetSampler(double L, double d, std::function<Rgb(const Vec3&, const Vec3&)> e) : L_(L), d_(d), e_(std::move(e)) {}
    bool bounds(Vec3* lo, Vec3* hi) override {
        *lo = Vec3(-L_, -L_, 0);
        *hi = Vec3(L_, L_, d_);
        return true;
    }
    void line_hits(int axis, const Vec3& o, std::vector<Hit>* hits) override {
        const double lo[3] = {-L_, -L_, 0}, hi[3] = {L_, L_, d_}, oc[3] = {o.x, o.y, o.z};
        for (int k = 0; k < 3; ++k)
            if (k != axis && !(oc[k] > lo[k] && oc[k] < hi[k])) return;
        const Vec3 dir(axis == 0, axis == 1, axis == 2);
        hits->push_back({lo[axis] - oc[axis], o + dir * (lo[axis] - oc[axis]), dir * -1.0, Vec3()});
        hits->push_back({hi[axis] - oc[axis], o + dir * (hi[axis] - oc[axis]), dir, Vec3()});
    }
    Rgb irradiance(const Vec3& p, const Vec3& n) override { return e_(p, n); }
    std::string describe() override { return "box"; }
    double thickness(const Vec3&, const Vec3& n) override {
        ++thickness_calls;
        if (std::fabs(n.z) > 0.5) return d_;
        return 2 * L_;
    }
    int thickness_calls = 0;

private:
    double L_, d_;
    std::function<Rgb(const Vec3&, const Vec3&)> e_;
};

}  // namespace

// A wide sheet one mean free path thick (marble, mm), lit with E_t = 1 on its back face: the
// front centre's exitance is T_total(d); lit on the front: R_total(d). Tolerance 1.5 % (the
// sample quadrature of a profile a few spacings wide; stated before measuring).
TEST(SlabSubsurface, SheetTransmitsAndReflectsTheSlabTotals) {
    const Medium m = Medium::from_reduced(Rgb(2.19, 2.62, 3.00), Rgb(0.0021, 0.0041, 0.0071), 1.5, 1.0);
    Subsurface s(m, SubsurfaceSettings{});
    const double d = s.mean_free_path();
    ASSERT_LT(d, s.slab_threshold());
    const Vec3 top(0.1, -0.05, d), up(0, 0, 1);
    for (int back = 0; back < 2; ++back) {
        SheetSampler sampler(25.0, d, [back](const Vec3&, const Vec3& n) { return Rgb(back ? (n.z < -0.5) : (n.z > 0.5)); });
        int key[2];
        const PointCloud& c = s.cloud(&key[back], sampler);
        EXPECT_GT(sampler.thickness_calls, 0);
        EXPECT_NEAR(c.thinnest(), d, 1e-12);
        EXPECT_TRUE(s.wants_thickness(c));
        const Rgb here(back ? 0.0 : 1.0);
        const Rgb l = s.radiance(c, top, up, up, here, d);
        const double ft = fresnel_transmittance(1.0, m.eta);
        const SlabProfiles& p = s.slab(d);  // the nearest thickness node (for the hierarchy check)
        for (int k = 0; k < 3; ++k) {
            // the closed-form totals at d itself: the lookup interpolates between thickness nodes
            const SlabChannel exact = SlabChannel::make(s.dipole().channel(k), d);
            const double want = back ? exact.T_total() : exact.R_total();
            EXPECT_NEAR(l[k] / ft, want, 0.015 * want) << (back ? "back" : "front") << " channel " << k;
            std::printf("sheet d = 1 mfp lit on the %s, channel %d: M %.5f, slab total %.5f (%+.2f %%)\n",
                        back ? "back" : "front", k, l[k] / ft, want, 100 * (l[k] / ft / want - 1));
        }
        // The hierarchy against the exact sum over every point.
        const int level = c.lookup_level(top);
        const double h = c.level_spacing(level);
        const Rgb no = p.transmit->near_reflectance(h);
        const Rgb fast = c.far_exitance_sided(*p.same, *p.transmit, top, up, p.d, 2 * h, h, s.settings().max_angle, no);
        const Rgb exact = c.far_exitance_sided_exact(*p.same, *p.transmit, top, up, p.d, 2 * h, h, no);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(fast[k], exact[k], 0.01 * exact[k] + 1e-12);
    }
}

// A back-lit slab several diffusion lengths thick (Jensen's Skin1, mm; T falls as e^{-k d},
// k d up to 26 in blue), at thicknesses between the cache's nodes: the radiance on the dark
// face is the slab's transmittance at the point's own thickness, within 3 % (stated before
// measuring: the geometric interpolation over nodes 9 % apart, and the sum's quadrature).
// Before: the far face was placed at the lower node's thickness, so every point of it sat
// sqrt(d^2 - d_node^2) off the normal, past T's peak (-7 / -12 / -23 % at 10.4 mm), and T
// was interpolated linearly (+12 % in blue at 12 mm).
constexpr double kThickSlabTransmission = 0.03;  // docs/claims.md
TEST(SlabSubsurface, ThickBackLitSlabTransmitsItsOwnThicknessesLight) {
    const Medium m = Medium::from_reduced(Rgb(0.74, 0.88, 1.01), Rgb(0.032, 0.17, 0.48), 1.0, 1.0);
    Subsurface s(m, SubsurfaceSettings{});
    const Vec3 up(0, 0, 1);
    int key[4];
    int k = 0;
    for (double d : {5.9, 10.4, 12.0, 15.9}) {
        ASSERT_LT(d, s.slab_threshold());
        SheetSampler sampler(120.0, d, [](const Vec3&, const Vec3& n) { return Rgb(n.z < -0.5); });
        const PointCloud& c = s.cloud(&key[k++], sampler);
        const Rgb l = s.radiance(c, Vec3(0.1, -0.05, d), up, up, Rgb(0.0), d);
        for (int ch = 0; ch < 3; ++ch) {
            const double want = SlabChannel::make(s.dipole().channel(ch), d).T_total();
            std::printf("back-lit Skin1 slab %.1f mm, channel %d: M %.4g, slab T %.4g (%+.2f %%)\n", d, ch, l[ch], want,
                        100 * (l[ch] / want - 1));
            EXPECT_NEAR(l[ch] / want, 1.0, kThickSlabTransmission) << d << " mm, channel " << ch;
        }
    }
}

// Past the slab threshold a slab still passes light to its other face, up to the transmit
// threshold (T_total below 1e-4 of R_inf in every channel; between 1.1x and 3x the slab
// threshold for Skin1). Back-lit, the dark face's exitance is the slab's transmittance there,
// within kThickSlabTransmission (it was the half-space's: none of it); lit on its own face, the
// lookup is the half-space's, bit for bit (the far face is dark).
TEST(SlabSubsurface, PastTheSlabThresholdABackLitFaceStillTransmits) {
    const Medium m = Medium::from_reduced(Rgb(0.74, 0.88, 1.01), Rgb(0.032, 0.17, 0.48), 1.0, 1.0);
    Subsurface s(m, SubsurfaceSettings{});
    const double t = s.transmit_threshold();
    ASSERT_GT(t, 1.1 * s.slab_threshold());
    ASSERT_LT(t, 3.0 * s.slab_threshold());
    double worst = 0;
    for (int c = 0; c < 3; ++c) {
        const double inf = s.dipole().channel(c).rd_total();
        worst = std::max(worst, SlabChannel::make(s.dipole().channel(c), t).T_total() / inf);
        EXPECT_GT(SlabChannel::make(s.dipole().channel(c), t / 1.1).T_total() / inf, c == 0 ? 1e-4 : 0.0);
    }
    EXPECT_LE(worst, 1e-4);
    EXPECT_GT(worst, 0.9e-4);
    const Vec3 up(0, 0, 1);
    int key[4];
    int k = 0;
    for (double f : {1.1, 1.4}) {
        const double d = f * s.slab_threshold();
        for (int back = 0; back < 2; ++back) {
            SheetSampler sampler(150.0, d, [back](const Vec3&, const Vec3& n) { return Rgb(back ? (n.z < -0.5) : (n.z > 0.5)); });
            const PointCloud& c = s.cloud(&key[k++], sampler);
            EXPECT_TRUE(s.wants_thickness(c));
            const Vec3 top(0.1, -0.05, d);
            if (!back) {
                EXPECT_FALSE(s.wants_thickness(c, Rgb(1.0)));  // a lit face casts no ray
                const Rgb a = s.radiance(c, top, up, up, Rgb(1.0)), b = s.radiance(c, top, up, up, Rgb(1.0), d);
                for (int ch = 0; ch < 3; ++ch) EXPECT_EQ(a[ch], b[ch]);
                continue;
            }
            EXPECT_TRUE(s.wants_thickness(c, Rgb(0.0)));
            const Rgb l = s.radiance(c, top, up, up, Rgb(0.0), d);
            for (int ch = 0; ch < 3; ++ch) {
                const double want = SlabChannel::make(s.dipole().channel(ch), d).T_total();
                std::printf("back-lit Skin1 slab %.1f mm (%.1f x the slab threshold), channel %d: M %.4g, slab T %.4g (%+.2f %%)\n",
                            d, f, ch, l[ch], want, 100 * (l[ch] / want - 1));
                EXPECT_NEAR(l[ch] / want, 1.0, kThickSlabTransmission) << d << " mm, channel " << ch;
            }
        }
    }
}

// The two thickness nodes around a point are summed in one traversal of the cloud
// (PointCloud::SecondProfiles): each node's result as its own traversal gives it, within
// kPairedTraversal relative (stated before measuring: the shared traversal aggregates no
// coarser than either alone, so only the aggregation error differs), both faces.
constexpr double kPairedTraversal = 2e-3;  // docs/claims.md
TEST(SlabSubsurface, TwoNodesInOneTraversalMatchTheirOwnTraversals) {
    const Medium m = Medium::from_reduced(Rgb(0.74, 0.88, 1.01), Rgb(0.032, 0.17, 0.48), 1.0, 1.0);
    Subsurface s(m, SubsurfaceSettings{});
    const double d = 3.0;
    const SlabProfiles& a = s.slab(d);
    const SlabProfiles& b = s.slab(d * 1.1);
    ASSERT_NE(&a, &b);
    double worst = 0;
    int key[2];
    for (int back = 0; back < 2; ++back) {
        SheetSampler sampler(40.0, d, [back](const Vec3&, const Vec3& n) { return Rgb(back ? (n.z < -0.5) : (n.z > 0.5)); });
        const PointCloud& c = s.cloud(&key[back], sampler);
        const Vec3 x(0.3, -0.2, d), up(0, 0, 1);
        const double h = c.level_spacing(c.lookup_level(x)), r0 = 2 * h;
        const Rgb na = a.transmit->near_reflectance(h), nb = b.transmit->near_reflectance(h);
        Rgb opp_a, opp_b, pair_b, pair_opp_b, pair_opp_a;
        const Rgb alone_a = c.far_exitance_sided(*a.same, *a.transmit, x, up, d, r0, h, 0.7, na, nullptr, &opp_a);
        const Rgb alone_b = c.far_exitance_sided(*b.same, *b.transmit, x, up, d, r0, h, 0.7, nb, nullptr, &opp_b);
        const PointCloud::SecondProfiles second{b.same.get(), b.transmit.get(), nb, &pair_b, &pair_opp_b};
        const Rgb pair_a = c.far_exitance_sided(*a.same, *a.transmit, x, up, d, r0, h, 0.7, na, nullptr, &pair_opp_a,
                                                nullptr, &second);
        for (int k = 0; k < 3; ++k) {
            ASSERT_GT(alone_a[k], 0.0);
            ASSERT_GT(alone_b[k], 0.0);
            for (double e : {pair_a[k] / alone_a[k] - 1, pair_b[k] / alone_b[k] - 1}) worst = std::max(worst, std::fabs(e));
            EXPECT_NEAR(pair_a[k], alone_a[k], kPairedTraversal * alone_a[k]) << back << " " << k;
            EXPECT_NEAR(pair_b[k], alone_b[k], kPairedTraversal * alone_b[k]) << back << " " << k;
            EXPECT_NEAR(pair_opp_b[k], opp_b[k], kPairedTraversal * alone_b[k]) << back << " " << k;
        }
    }
    std::printf("two thickness nodes in one traversal against one each: worst %.2e relative\n", worst);
}

// The radiance at a thin point is continuous in its thickness: over an octave of thicknesses
// 1/512 octave apart, no step between neighbours is larger than 3x the median step (stated
// before measuring; a lookup at the nearest thickness node instead has steps of 1-2 % at the
// switches and none between them).
constexpr double kThicknessStepRatio = 3.0;  // largest step over the median (docs/claims.md)
TEST(SlabSubsurface, RadianceIsContinuousInThickness) {
    const Medium m = Medium::from_reduced(Rgb(2.19, 2.62, 3.00), Rgb(0.0021, 0.0041, 0.0071), 1.5, 1.0);
    Subsurface s(m, SubsurfaceSettings{});
    const double d = s.mean_free_path();
    const Vec3 top(0.1, -0.05, d), up(0, 0, 1);
    for (int back = 0; back < 2; ++back) {
        SheetSampler sampler(25.0, d, [back](const Vec3&, const Vec3& n) { return Rgb(back ? (n.z < -0.5) : (n.z > 0.5)); });
        int key = 0;
        const PointCloud& c = s.cloud(&key, sampler);
        const Rgb here(back ? 0.0 : 1.0);
        std::vector<double> step;
        double prev = 0;
        for (int j = 0; j <= 512; ++j) {
            const double v = s.radiance(c, top, up, up, here, d * std::exp2(j / 512.0)).r;
            ASSERT_TRUE(v > 0) << j;
            if (j > 0) step.push_back(std::fabs(std::log(v / prev)));
            prev = v;
        }
        std::vector<double> sorted = step;
        std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
        const double median = sorted[sorted.size() / 2], largest = *std::max_element(step.begin(), step.end());
        std::printf("lit on the %s: steps over 1/512 octave of thickness: median %.2e, largest %.2e\n",
                    back ? "back" : "front", median, largest);
        EXPECT_GT(median, 0.0);
        EXPECT_LT(largest, kThicknessStepRatio * median) << (back ? "back" : "front");
    }
}

// At or above the threshold the thickness changes nothing, bit for bit; thin geometry off asks
// no thickness at all.
TEST(SlabSubsurface, ThickObjectsAndThinGeometryOffAreUnchanged) {
    const Medium m = Medium::from_reduced(Rgb(2.19, 2.62, 3.00), Rgb(0.0021, 0.0041, 0.0071), 1.5, 1.0);
    Subsurface s(m, SubsurfaceSettings{});
    SheetSampler sampler(10.0, 2.0, [](const Vec3&, const Vec3& n) { return Rgb(n.z > 0.5); });
    int key = 0;
    const PointCloud& c = s.cloud(&key, sampler);
    const Vec3 top(0.3, 0.2, 2.0), up(0, 0, 1);
    const Rgb a = s.radiance(c, top, up, up, Rgb(1.0));
    for (double t : {s.slab_threshold(), 2 * s.slab_threshold(), std::numeric_limits<double>::infinity()}) {
        const Rgb b = s.radiance(c, top, up, up, Rgb(1.0), t);
        for (int k = 0; k < 3; ++k) EXPECT_EQ(a[k], b[k]);
    }
    SubsurfaceSettings off;
    off.thin = false;
    Subsurface s2(m, off);
    EXPECT_EQ(s2.slab_threshold(), 0.0);
    SheetSampler sampler2(10.0, 0.1, [](const Vec3&, const Vec3& n) { return Rgb(n.z > 0.5); });
    const PointCloud& c2 = s2.cloud(&key, sampler2);
    EXPECT_EQ(sampler2.thickness_calls, 0);
    EXPECT_FALSE(s2.wants_thickness(c2));
}

// A slab's profiles are made per thickness node in every render (SlabCache), and each call of
// the multipole's image sums costs thousands of instructions: its T (and R) tables call it at
// every 4th node only, the nodes between from the quintic Hermite of those
// (RdProfile sample_every), the disc integrals on the table. Against the table made by calling
// it at every node, over media, indices and thicknesses from 0.01 to 16 mfp': values
// wherever they exceed 1e-9 of the peak, slopes, discs and totals.
TEST(SlabProfile, TablesSampledAtEveryFourthNodeAreTheFullTables) {
    // Errors as shares of the face's total: a value's per unit of ln r (2 pi r max(r, scale)
    // |df|, what a far sum over a surface weights it by), a slope's the same times
    // max(r, scale), a disc integral's as it is.
    double worst_f = 0, worst_d1 = 0, worst_disc = 0;
    long calls[2] = {0, 0};
    for (double ap : {0.02, 0.3, 0.9, 0.99, 1.0})
        for (double eta : {1.0, 1.3})
            for (double d : {0.01, 0.25, 1.0, 4.0, 16.0}) {
                const Dipole dip(unit_medium(ap, eta));
                const SlabChannel ch = SlabChannel::make(dip.channel(0), d);
                for (bool opposite : {false, true}) {
                    long* count = &calls[0];
                    auto fn = [&](double r) {
                        ++*count;
                        return Rgb(opposite ? ch.T(r) : ch.R(r));
                    };
                    const double scale = std::min(ch.z0, ch.cutoff);
                    const RdProfile full(fn, RdProfile::Fn(), scale, ch.cutoff);
                    count = &calls[1];
                    const RdProfile sparse(fn, RdProfile::Fn(), scale, ch.cutoff, 4);
                    count = &calls[0];  // (the evaluations below read the tables only)
                    const double total = full.total().r;
                    if (!(total > 0)) continue;
                    for (int i = 0; i < 4000; ++i) {
                        const double r = ch.cutoff * std::pow((i + 0.37) / 4000.0, 3.0), w = 2 * kPi * r * std::max(r, scale);
                        Rgb f0, a0, b0, f1, a1, b1;
                        full.eval(r, &f0, &a0, &b0);
                        sparse.eval(r, &f1, &a1, &b1);
                        worst_f = std::max(worst_f, w * std::fabs(f1.r - f0.r) / total);
                        worst_d1 = std::max(worst_d1, w * std::max(r, scale) * std::fabs(a1.r - a0.r) / total);
                    }
                    for (double R : {0.1 * scale, scale, 3 * scale, 0.3 * ch.cutoff, ch.cutoff})
                        worst_disc = std::max(worst_disc, std::fabs(sparse.disc(R).r - full.disc(R).r) / total);
                }
            }
    std::printf("every 4th node: values %.2e, slopes %.2e, discs %.2e of the total; %ld calls against %ld\n", worst_f,
                worst_d1, worst_disc, calls[1], calls[0]);
    EXPECT_LT(worst_f, 1e-6);
    EXPECT_LT(worst_d1, 1e-4);  // (the full table's own slopes: within 1e-3 of the function's, TableMatchesTheAnalyticProfile)
    EXPECT_LT(worst_disc, 1e-6);
    EXPECT_LT(calls[1] * 4, calls[0]);
}
