// The small optimisers of optimize.h on problems with known minima.
#include <gtest/gtest.h>

#include <cmath>

#include "shading/core/optimize.h"

using namespace shading;

namespace {

// Rosenbrock as least squares: r = (1 - x, 10 (y - x^2)), minimum 0 at (1, 1).
void rosenbrock_residuals(const Vector& x, Vector& r) {
    r.assign({1.0 - x[0], 10.0 * (x[1] - x[0] * x[0])});
}

TEST(LevenbergMarquardt, RosenbrockFromTheClassicStart) {
    LmResult r = levenberg_marquardt(rosenbrock_residuals, {-1.2, 1.0}, {}, {});
    EXPECT_TRUE(r.converged) << r.stop;
    EXPECT_NEAR(r.x[0], 1.0, 1e-7);
    EXPECT_NEAR(r.x[1], 1.0, 1e-7);
    EXPECT_LT(r.cost, 1e-20);
}

TEST(LevenbergMarquardt, AnalyticJacobianGivesTheSameMinimum) {
    auto jac = [](const Vector& x, const Vector&, Vector& J) { J.assign({-1.0, 0.0, -20.0 * x[0], 10.0}); };
    LmResult r = levenberg_marquardt(rosenbrock_residuals, {-1.2, 1.0}, {}, {}, {}, jac);
    EXPECT_NEAR(r.x[0], 1.0, 1e-9);
    EXPECT_NEAR(r.x[1], 1.0, 1e-9);
}

TEST(LevenbergMarquardt, LinearFitAndItsCovarianceFactor) {
    // y = 2 + 3 x exactly at x = 0..4: the minimum is exact and (J^T J)^-1 = (X^T X)^-1.
    const Vector xs = {0, 1, 2, 3, 4};
    auto res = [&](const Vector& p, Vector& r) {
        r.resize(xs.size());
        for (size_t i = 0; i < xs.size(); ++i) r[i] = p[0] + p[1] * xs[i] - (2 + 3 * xs[i]);
    };
    LmResult r = levenberg_marquardt(res, {0.0, 0.0}, {}, {});
    EXPECT_NEAR(r.x[0], 2.0, 1e-8);
    EXPECT_NEAR(r.x[1], 3.0, 1e-8);
    // X^T X = [[5, 10], [10, 30]], inverse = [[0.6, -0.2], [-0.2, 0.1]].
    ASSERT_EQ(r.jtj_inverse.size(), 4u);
    EXPECT_NEAR(r.jtj_inverse[0], 0.6, 1e-5);
    EXPECT_NEAR(r.jtj_inverse[1], -0.2, 1e-5);
    EXPECT_NEAR(r.jtj_inverse[3], 0.1, 1e-5);
}

TEST(LevenbergMarquardt, BoxBoundsHoldAtTheSolution) {
    // min (x - 3)^2 + (y + 1)^2 on x <= 2, y >= 0: the corner (2, 0).
    auto res = [](const Vector& p, Vector& r) { r.assign({p[0] - 3.0, p[1] + 1.0}); };
    LmResult r = levenberg_marquardt(res, {0.5, 0.5}, {-10, 0}, {2, 10});
    EXPECT_DOUBLE_EQ(r.x[0], 2.0);
    EXPECT_DOUBLE_EQ(r.x[1], 0.0);
}

TEST(LevenbergMarquardt, ExponentialDecayFromAFarStart) {
    // y = 5 exp(-0.7 t) sampled at 20 points; start at (1, 0.05).
    auto res = [](const Vector& p, Vector& r) {
        r.resize(20);
        for (int i = 0; i < 20; ++i) {
            double t = 0.25 * i;
            r[i] = p[0] * std::exp(-p[1] * t) - 5.0 * std::exp(-0.7 * t);
        }
    };
    LmResult r = levenberg_marquardt(res, {1.0, 0.05}, {}, {});
    EXPECT_NEAR(r.x[0], 5.0, 1e-7);
    EXPECT_NEAR(r.x[1], 0.7, 1e-8);
}

TEST(Nnls, ActiveConstraintAndKkt) {
    // A = I (3x3) scaled, b = (1, -2, 3): solution (1, 0, 3).
    Vector ata = {1, 0, 0, 0, 1, 0, 0, 0, 1}, atb = {1, -2, 3};
    Vector x = nnls_small(ata, atb, 3);
    EXPECT_NEAR(x[0], 1, 1e-12);
    EXPECT_EQ(x[1], 0);
    EXPECT_NEAR(x[2], 3, 1e-12);
    // Correlated columns: A = [[1, 1], [1, 0], [0, 1]] b = (2, 3, -1): unconstrained (3, -1) -> (x0 only).
    Vector ata2 = {2, 1, 1, 2}, atb2 = {5, 1};
    Vector y = nnls_small(ata2, atb2, 2);
    EXPECT_NEAR(y[0], 2.5, 1e-12);
    EXPECT_EQ(y[1], 0);
    // KKT: the gradient on the active entry points outwards (A^T (b - A x) <= 0 there).
    EXPECT_LE(atb2[1] - ata2[2] * y[0] - ata2[3] * y[1], 1e-12);
    // An unconstrained entry may go negative.
    Vector z = nnls_small(ata2, atb2, 2, {false, true});
    EXPECT_NEAR(z[0], 3, 1e-9);
    EXPECT_NEAR(z[1], -1, 1e-9);
}

TEST(SolveSpd, SingularSystemGetsAShift) {
    Vector A = {1, 1, 1, 1}, b = {2, 2}, x;
    ASSERT_TRUE(solve_spd(A, b, 2, x));
    EXPECT_NEAR(x[0] + x[1], 2.0, 1e-6);
}

}  // namespace
