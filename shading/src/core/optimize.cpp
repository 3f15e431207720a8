// Levenberg-Marquardt, small SPD solves and NNLS (optimize.h).
#include "shading/core/optimize.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>

namespace shading {

namespace {

double sumsq(const Vector& r) {
    double s = 0;
    for (double v : r) s += v * v;
    return s;
}

bool all_finite(const Vector& v) {
    for (double x : v)
        if (!std::isfinite(x)) return false;
    return true;
}

double lo_of(const Vector& lo, size_t j) { return lo.empty() ? -std::numeric_limits<double>::infinity() : lo[j]; }
double hi_of(const Vector& hi, size_t j) { return hi.empty() ? std::numeric_limits<double>::infinity() : hi[j]; }

void clamp_to(Vector& x, const Vector& lo, const Vector& hi) {
    for (size_t j = 0; j < x.size(); ++j) x[j] = std::clamp(x[j], lo_of(lo, j), hi_of(hi, j));
}

// Cholesky of A (n x n) in place (lower triangle); false if not positive definite.
bool cholesky(Vector& A, size_t n) {
    for (size_t j = 0; j < n; ++j) {
        double d = A[j * n + j];
        for (size_t k = 0; k < j; ++k) d -= A[j * n + k] * A[j * n + k];
        if (!(d > 0) || !std::isfinite(d)) return false;
        d = std::sqrt(d);
        A[j * n + j] = d;
        for (size_t i = j + 1; i < n; ++i) {
            double s = A[i * n + j];
            for (size_t k = 0; k < j; ++k) s -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = s / d;
        }
    }
    return true;
}

void cholesky_solve(const Vector& L, size_t n, Vector& x) {
    for (size_t i = 0; i < n; ++i) {
        double s = x[i];
        for (size_t k = 0; k < i; ++k) s -= L[i * n + k] * x[k];
        x[i] = s / L[i * n + i];
    }
    for (size_t i = n; i-- > 0;) {
        double s = x[i];
        for (size_t k = i + 1; k < n; ++k) s -= L[k * n + i] * x[k];
        x[i] = s / L[i * n + i];
    }
}

// Factorises A, shifting its diagonal by growing multiples of its scale when needed.
bool factor_shifted(Vector& A, size_t n) {
    double scale = 0;
    for (size_t j = 0; j < n; ++j) scale = std::max(scale, std::abs(A[j * n + j]));
    if (scale == 0) scale = 1;
    Vector orig = A;
    for (double shift = 0; shift < 1e3 * scale; shift = shift == 0 ? 1e-13 * scale : shift * 100) {
        A = orig;
        for (size_t j = 0; j < n; ++j) A[j * n + j] += shift;
        if (cholesky(A, n)) return true;
    }
    return false;
}

}  // namespace

bool solve_spd(Vector A, Vector b, size_t n, Vector& x) {
    if (!factor_shifted(A, n)) return false;
    cholesky_solve(A, n, b);
    x = std::move(b);
    return all_finite(x);
}

bool invert_spd(const Vector& A, size_t n, Vector& inv) {
    Vector L = A;
    if (!factor_shifted(L, n)) return false;
    inv.assign(n * n, 0.0);
    for (size_t j = 0; j < n; ++j) {
        Vector e(n, 0.0);
        e[j] = 1;
        cholesky_solve(L, n, e);
        for (size_t i = 0; i < n; ++i) inv[i * n + j] = e[i];
    }
    return all_finite(inv);
}

// ---------------------------------------------------------------- Levenberg-Marquardt

LmResult levenberg_marquardt(const ResidualFn& rfn, const Vector& x0, const Vector& lower, const Vector& upper,
                             const LmOptions& opt, const JacobianFn& jac) {
    const size_t n = x0.size();
    if ((!lower.empty() && lower.size() != n) || (!upper.empty() && upper.size() != n))
        throw std::invalid_argument("levenberg_marquardt: bounds must be empty or of the parameters' size");
    LmResult res;
    res.x = x0;
    clamp_to(res.x, lower, upper);
    Vector r, rt, J, xt(n);
    auto eval = [&](const Vector& x, Vector& out) -> bool {
        ++res.evaluations;
        try {
            rfn(x, out);
        } catch (const std::exception&) {
            return false;
        }
        return all_finite(out);
    };
    if (!eval(res.x, r)) throw std::invalid_argument("levenberg_marquardt: residuals not finite at the start point");
    const size_t m = r.size();
    double cost = 0.5 * sumsq(r);

    auto jacobian = [&](const Vector& x, const Vector& r0, Vector& Jout) {
        Jout.assign(m * n, 0.0);
        if (jac) {
            jac(x, r0, Jout);
            return;
        }
        Vector xp = x, rp;
        for (size_t j = 0; j < n; ++j) {
            double h = opt.fd_step * std::max(std::abs(x[j]), 1e-3);
            // Step inwards at an upper bound.
            if (x[j] + h > hi_of(upper, j)) h = -h;
            xp[j] = x[j] + h;
            if (!eval(xp, rp) || rp.size() != m) {
                xp[j] = x[j];
                continue;  // a column of zeros: that parameter does not move this iteration
            }
            for (size_t i = 0; i < m; ++i) Jout[i * n + j] = (rp[i] - r0[i]) / h;
            xp[j] = x[j];
        }
    };

    Vector JtJ(n * n), g(n), diag(n);
    double lambda = -1;
    bool need_jacobian = true;
    res.stop = "max iterations";
    for (res.iterations = 0; res.iterations < opt.max_iterations; ++res.iterations) {
        if (need_jacobian) {
            jacobian(res.x, r, J);
            std::fill(JtJ.begin(), JtJ.end(), 0.0);
            std::fill(g.begin(), g.end(), 0.0);
            for (size_t i = 0; i < m; ++i) {
                const double* Ji = &J[i * n];
                for (size_t a = 0; a < n; ++a) {
                    if (Ji[a] == 0) continue;
                    g[a] += Ji[a] * r[i];
                    for (size_t b = 0; b <= a; ++b) JtJ[a * n + b] += Ji[a] * Ji[b];
                }
            }
            for (size_t a = 0; a < n; ++a)
                for (size_t b = 0; b < a; ++b) JtJ[b * n + a] = JtJ[a * n + b];
            // Parameters pinned at a bound whose gradient pushes outwards do not move.
            double gmax = 0;
            for (size_t a = 0; a < n; ++a) {
                bool at_lo = res.x[a] <= lo_of(lower, a) && g[a] > 0;
                bool at_hi = res.x[a] >= hi_of(upper, a) && g[a] < 0;
                if (!(at_lo || at_hi)) gmax = std::max(gmax, std::abs(g[a]) / std::sqrt(std::max(JtJ[a * n + a], 1e-300)));
            }
            if (gmax <= opt.gtol * std::sqrt(std::max(2 * cost, 1e-300))) {
                res.converged = true;
                res.stop = "gradient";
                break;
            }
            for (size_t a = 0; a < n; ++a) diag[a] = std::max(diag[a], JtJ[a * n + a]);
            if (lambda < 0) lambda = opt.lambda0;  // relative: the damping term is lambda diag(J^T J)
            need_jacobian = false;
        }
        // (J^T J + lambda diag) dx = -g, projected onto the box.
        Vector A = JtJ, b(n), dx;
        for (size_t a = 0; a < n; ++a) {
            A[a * n + a] += lambda * std::max(diag[a], 1e-300);
            b[a] = -g[a];
        }
        if (!solve_spd(A, b, n, dx)) {
            lambda *= 10;
            continue;
        }
        for (size_t a = 0; a < n; ++a) xt[a] = res.x[a] + dx[a];
        clamp_to(xt, lower, upper);
        double step = 0, xnorm = 0;
        for (size_t a = 0; a < n; ++a) {
            step += (xt[a] - res.x[a]) * (xt[a] - res.x[a]);
            xnorm += res.x[a] * res.x[a];
        }
        step = std::sqrt(step);
        xnorm = std::sqrt(xnorm);
        if (step <= opt.xtol * (xnorm + opt.xtol)) {
            res.converged = true;
            res.stop = "step";
            break;
        }
        if (eval(xt, rt) && rt.size() == m) {
            double ct = 0.5 * sumsq(rt);
            if (ct < cost) {
                double rel = (cost - ct) / std::max(cost, 1e-300);
                res.x = xt;
                r.swap(rt);
                cost = ct;
                lambda = std::max(lambda / 10, 1e-12);
                need_jacobian = true;
                if (rel <= opt.ftol) {
                    res.converged = true;
                    res.stop = "cost";
                    ++res.iterations;
                    break;
                }
                continue;
            }
        }
        lambda *= 10;
        if (lambda > 1e16) {
            res.converged = true;
            res.stop = "damping (no downhill step)";
            break;
        }
    }
    res.cost = cost;
    // Covariance factor at the solution: free parameters only.
    jacobian(res.x, r, J);
    std::vector<size_t> freeidx;
    for (size_t a = 0; a < n; ++a)
        if (res.x[a] > lo_of(lower, a) && res.x[a] < hi_of(upper, a)) freeidx.push_back(a);
    const size_t nf = freeidx.size();
    Vector F(nf * nf, 0.0), Finv;
    for (size_t i = 0; i < m; ++i)
        for (size_t a = 0; a < nf; ++a)
            for (size_t b = 0; b < nf; ++b) F[a * nf + b] += J[i * n + freeidx[a]] * J[i * n + freeidx[b]];
    res.jtj_inverse.assign(n * n, 0.0);
    if (nf && invert_spd(F, nf, Finv))
        for (size_t a = 0; a < nf; ++a)
            for (size_t b = 0; b < nf; ++b) res.jtj_inverse[freeidx[a] * n + freeidx[b]] = Finv[a * nf + b];
    return res;
}

// ---------------------------------------------------------------- NNLS

Vector nnls_small(const Vector& ata, const Vector& atb, size_t n, const std::vector<bool>& unconstrained) {
    auto is_free = [&](size_t j) { return !unconstrained.empty() && unconstrained[j]; };
    std::vector<bool> passive(n, false);
    for (size_t j = 0; j < n; ++j) passive[j] = is_free(j);
    Vector x(n, 0.0);
    auto solve_passive = [&](Vector& z) {
        std::vector<size_t> P;
        for (size_t j = 0; j < n; ++j)
            if (passive[j]) P.push_back(j);
        z.assign(n, 0.0);
        if (P.empty()) return;
        const size_t k = P.size();
        Vector A(k * k), b(k), s;
        for (size_t a = 0; a < k; ++a) {
            b[a] = atb[P[a]];
            for (size_t c = 0; c < k; ++c) A[a * k + c] = ata[P[a] * n + P[c]];
        }
        if (!solve_spd(A, b, k, s)) return;
        for (size_t a = 0; a < k; ++a) z[P[a]] = s[a];
    };
    solve_passive(x);
    // Unconstrained start: if every constrained entry is already >= 0, done.
    for (int outer = 0; outer < int(3 * n + 3); ++outer) {
        // Fix negatives by moving towards the last feasible point (inner loop).
        Vector z;
        solve_passive(z);
        for (int inner = 0; inner < int(3 * n + 3); ++inner) {
            bool bad = false;
            for (size_t j = 0; j < n; ++j)
                if (passive[j] && !is_free(j) && z[j] <= 0) bad = true;
            if (!bad) break;
            double alpha = 1;
            for (size_t j = 0; j < n; ++j)
                if (passive[j] && !is_free(j) && z[j] <= 0) alpha = std::min(alpha, x[j] / std::max(x[j] - z[j], 1e-300));
            for (size_t j = 0; j < n; ++j) x[j] += alpha * (z[j] - x[j]);
            for (size_t j = 0; j < n; ++j)
                if (passive[j] && !is_free(j) && x[j] <= 1e-15) {
                    passive[j] = false;
                    x[j] = 0;
                }
            solve_passive(z);
        }
        x = z;
        // Gradient of 0.5 |Ax - b|^2 is ata x - atb; w = -gradient.
        size_t jmax = n;
        double wmax = 1e-14 * (1 + std::abs(*std::max_element(atb.begin(), atb.end())));
        for (size_t j = 0; j < n; ++j) {
            if (passive[j]) continue;
            double w = atb[j];
            for (size_t c = 0; c < n; ++c) w -= ata[j * n + c] * x[c];
            if (w > wmax) {
                wmax = w;
                jmax = j;
            }
        }
        if (jmax == n) break;
        passive[jmax] = true;
    }
    for (size_t j = 0; j < n; ++j)
        if (!is_free(j)) x[j] = std::max(0.0, x[j]);
    return x;
}

}  // namespace shading
