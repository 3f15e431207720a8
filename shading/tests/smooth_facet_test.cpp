// smooth_facet_point: the curved surface a flat triangle's vertex normals describe.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "shading/core/smooth_facet.h"

using namespace shading;

namespace {

Vec3 on_sphere(double theta, double phi) {
    return {std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
}

Vec3 at(const Vec3 v[3], double b1, double b2) { return v[0] * (1 - b1 - b2) + v[1] * b1 + v[2] * b2; }

}  // namespace

TEST(SmoothFacet, LiftsAUnitSphereFacetOutOfTheSphere) {
    // A facet of a UV sphere of radius 1 (7.5 degrees, as a 48 x 24 mesh), its exact normals at
    // the vertices: the flat facet lies up to its depth inside the sphere (the polyhedron's
    // neighbouring facets then shadow it near the terminator). Every lifted point lies on or
    // just outside the sphere, by at most about that depth (the construction's bulge).
    const double d = 7.5 * kDegree;
    const Vec3 v[3] = {on_sphere(0.6, 0.3), on_sphere(0.6, 0.3 + d), on_sphere(0.6 + d, 0.3)};
    double depth = 0, below = 0, above = 0;
    for (int i = 0; i <= 20; ++i)
        for (int j = 0; i + j <= 20; ++j) {
            const Vec3 p = at(v, i / 20.0, j / 20.0);
            const Vec3 q = smooth_facet_point(p, v, v, p);
            depth = std::max(depth, 1 - length(p));
            below = std::max(below, 1 - length(q));
            above = std::max(above, length(q) - 1);
            EXPECT_GE(length(q), length(p) - 1e-15);  // only ever out
        }
    std::printf("flat facet up to %.3g inside the sphere; lifted, up to %.3g inside and %.3g outside\n", depth, below,
                above);
    // measured: 2.95e-3 inside; lifted 0 inside (the vertices), 2.92e-3 outside
    EXPECT_GT(depth, 2e-3);
    EXPECT_LT(below, 1e-12);
    EXPECT_LT(above, 1.2 * depth);
}

TEST(SmoothFacet, VerticesAndFlatOrConcaveFacetsStay) {
    const Vec3 v[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    // the facet's own normal at every vertex: a flat surface
    const Vec3 flat[3] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
    const Vec3 p = at(v, 0.3, 0.3);
    const Vec3 q = smooth_facet_point(p, v, flat, Vec3(0, 0, 1));
    EXPECT_EQ(q.x, p.x);
    EXPECT_EQ(q.y, p.y);
    EXPECT_EQ(q.z, p.z);
    // normals leaning outward from the facet's centre (a concave bowl seen from +z): p is above
    // every tangent plane and stays
    const Vec3 bowl[3] = {{0.3, 0.3, 1}, {-0.5, 0.3, 1}, {0.3, -0.5, 1}};
    const Vec3 c = smooth_facet_point(p, v, bowl, Vec3(0, 0, 1));
    EXPECT_NEAR(length(c - p), 0.0, 1e-15);
    // a vertex of a convex facet stays where it is
    const Vec3 dome[3] = {{-0.3, -0.3, 1}, {0.5, -0.3, 1}, {-0.3, 0.5, 1}};
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(length(smooth_facet_point(v[k], v, dome, Vec3(0, 0, 1)) - v[k]), 0.0, 1e-15);
    // and its centre moves out along +z
    const Vec3 m = smooth_facet_point(at(v, 1 / 3.0, 1 / 3.0), v, dome, Vec3(0, 0, 1));
    EXPECT_GT(m.z, 0.01);
}

TEST(SmoothFacet, NormalsAreTakenOnTheOutwardSide) {
    // the same dome with its vertex normals given inward (a mesh whose normals point into it):
    // the lift is the same, out of the surface
    const Vec3 v[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    const Vec3 out[3] = {{-0.3, -0.3, 1}, {0.5, -0.3, 1}, {-0.3, 0.5, 1}};
    const Vec3 in[3] = {-out[0], -out[1], -out[2]};
    const Vec3 p = at(v, 0.25, 0.4);
    const Vec3 a = smooth_facet_point(p, v, out, Vec3(0, 0, 1)), b = smooth_facet_point(p, v, in, Vec3(0, 0, 1));
    EXPECT_GT(a.z, 0.0);
    EXPECT_NEAR(length(a - b), 0.0, 1e-15);
}

TEST(SmoothFacet, DegenerateInputStaysWhereItIs) {
    const Vec3 p(0.2, 0.2, 0);
    const Vec3 n[3] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1}};
    const Vec3 line[3] = {{0, 0, 0}, {1, 1, 0}, {2, 2, 0}};  // no area
    EXPECT_NEAR(length(smooth_facet_point(p, line, n, Vec3(0, 0, 1)) - p), 0.0, 0.0);
    const Vec3 v[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    const Vec3 zero[3] = {{0, 0, 1}, {0, 0, 0}, {0, 0, 1}};
    EXPECT_NEAR(length(smooth_facet_point(p, v, zero, Vec3(0, 0, 1)) - p), 0.0, 0.0);
    const Vec3 nan[3] = {{0, 0, 1}, {0, 0, std::nan("")}, {0, 0, 1}};
    EXPECT_NEAR(length(smooth_facet_point(p, v, nan, Vec3(0, 0, 1)) - p), 0.0, 0.0);
}
