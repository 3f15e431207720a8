// Small dense optimisers for fitting models to data (POV-free, no dependencies):
//
//  * levenberg_marquardt(): nonlinear least squares min 0.5 |r(x)|^2 with box bounds
//    (steps are projected onto the box), Marquardt's diagonal scaling, and a forward-
//    difference Jacobian unless the caller supplies one;
//  * solve_spd(): the small symmetric (semi)definite solves LM needs, by Cholesky with a
//    diagonal shift when the matrix is singular;
//  * nnls_small(): non-negative linear least squares for a handful of unknowns (active set).
//
// Dimensions are small (a few to ~20 parameters); matrices are dense row-major vectors.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace shading {

using Vector = std::vector<double>;

// Residuals r(x) (size m, fixed for a problem). Throwing is allowed: the step is rejected.
using ResidualFn = std::function<void(const Vector& x, Vector& r)>;
// Jacobian J (m x n, row-major: J[i * n + j] = dr_i / dx_j) at x, given r(x).
using JacobianFn = std::function<void(const Vector& x, const Vector& r, Vector& J)>;

struct LmOptions {
    int max_iterations = 100;       // accepted or rejected steps
    double ftol = 1e-10;            // stop when the relative decrease of |r|^2 is below this
    double xtol = 1e-10;            // stop when the step is below xtol (|x| + xtol)
    double gtol = 1e-14;            // stop when the scaled gradient is below this
    double lambda0 = 1e-3;          // initial damping relative to max diag(J^T J)
    double fd_step = 1e-6;          // relative forward-difference step (when no JacobianFn)
};

struct LmResult {
    Vector x;
    double cost = 0;        // 0.5 |r|^2 at x
    int iterations = 0;
    int evaluations = 0;    // residual evaluations (Jacobian columns included)
    bool converged = false;
    std::string stop;       // why it stopped
    // Gauss-Newton covariance factor (J^T J)^-1 at x (n x n); parameters at a bound have
    // zero rows/columns. Multiply by the residual variance for a parameter covariance.
    Vector jtj_inverse;
};

// lower/upper may be empty (unbounded) or of x0's size (use +-infinity for one-sided).
LmResult levenberg_marquardt(const ResidualFn& r, const Vector& x0, const Vector& lower, const Vector& upper,
                             const LmOptions& opt = {}, const JacobianFn& jac = nullptr);

// Solves A x = b for symmetric positive (semi)definite A (n x n); a singular A gets a small
// diagonal shift. Returns false only if no shift makes it factorisable.
bool solve_spd(Vector A, Vector b, size_t n, Vector& x);
// Inverse of a symmetric positive (semi)definite matrix (same shift rule).
bool invert_spd(const Vector& A, size_t n, Vector& inv);

// min |A x - b|^2 subject to x >= 0, given the normal equations ata = A^T A (n x n) and
// atb = A^T b (n small): an active-set method (Lawson-Hanson) on the normal equations.
// Entries flagged in `unconstrained` (may be empty) may be negative.
Vector nnls_small(const Vector& ata, const Vector& atb, size_t n, const std::vector<bool>& unconstrained = {});

}  // namespace shading
