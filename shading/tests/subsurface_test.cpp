// The hierarchical dipole finish: near/far split, octree aggregation, lazy per-object clouds.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <thread>
#include <vector>

#include "shading/finish.h"
#include "shading/media_presets.h"
#include "shading/subsurface.h"

using namespace shading;

namespace {

// Marble (Jensen 2001) in mm, one scene unit = 1 mm.
Medium marble() { return Medium::from_reduced(Rgb(2.19, 2.62, 3.00), Rgb(0.0021, 0.0041, 0.0071), 1.5); }

// Samples on a square grid of spacing h over [-L, L]^2 in the plane z = 0, normal +z, lit by
// E(x, y) (transmitted irradiance).
std::vector<SurfacePoint> plane(double L, double h, const std::function<Rgb(double, double)>& E) {
    std::vector<SurfacePoint> pts;
    int n = int(std::round(2 * L / h));
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            double x = -L + (i + 0.5) * h, y = -L + (j + 0.5) * h;
            pts.push_back({Vec3(x, y, 0), Vec3(0, 0, 1), h * h, E(x, y)});
        }
    return pts;
}

// M(x) for the plane: far part by the cloud (exact or hierarchical) plus the near part.
Rgb exitance(const Subsurface& s, const PointCloud& c, const Vec3& x, const Rgb& e_here, bool exact) {
    const double h = c.spacing(), r0 = Subsurface::near_radius(h);
    Rgb far = exact ? c.far_exitance_exact(s.dipole(), x, r0, h)
                    : c.far_exitance(s.profile(), x, r0, h, s.settings().max_angle, s.cutoff());
    return far + e_here * c.near_reflectance();
}

// Half-plane x' > 0 lit with E = 1: the exact M at (d, 0) by quadrature of Rd over the lit side.
double half_plane_exitance(const DipoleChannel& ch, double d) {
    // M(d) = int_{x' > 0} int_y Rd(sqrt((x' - d)^2 + y^2)) dy dx'; in polar coordinates around
    // (d, 0): the lit part of the circle of radius r is the arc where r cos(t) > -d.
    double sum = 0;
    const int nr = 200000;
    const double rmax = 60.0 / std::max(ch.sigma_tr, 1e-3);
    // r substitution r = rmax u^2 concentrates nodes near 0 (Rd ~ 1/r^3 there).
    for (int k = 0; k < nr; ++k) {
        double u = (k + 0.5) / nr, r = rmax * u * u, dr = 2 * rmax * u / nr;
        double frac;  // fraction of the circle inside the lit half plane
        if (d >= r) frac = 1.0;
        else if (d <= -r) frac = 0.0;
        else frac = 1.0 - std::acos(d / r) / kPi;
        sum += ch.rd(r) * 2 * kPi * r * frac * dr;
    }
    return sum;
}

}  // namespace

TEST(Subsurface, NearAndFarPartsAddUpToTheTotal) {
    // integral of Rd = near_reflectance + integral of w Rd (continuum): the split loses nothing.
    Subsurface s(marble(), SubsurfaceSettings{});
    for (double h : {0.05, 0.2, 1.0}) {
        Rgb near = s.near_reflectance(h);
        const double r0 = Subsurface::near_radius(h);
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel& ch = s.dipole().channel(c);
            double far = 0;
            const int n = 400000;
            const double rmax = 200.0 / ch.sigma_tr;
            for (int k = 0; k < n; ++k) {
                double u = (k + 0.5) / n, r = rmax * u * u, dr = 2 * rmax * u / n;
                far += PointCloud::window(r, r0, h) * ch.rd(r) * 2 * kPi * r * dr;
            }
            EXPECT_NEAR(near[c] + far, ch.rd_total(), 2e-4 * ch.rd_total()) << "h=" << h << " c=" << c;
        }
    }
}

TEST(Subsurface, UniformlyLitPlaneGivesTheTotalReflectanceEverywhere) {
    // A flat, uniformly lit surface: M = Rd_total E wherever x sits relative to the grid (no
    // pattern), for spacings finer and coarser than the mean free path (~0.45 mm here).
    Subsurface s(marble(), SubsurfaceSettings{});
    const Rgb total = s.dipole().rd_total();
    for (double h : {0.1, 0.4, 2.0}) {
        PointCloud c(plane(80.0, h, [](double, double) { return Rgb(1.0); }), h, s.near_reflectance(h));
        for (double off : {0.0, 0.25, 0.5}) {
            Vec3 x(off * h, 0.37 * off * h, 0);
            Rgb m = exitance(s, c, x, Rgb(1.0), false);
            for (int k = 0; k < 3; ++k)
                EXPECT_NEAR(m[k], total[k], 5e-3 * total[k]) << "h=" << h << " offset " << off << " c=" << k;
        }
    }
}

TEST(Subsurface, HalfLitPlaneFollowsTheShadowEdgeIntegral) {
    // Light bleeding across a sharp shadow edge (x = 0): the cloud against a direct quadrature.
    Subsurface s(marble(), SubsurfaceSettings{});
    const double h = 0.1;
    PointCloud c(plane(60.0, h, [](double x, double) { return Rgb(x > 0 ? 1.0 : 0.0); }), h, s.near_reflectance(h));
    for (double d : {-3.0, -1.0, -0.5, 0.5, 1.0, 3.0}) {
        Vec3 x(d, 0.013, 0);
        Rgb m = exitance(s, c, x, Rgb(d > 0 ? 1.0 : 0.0), false);
        for (int k = 0; k < 3; ++k) {
            double want = half_plane_exitance(s.dipole().channel(k), d);
            EXPECT_NEAR(m[k], want, 0.01 * s.dipole().channel(k).rd_total()) << "d=" << d << " c=" << k;
        }
    }
}

TEST(Subsurface, HierarchyAgreesWithTheExactSumAndPrunes) {
    SubsurfaceSettings st;
    Subsurface s(marble(), st);
    const double h = 0.2;
    PointCloud c(plane(40.0, h, [](double x, double y) { return Rgb(1.0 + 0.5 * std::sin(x) * std::cos(0.3 * y)); }), h,
                 s.near_reflectance(h));
    for (Vec3 x : {Vec3(0, 0, 0), Vec3(5.3, -2.1, 0), Vec3(39, 39, 0), Vec3(0, 0, 3.0)}) {
        Rgb exact = c.far_exitance_exact(s.dipole(), x, 2 * h, h);
        std::size_t visited = 0;
        Rgb fast = c.far_exitance(s.profile(), x, 2 * h, h, st.max_angle, s.cutoff(), &visited);
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(fast[k], exact[k], 0.01 * exact[k] + 1e-9) << k;
        EXPECT_LT(visited, c.points().size() / 20);  // far fewer nodes than points
    }
}

TEST(Subsurface, CloudIsBuiltOncePerObjectAcrossThreads) {
    Subsurface s(marble(), SubsurfaceSettings{});
    std::atomic<int> builds{0};
    int a, b;
    auto make = [&](double* h) {
        ++builds;
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        *h = 0.5;
        return plane(5.0, 0.5, [](double, double) { return Rgb(1.0); });
    };
    std::vector<std::thread> ts;
    std::atomic<const PointCloud*> seen[8];
    for (int i = 0; i < 8; ++i)
        ts.emplace_back([&, i] { seen[i] = &s.cloud(i % 2 ? (void*)&a : (void*)&b, make); });
    for (auto& t : ts) t.join();
    EXPECT_EQ(builds.load(), 2);
    for (int i = 2; i < 8; ++i) EXPECT_EQ(seen[i].load(), seen[i % 2].load());
    EXPECT_DOUBLE_EQ(seen[0].load()->spacing(), 0.5);
}

TEST(Subsurface, RadianceIsFresnelTimesExitanceAndStableAtHardCases) {
    const double h = 0.25;
    for (const Medium& m : {marble(), Medium::from_reduced(Rgb(1.0), Rgb(0.0), 1.3),       // albedo 1
                            Medium::from_reduced(Rgb(1.0), Rgb(0.01), 1.0),                  // eta = 1
                            Medium::from_reduced(Rgb(1e6), Rgb(1e3), 1.4)}) {              // opaque limit
        Subsurface s(m, SubsurfaceSettings{});
        PointCloud c(plane(10.0, h, [](double, double) { return Rgb(1.0); }), h, s.near_reflectance(h));
        for (Vec3 x : {Vec3(0.125, 0.125, 0), Vec3(0, 0, 0), Vec3(3, 1, 1e-9)}) {  // on a sample, between, off
            Rgb l = s.radiance(c, x, Vec3(0, 0, 1), normalize(Vec3(0.3, 0, 1)), Rgb(1.0));
            for (int k = 0; k < 3; ++k) {
                EXPECT_TRUE(std::isfinite(l[k]));
                EXPECT_GE(l[k], 0.0);
                EXPECT_LE(l[k], 1.0 + 1e-6);  // never more than comes in
            }
        }
        EXPECT_EQ(s.radiance(c, Vec3(0, 0, 0), Vec3(0, 0, 1), Vec3(0, 0, -1), Rgb(1.0)).max_component(), 0.0);
    }
}

TEST(Subsurface, SurfaceBrdfIsSingleScatteringPlusCoat) {
    auto s = std::make_shared<Subsurface>(marble(), SubsurfaceSettings{});
    Vec3 wo = normalize(Vec3(0.2, 0.1, 1)), wi = normalize(Vec3(-0.4, 0.3, 1));
    DipoleSurfaceBrdf only(s, nullptr);
    Rgb ss = s->dipole().single_scatter_brdf(wo, wi);
    EXPECT_EQ(only.f(wo, wi).g, ss.g);
    auto coat = std::make_shared<TransmittanceBrdf>(1.5);
    DipoleSurfaceBrdf both(s, coat);
    EXPECT_DOUBLE_EQ(both.f(wo, wi).g, ss.g + coat->f(wo, wi).g);
    // The transmittance BRDF lit by the light loop yields Ft cos E (POV units).
    auto t = make_finish_model(std::make_shared<TransmittanceBrdf>(1.5));
    Rgb w = finish_light_weight(*t, Vec3(0, 0, 1), Vec3(0, 0, 1), wi, Rgb(1.0));
    EXPECT_NEAR(w.r, fresnel_transmittance(wi.z, 1.5) * wi.z, 1e-12);
}

TEST(Subsurface, BadSettingsAreRejected) {
    SubsurfaceSettings st;
    st.max_angle = 0;
    EXPECT_THROW(Subsurface(marble(), st), std::invalid_argument);
    st.max_angle = 0.3;
    st.spacing = -1;
    EXPECT_THROW(Subsurface(marble(), st), std::invalid_argument);
}

TEST(Subsurface, FinishModelCarriesTheDipoleUnderItsCoat) {
    auto s = std::make_shared<const Subsurface>(marble(), SubsurfaceSettings{});
    auto coat = make_finish_model_from_spec("microfacet d=beckmann m=0.2 f=dielectric eta=1.5");
    coat->scale = Rgb(2.0);
    coat->reflection_samples = 8;
    auto m = finish_model_with_subsurface(coat.get(), s);
    EXPECT_EQ(m->subsurface, s);
    EXPECT_EQ(m->scale.r, 2.0);
    EXPECT_EQ(m->reflection_samples, 8);
    Vec3 wo = normalize(Vec3(0.1, 0, 1)), wi = normalize(Vec3(-0.2, 0.1, 1));
    EXPECT_NEAR(m->brdf->f(wo, wi).g, coat->brdf->f(wo, wi).g + s->dipole().single_scatter_brdf(wo, wi).g, 1e-12);
    // A second dipole replaces the first instead of stacking single scattering twice.
    auto s2 = std::make_shared<const Subsurface>(marble(), SubsurfaceSettings{});
    auto m2 = finish_model_with_subsurface(m.get(), s2);
    EXPECT_NEAR(m2->brdf->f(wo, wi).g, m->brdf->f(wo, wi).g, 1e-12);
    EXPECT_EQ(m2->subsurface, s2);
    // No coat: single scattering alone.
    auto bare = finish_model_with_subsurface(nullptr, s);
    EXPECT_NEAR(bare->brdf->f(wo, wi).g, s->dipole().single_scatter_brdf(wo, wi).g, 1e-15);
}

TEST(Subsurface, ReleasingTheLastFinishFreesItsOwnHandleWithoutDeadlock) {
    // A dipole finish model owns a registered handle (its transmittance light loop): releasing
    // the model's handle must destroy it outside the registry lock.
    std::size_t before = finish_model_live_count();
    {
        auto s = std::make_shared<const Subsurface>(marble(), SubsurfaceSettings{});
        int h = finish_model_register(finish_model_with_subsurface(nullptr, s));
        EXPECT_EQ(finish_model_live_count(), before + 2);
        s.reset();
        finish_model_release(h);  // deadlocked before the fix
    }
    EXPECT_EQ(finish_model_live_count(), before);
}

TEST(SubsurfaceRdProfile, TableMatchesTheAnalyticProfile) {
    for (const Medium& m : {marble(), Medium::from_reduced(Rgb(1.0), Rgb(0.05), 1.3), Medium::from_reduced(Rgb(1.0), Rgb(0.0), 1.3)}) {
        Subsurface s(m, SubsurfaceSettings{});
        const RdProfile& p = s.profile();
        double worst = 0, worst_d = 0, worst_d2 = 0;
        for (int i = 0; i < 20000; ++i) {
            double r = p.r_max() * std::pow((i + 0.37) / 20000.0, 3.0);
            Rgb a = s.dipole().rd(r), f, d1, d2;
            p.eval(r, &f, &d1, &d2);
            for (int k = 0; k < 3; ++k) {
                if (!(a[k] > 1e-9 * s.dipole().rd(0.0)[k])) continue;
                worst = std::max(worst, std::abs(f[k] - a[k]) / a[k]);
                double e = 1e-4 * std::max(r, 1e-3);
                double num = (s.dipole().rd(r + e)[k] - s.dipole().rd(std::max(0.0, r - e))[k]) / (r + e - std::max(0.0, r - e));
                if (r > 0.05 && std::abs(num) > 1e-6 * a[k]) worst_d = std::max(worst_d, std::abs(d1[k] - num) / std::abs(num));
                double num2 = (s.dipole().rd(r + e)[k] - 2 * a[k] + s.dipole().rd(std::fabs(r - e))[k]) / (e * e);
                if (r > 0.05 && std::abs(num2) > 1e-3 * a[k]) worst_d2 = std::max(worst_d2, std::abs(d2[k] - num2) / (std::abs(num2) + 1e-3 * a[k]));
            }
        }
        EXPECT_LT(worst, 1e-4);
        EXPECT_LT(worst_d, 1e-3);
        EXPECT_LT(worst_d2, 2e-2);
        EXPECT_EQ(p.rd(p.r_max() * 1.01).r, 0.0);
    }
}
