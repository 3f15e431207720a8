#include <gtest/gtest.h>

#include "shading/core/vec.h"

using namespace shading;

TEST(Frame, FromNormalIsOrthonormal) {
    for (Vec3 n : {Vec3(0, 0, 1), Vec3(0, 0, -1), normalize(Vec3(1, 2, 3)), normalize(Vec3(-1, 0, 1e-12))}) {
        Frame f = Frame::from_normal(n);
        EXPECT_NEAR(dot(f.t, f.t), 1.0, 1e-12);
        EXPECT_NEAR(dot(f.b, f.b), 1.0, 1e-12);
        EXPECT_NEAR(dot(f.t, f.b), 0.0, 1e-12);
        EXPECT_NEAR(dot(f.t, n), 0.0, 1e-12);
        EXPECT_NEAR(dot(f.b, n), 0.0, 1e-12);
        Vec3 v = normalize(Vec3(0.3, -0.4, 0.5));
        Vec3 r = f.to_world(f.to_local(v));
        EXPECT_NEAR(r.x, v.x, 1e-12);
        EXPECT_NEAR(r.y, v.y, 1e-12);
        EXPECT_NEAR(r.z, v.z, 1e-12);
        EXPECT_NEAR(f.to_local(n).z, 1.0, 1e-12);
    }
}

TEST(Frame, TangentHintProjectedAndFallbackWhenParallel) {
    Vec3 n(0, 0, 1);
    Frame f = Frame::from_normal_tangent(n, Vec3(2, 0, 5));
    EXPECT_NEAR(f.t.x, 1.0, 1e-12);
    EXPECT_NEAR(f.b.y, 1.0, 1e-12);
    Frame g = Frame::from_normal_tangent(n, Vec3(0, 0, 3));  // parallel: fallback
    EXPECT_NEAR(dot(g.t, n), 0.0, 1e-12);
    EXPECT_NEAR(dot(g.t, g.t), 1.0, 1e-12);
}

TEST(Frame, PoleHasDefinedPhi) {
    Vec3 pole(0, 0, 1);
    EXPECT_EQ(cos_phi(pole), 1.0);
    EXPECT_EQ(sin_phi(pole), 0.0);
    Vec3 w = spherical_direction(0.7, 2.0);
    EXPECT_NEAR(std::atan2(sin_phi(w), cos_phi(w)), 2.0, 1e-12);
}
