// The exact profile's curvature correction: the cloud's mean curvature estimate, the measured
// coefficient c(eta), and the lookup that applies them (curvature.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "shading/subsurface/curvature.h"
#include "shading/subsurface/subsurface.h"

using namespace shading;

namespace {

// Points on a sphere of radius R about the origin, about h apart (a Fibonacci lattice), with
// outward normals (inward: seen from inside, a concave face).
std::vector<SurfacePoint> sphere(double R, double h, bool inward = false) {
    const int n = int(std::ceil(4 * kPi * R * R / (h * h)));
    std::vector<SurfacePoint> pts;
    const double golden = kPi * (3.0 - std::sqrt(5.0));
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - (i + 0.5) * 2.0 / n, r = std::sqrt(1.0 - z * z), phi = golden * i;
        const Vec3 u(r * std::cos(phi), r * std::sin(phi), z);
        pts.push_back({u * R, inward ? -u : u, 4 * kPi * R * R / n, Rgb(1.0)});
    }
    return pts;
}

// A cylinder of radius R along z, |z| <= L, about h apart, outward normals.
std::vector<SurfacePoint> cylinder(double R, double L, double h) {
    std::vector<SurfacePoint> pts;
    const int na = int(std::ceil(2 * kPi * R / h)), nz = int(std::ceil(2 * L / h));
    for (int i = 0; i < na; ++i)
        for (int j = 0; j < nz; ++j) {
            const double a = 2 * kPi * (i + 0.5 * (j % 2)) / na, z = -L + (j + 0.5) * 2 * L / nz;
            const Vec3 u(std::cos(a), std::sin(a), 0);
            pts.push_back({u * R + Vec3(0, 0, z), u, h * h, Rgb(1.0)});
        }
    return pts;
}

// Both faces of a sheet of thickness d: z = 0 (normal -z) and z = d (normal +z), spacing h.
std::vector<SurfacePoint> sheet(double L, double d, double h) {
    std::vector<SurfacePoint> pts;
    const int n = int(std::round(2 * L / h));
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            const double x = -L + (i + 0.5) * h, y = -L + (j + 0.5) * h;
            pts.push_back({Vec3(x, y, d), Vec3(0, 0, 1), h * h, Rgb(1.0)});
            pts.push_back({Vec3(x, y, 0), Vec3(0, 0, -1), h * h, Rgb(1.0)});
        }
    return pts;
}

// The estimate on a sphere against 1/R, absolute (scene units^-1): exact but for rounding.
constexpr double kSphereCurvatureTol = 1e-12;

}  // namespace

TEST(CloudCurvature, ASphereIsOneOverItsRadiusFromOutsideAndMinusThatFromInside) {
    const double R = 7.0, h = 0.3;
    for (bool inward : {false, true}) {
        PointCloud c(sphere(R, h, inward), h);
        for (Vec3 u : {Vec3(0, 0, 1), normalize(Vec3(1, 2, -0.5)), normalize(Vec3(-0.3, 0.1, 0.2))}) {
            // on the sphere but between samples, with its exact normal
            const double H = c.mean_curvature_about(u * R, inward ? -u : u, h);
            EXPECT_NEAR(H, (inward ? -1.0 : 1.0) / R, kSphereCurvatureTol) << "inward " << inward;
            std::printf("sphere R %g, inward %d: H - 1/R = %.2e\n", R, int(inward), H - (inward ? -1.0 : 1.0) / R);
        }
    }
}

TEST(CloudCurvature, APlaneIsFlatAndASheetsOtherFaceIsLeftOut) {
    const double h = 0.2;
    for (double d : {0.05, 0.3, 2.0}) {  // the other face inside the window, at its edge, beyond
        PointCloud c(sheet(4.0, d, h), h);
        EXPECT_EQ(c.mean_curvature_about(Vec3(0.03, -0.07, d), Vec3(0, 0, 1), h), 0.0) << d;
        EXPECT_EQ(c.mean_curvature_about(Vec3(0.5, 0.5, 0), Vec3(0, 0, -1), h), 0.0) << d;
    }
    // no other point: 0
    PointCloud one({SurfacePoint{Vec3(0, 0, 0), Vec3(0, 0, 1), 1.0, Rgb(1.0)}}, h);
    EXPECT_EQ(one.mean_curvature_about(Vec3(0, 0, 0), Vec3(0, 0, 1), h), 0.0);
}

TEST(CloudCurvature, ACylinderIsTheMeanOfItsTwoCurvatures) {
    // 1 / (2R): the normal curvature 1/R across the axis, 0 along it, averaged over the window
    const double R = 5.0, h = 0.1;
    PointCloud c(cylinder(R, 2.0, h), h);
    const double H = c.mean_curvature_about(Vec3(R, 0, 0.01), Vec3(1, 0, 0), h);
    EXPECT_NEAR(H * 2 * R, 1.0, 0.05);
}

// A refined cloud: points far denser than the window (a shadow edge refined 4 levels: 16 per
// spacing across), where mean_curvature_about takes nodes whole from their sums about their
// centroids. Against the same least squares summed point by point (written here): a sphere is
// 1/R exactly either way; on an ellipsoid and on both faces of a thin sheet the two agree
// within kDenseCurvatureTol of the ellipsoid's largest normal curvature.
constexpr double kDenseCurvatureTol = 0.01;

namespace {

// The estimate point by point: the window's weights 1 - w(r) (rd_profile.h far_window, R0 = 2h),
// points facing away from nx left out.
double curvature_by_points(const std::vector<SurfacePoint>& pts, const Vec3& x, const Vec3& nx, double h) {
    double num = 0, den = 0;
    for (const SurfacePoint& q : pts) {
        const Vec3 v = x - q.p;
        const double r2 = dot(v, v);
        if (!(r2 > 0) || !(dot(q.n, nx) > 0)) continue;
        const double w = 1.0 - far_window(std::sqrt(r2), 2 * h, h);
        num += q.area * w * dot(nx - q.n, v);
        den += q.area * w * r2;
    }
    return den > 0 ? num / den : 0.0;
}

// Points of the ellipsoid (x/a)^2 + (y/b)^2 + (z/c)^2 = 1 within `cap` of the pole (0, 0, c),
// about s apart (a grid in x, y), with their areas and outward normals; `lower` adds the
// mirror image z -> -z (a thin lens: its other face inside the window when c is small).
std::vector<SurfacePoint> ellipsoid_cap(double a, double b, double c, double cap, double s, bool lower = false) {
    std::vector<SurfacePoint> pts;
    for (double x = -cap; x <= cap; x += s)
        for (double y = -cap; y <= cap; y += s) {
            const double t = 1 - sqr(x / a) - sqr(y / b);
            if (!(t > 0.05) || x * x + y * y > cap * cap) continue;
            const double z = c * std::sqrt(t);
            const Vec3 n = normalize(Vec3(x / (a * a), y / (b * b), z / (c * c)));
            const double area = s * s / n.z;  // the grid cell projected onto the surface
            pts.push_back({Vec3(x, y, z), n, area, Rgb(1.0)});
            if (lower) pts.push_back({Vec3(x, y, -z), Vec3(n.x, n.y, -n.z), area, Rgb(1.0)});
        }
    return pts;
}

}  // namespace

TEST(CloudCurvature, ADenseCloudTakesWholeNodesAsItsPointsWould) {
    const double h = 0.3, s = h / 16;
    // a sphere (a cap of it: R 7) is exact
    {
        std::vector<SurfacePoint> pts = ellipsoid_cap(7, 7, 7, 2.0, s);
        const PointCloud cloud(pts, s);
        for (Vec3 u : {Vec3(0, 0, 1), normalize(Vec3(0.05, -0.03, 1))}) {
            const double H = cloud.mean_curvature_about(u * 7.0, u, h);
            EXPECT_NEAR(H, 1.0 / 7.0, kSphereCurvatureTol);
        }
    }
    // an ellipsoid: normal curvatures from 1/18 to 1/3 about the pole
    double worst = 0;
    {
        const double a = 6, b = 4, c = 3;
        std::vector<SurfacePoint> pts = ellipsoid_cap(a, b, c, 2.5, s);
        const PointCloud cloud(pts, s);
        const double kmax = c / (b * b);
        for (const Vec3& p : {Vec3(0, 0, c), Vec3(0.7, -0.4, 0), Vec3(-1.1, 0.9, 0)}) {
            const double t = 1 - sqr(p.x / a) - sqr(p.y / b);
            const Vec3 x(p.x, p.y, c * std::sqrt(t));
            const Vec3 n = normalize(Vec3(x.x / (a * a), x.y / (b * b), x.z / (c * c)));
            const double H = cloud.mean_curvature_about(x, n, h), ref = curvature_by_points(pts, x, n, h);
            worst = std::max(worst, std::fabs(H - ref) / kmax);
            EXPECT_NEAR(H, ref, kDenseCurvatureTol * kmax) << x.x << "," << x.y;
        }
    }
    // a thin lens (c 0.2: its other face 0.4 away at the pole, inside the window)
    {
        std::vector<SurfacePoint> pts = ellipsoid_cap(6, 4, 0.2, 2.0, s, true);
        const PointCloud cloud(pts, s);
        const Vec3 x(0.3, 0.2, 0.2 * std::sqrt(1 - sqr(0.3 / 6) - sqr(0.2 / 4)));
        const Vec3 n = normalize(Vec3(x.x / 36, x.y / 16, x.z / 0.04));
        const double H = cloud.mean_curvature_about(x, n, h), ref = curvature_by_points(pts, x, n, h);
        worst = std::max(worst, std::fabs(H - ref) / (0.2 / 16));
        EXPECT_NEAR(H, ref, kDenseCurvatureTol * (0.2 / 16));
    }
    std::printf("dense clouds: whole nodes against point by point, worst %.2e of the largest curvature\n", worst);
}

TEST(CurvatureCoefficient, GrowsWithTheIorAtEveryAlbedoAndIsHeldBeyondTheGrid) {
    for (double albedo : {0.2, 0.4, 0.5, 0.75, 0.9, 0.97, 0.995, 0.999}) {
        double last = 0;
        for (double eta = 1.0; eta <= 2.0 + 1e-9; eta += 0.05) {
            const double c = curvature_coefficient(eta, albedo);
            EXPECT_GE(c, last) << "eta " << eta << " albedo " << albedo;  // never below 0
            if (eta > 1.25) {
                EXPECT_GT(c, last) << "eta " << eta << " albedo " << albedo;
            }
            last = c;
        }
        EXPECT_EQ(curvature_coefficient(3.0, albedo), curvature_coefficient(2.0, albedo));
        EXPECT_EQ(curvature_coefficient(0.8, albedo), curvature_coefficient(1.0, albedo));
    }
    EXPECT_EQ(curvature_coefficient(1.3, 0.1), curvature_coefficient(1.3, 0.4));
    EXPECT_EQ(curvature_coefficient(1.3, 1.0), curvature_coefficient(1.3, 0.995));
    EXPECT_TRUE(std::isfinite(curvature_coefficient(std::nan(""), std::nan(""))));
    // without refraction the boundary adds nothing; the measured size effect at high albedo
    // (negative) is taken as 0
    for (double albedo : {0.4, 0.6}) EXPECT_LT(std::abs(curvature_coefficient(1.0, albedo)), 0.05);
    for (double albedo : {0.9, 0.98, 0.995}) EXPECT_EQ(curvature_coefficient(1.0, albedo), 0.0);
    // a measured node (shading/DIPOLE.md 6d), and halfway between two
    EXPECT_NEAR(curvature_coefficient(1.3, 0.75), 0.825, 1e-12);
    EXPECT_NEAR(curvature_coefficient(1.35, 0.75),
                0.5 * (curvature_coefficient(1.3, 0.75) + curvature_coefficient(1.4, 0.75)), 1e-12);
}

TEST(CurvatureCoefficient, FadesOutWithForwardScattering) {
    EXPECT_EQ(curvature_anisotropy_weight(0.0), 1.0);
    EXPECT_NEAR(curvature_anisotropy_weight(0.3), 0.75, 1e-12);
    EXPECT_NEAR(curvature_anisotropy_weight(-0.3), 0.75, 1e-12);
    EXPECT_EQ(curvature_anisotropy_weight(kCurvatureGMax), 0.0);
    EXPECT_EQ(curvature_anisotropy_weight(0.9), 0.0);
    EXPECT_EQ(curvature_anisotropy_weight(std::nan("")), 0.0);
    // a medium of g 0.9 keeps the flat profile; g 0.3 gets three quarters of the isotropic term
    for (double g : {0.9, 0.3}) {
        Medium m = Medium::from_reduced(Rgb(0.9), Rgb(0.1), 1.3);
        m.g = Rgb(g);
        m.sigma_s = m.sigma_s * (1.0 / (1.0 - g));  // the same sigma_s'
        SubsurfaceSettings on;
        on.curvature = true;
        const Subsurface s(m, on);
        EXPECT_NEAR(s.curvature_length()[0], curvature_coefficient(1.3, 0.9) * curvature_anisotropy_weight(g), 1e-12);
    }
}

TEST(SubsurfaceCurvature, ALookupOnASphereIsTheFlatOneTimesOnePlusCMfpOverR) {
    // Skin1 (mm) at ior 1.3, and a medium of high albedo at ior 1.5
    for (const Medium& m : {Medium::from_reduced(Rgb(0.74, 0.88, 1.01), Rgb(0.032, 0.17, 0.48), 1.3),
                            Medium::from_reduced(Rgb(0.99, 0.98, 0.95), Rgb(0.01, 0.02, 0.05), 1.5)}) {
        SubsurfaceSettings flat, curved;
        curved.curvature = true;
        Subsurface sf(m, flat), sc(m, curved);
        for (double R : {40.0, 8.0, 2.0}) {  // the last: |c| mfp' / R beyond the clamp in some channels
            const double h = 0.3;
            PointCloud cloud(sphere(R, h), h, sf.near_reflectance(h));
            const Vec3 u = normalize(Vec3(0.2, -0.4, 1.0)), to_eye = normalize(Vec3(0, 0.3, 1));
            const Rgb a = sf.radiance(cloud, u * R, u, to_eye, Rgb(1.0));
            const Rgb b = sc.radiance(cloud, u * R, u, to_eye, Rgb(1.0));
            for (int k = 0; k < 3; ++k) {
                const double st = m.sigma_s_prime()[k] + m.sigma_a[k], mfp = 1.0 / st;
                const double c = curvature_coefficient(m.eta, m.sigma_s_prime()[k] / st);
                EXPECT_NE(c, 0.0);
                const double gain = std::clamp(c * mfp / R, -kMaxCurvatureGain, kMaxCurvatureGain);
                EXPECT_GT(a[k], 0.0);
                EXPECT_NEAR(b[k] / a[k], 1.0 + gain, 1e-9) << "eta " << m.eta << " R " << R << " channel " << k;
                EXPECT_NEAR(sc.curvature_length()[k], c * mfp, 1e-12);
            }
        }
        EXPECT_EQ(sf.curvature_length().max_component(), 0.0);
    }
}
