// Exact subsurface profile tables: built from run_transport_mc, stored as .ssp files, evaluated
// per channel. See ss_profile.h and shading/DIPOLE.md ("Exact profiles", "Profile tables").
#include "shading/subsurface/ss_profile.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <sstream>

#include "shading/brdf/fresnel.h"
#include "shading/core/bytes.h"
#include "shading/core/quadrature.h"

namespace shading {

namespace {

constexpr double kTiny = 1e-37;  // floor of profile values before taking logs (float32 range)

std::string num(double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.9g", v);
    return buf;
}

std::string hex64(std::uint64_t v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%016llx", static_cast<unsigned long long>(v));
    return buf;
}

// Critical inside cosine of a face: light inside with mu below it is totally reflected.
double critical_cos(double eta) { return eta > 1.0 ? std::sqrt(1.0 - 1.0 / (eta * eta)) : 0.0; }

// Nodes of the inside-radiance samples on (0, 1], increasing, the last 1: those of
// McSettings::radiance_cosines (the Monte Carlo's next-event estimate is made there).
double angle_node(int j, int n) { return 0.5 * (1.0 - std::cos(kPi * (j + 0.5) / (n - 0.5))); }
// Lagrange polynomial through (angle_node(j), v[j]) evaluated at mu.
double angle_poly(const std::vector<double>& v, double mu) {
    const int n = int(v.size());
    double sum = 0;
    for (int j = 0; j < n; ++j) {
        const double xj = angle_node(j, n);
        double l = 1.0;
        for (int i = 0; i < n; ++i)
            if (i != j) l *= (mu - angle_node(i, n)) / (xj - angle_node(i, n));
        sum += l * v[j];
    }
    return sum;
}

// 2 integral_0^1 Ft(mu_o) I(mu'(mu_o)) / eta^2 mu_o dmu_o of stored samples pi I / M: the exit
// distribution's integral (1 up to the interpolant's error).
double exit_integral(const std::vector<double>& samples, double eta) {
    double sum = 0;
    const int steps = 512;
    for (int i = 0; i < steps; ++i) {
        const double mo = (i + 0.5) / steps;
        const double mi = std::sqrt(std::max(0.0, 1.0 - (1.0 - mo * mo) / (eta * eta)));
        sum += 2.0 * (1.0 - fresnel_dielectric(mo, eta)) * std::max(0.0, angle_poly(samples, mi)) * mo / steps;
    }
    return sum / (eta * eta);
}

// ---------------------------------------------------------------- the radial interpolant
// Node 0 at rho = 0, nodes b >= 1 uniformly spaced in x = ln rho. Segment 0 [0, rho_1] is linear
// in rho between the two values; segments b >= 1 are cubic Hermite in x on y = ln Rd with
// central-difference tangents (one-sided at the ends): C1 everywhere from rho_1 on.
struct RadialCurve {
    const double* rho = nullptr;  // nodes
    const double* y = nullptr;    // ln value at the nodes
    int n = 0;
    double h = 1;                 // node spacing in ln rho

    double tangent(int b) const {
        if (b <= 1) return (y[2] - y[1]) / h;
        if (b >= n - 1) return (y[n - 1] - y[n - 2]) / h;
        return (y[b + 1] - y[b - 1]) / (2 * h);
    }
    // Value in segment b (rho in [rho[b], rho[b+1]]).
    double eval_in(int b, double r) const {
        if (b == 0) {
            const double t = r / rho[1];
            return std::exp(y[0]) * (1 - t) + std::exp(y[1]) * t;
        }
        const double t = (std::log(r) - std::log(rho[b])) / h;
        const double t2 = t * t, t3 = t2 * t;
        const double v = (2 * t3 - 3 * t2 + 1) * y[b] + (t3 - 2 * t2 + t) * h * tangent(b) + (-2 * t3 + 3 * t2) * y[b + 1] +
                         (t3 - t2) * h * tangent(b + 1);
        return std::exp(v);
    }
    int segment(double r) const {
        if (!(r > rho[1])) return 0;
        int b = 1 + int(std::floor((std::log(r) - std::log(rho[1])) / h));
        return std::clamp(b, 1, n - 2);
    }
    double eval(double r) const { return eval_in(segment(r), r); }
    // Integral of 2 pi r value(r) over [r1, r2] inside segment b.
    double integral_in(int b, double r1, double r2) const {
        if (!(r2 > r1)) return 0.0;
        double sum = 0;
        if (b == 0) {
            for (int i = 0; i < 8; ++i) {
                const double r = r1 + (r2 - r1) * kGaussLegendre8UnitX[i];
                sum += kGaussLegendre8UnitW[i] * 2 * kPi * r * eval_in(0, r);
            }
            return sum * (r2 - r1);
        }
        const double x1 = std::log(r1), x2 = std::log(r2);
        for (int i = 0; i < 8; ++i) {
            const double r = std::exp(x1 + (x2 - x1) * kGaussLegendre8UnitX[i]);
            sum += kGaussLegendre8UnitW[i] * 2 * kPi * r * r * eval_in(b, r);
        }
        return sum * (x2 - x1);
    }
    // Integral of 2 pi r value over [r1, r2] (within the nodes' range).
    double integral(double r1, double r2) const {
        double sum = 0;
        int b = segment(r1);
        const int last = segment(r2);
        for (; b <= last; ++b) {
            const double lo = std::max(r1, rho[b]), hi = std::min(r2, rho[b + 1]);
            sum += integral_in(b, lo, hi);
        }
        return sum;
    }
};

// The largest tail amplitude and radius-node value a file may hold (the loader's bound).
constexpr double kMaxTailAmplitude = 1e30;

// Radial node positions of the tables: 0, then the geometric centres of bins 1 .. count-1.
std::vector<double> node_positions(const RadialBins& bins) {
    std::vector<double> r(bins.count);
    r[0] = 0.0;
    for (int b = 1; b < bins.count; ++b) r[b] = std::sqrt(bins.inner(b) * bins.outer(b));
    return r;
}

// Tail shape (1 + k rho) exp(-k rho) / rho^3 and its integral of 2 pi rho from R to infinity.
double tail_shape(double k, double rho) { return (1 + k * rho) * std::exp(-k * rho) / (rho * rho * rho); }
double tail_flux(double k, double R) { return 2 * kPi * std::exp(-k * R) / R; }

// ---------------------------------------------------------------- processing of the tallies

struct Diagnostics {
    double worst_tail_ratio = 1;  // flux-matched / fitted tail amplitude, farthest from 1
    double worst_deconv = 0;      // largest relative mismatch of annulus means left after deconvolution
    double worst_angle_rms = 0;   // flux-weighted rms relative residual of the high orders' angular fit
    double worst_radiance_flux = 0;  // |exitance implied by the angular samples / the exits' total - 1|
    int dropped_tails = 0;           // tails whose amplitude would overflow the file (noise-only faces)
    int noisy_angles = 0;            // faces whose angular samples were normalised by their own flux
};

void process_face(const McFace& f, const McSettings& mc, int k, double g, double eta, FaceRecord& rec,
                  Diagnostics& diag) {
    const RadialBins& bins = mc.bins;
    const int nb = bins.count;
    const double alpha = mc.albedos[k];
    rec.multi = f.multi[k];
    rec.single = f.single[k];
    rec.ballistic = f.ballistic[k];

    // Bin means and where they stop being reliable (relative error above 5 % beyond 1 mfp').
    std::vector<double> m(nb), se(nb);
    for (int b = 0; b < nb; ++b) {
        m[b] = f.radial[std::size_t(k) * nb + b];
        se[b] = f.radial_se[std::size_t(k) * nb + b];
    }
    const int b_one = bins.index(1.0);
    int b_end = nb;
    for (int b = b_one; b < nb; ++b)
        if (!(m[b] > 0) || se[b] > 0.05 * m[b]) {
            b_end = b;
            break;
        }
    // Below 1 mfp' a bin can be empty only for a vanishing profile: keep it positive for the logs.
    double floor_v = kTiny;
    for (int b = 0; b < b_end; ++b) floor_v = std::max(floor_v, m[b] * 1e-12);
    for (int b = 0; b < b_end; ++b) m[b] = std::max(m[b], floor_v);

    // Matched tail beyond rho_t: the asymptotic transport decay rate, amplitude from the flux the
    // Monte Carlo puts beyond rho_t (so the profile integrates to the total).
    const double k_tr = transport_decay_rate(alpha, g) / (1.0 - alpha * g);
    const double rho_t = bins.inner(b_end < nb ? b_end : nb - 1);
    double inside = 0;
    for (int b = 0; b < b_end; ++b) inside += m[b] * bins.area(b);
    const double beyond = rec.multi - inside;
    double a_fit = 0;
    {
        int n = 0;
        for (int b = std::max(1, b_end - 3); b < b_end; ++b, ++n) {
            const double c = std::sqrt(bins.inner(b) * bins.outer(b));
            a_fit += m[b] / tail_shape(k_tr, c);
        }
        a_fit = n > 0 ? a_fit / n : 0.0;
    }
    // Where the tail carries more than 1 % of the total (high albedo, the asymptotic regime from a
    // few mfp' on) its amplitude conserves the flux; below that (the tail holds a negligible flux
    // but is not yet asymptotic where the data stop) it continues the data with one of two
    // two-parameter forms fitted to the last (up to 6) reliable bins beyond 1 mfp':
    //   power:      Rd = A exp(-k rho) rho^-p                 (a local power law)
    //   asymptotic: Rd = exp(-k rho) rho^-2 (c0 + c1 / rho)   (the far field's family; the dipole's
    //                                                          (1 + k rho) exp(-k rho) / rho^3 is one)
    // chosen by cross-validation: each fitted to all but the last two of those bins, the one that
    // predicts those two better is refitted to all. (Either alone was 12 % off two bins beyond the
    // data in some media: the power law where the decay steepens, the asymptotic form at low
    // albedo without anisotropy, where the asymptotic regime starts much later.)
    const bool flux_tail = beyond > 0.01 * rec.multi;
    double a = 0;
    if (k_tr * rho_t < 600) {
        a = flux_tail ? beyond / tail_flux(k_tr, rho_t) : a_fit;
        // A face with almost no exits (transmission through a thick slab at low albedo) can put
        // a few noisy exits beyond a radius where the asymptotic decay is already e^-70: its
        // flux-matched amplitude then exceeds what the file stores (kMaxTailAmplitude). Such a
        // tail holds nothing a render can see; it is dropped and counted.
        if (!(std::isfinite(a) && a >= 0)) a = 0;
        if (a > kMaxTailAmplitude) {
            a = 0;
            ++diag.dropped_tails;
        }
    }
    struct TailFit {
        int kind = -1;  // 0 power (p0 = ln A, p1 = p), 1 asymptotic (p0 = c0, p1 = c1); -1 none
        double p0 = 0, p1 = 0;
        double at(double r, double k) const {
            if (kind == 0) return std::exp(p0 - k * r - p1 * std::log(r));
            return std::exp(-k * r) / (r * r) * (p0 + p1 / r);
        }
    };
    // Weighted least squares of one form over bins [b0, b1) (weights from relative errors).
    auto fit = [&](int kind, int b0, int b1) {
        double A00 = 0, A01 = 0, A11 = 0, v0 = 0, v1 = 0;
        int n = 0;
        for (int b = b0; b < b1; ++b, ++n) {
            const double c = std::sqrt(bins.inner(b) * bins.outer(b));
            const double rel = se[b] > 0 ? se[b] / m[b] : 1.0;
            double x, y, w;
            if (kind == 0) {  // ln m + k rho = ln A - p ln rho
                x = -std::log(c);
                y = std::log(m[b]) + k_tr * c;
                w = 1.0 / (rel * rel);
            } else {  // m exp(k rho) rho^2 = c0 + c1 / rho
                x = 1.0 / c;
                y = m[b] * std::exp(k_tr * c) * c * c;
                w = 1.0 / (rel * rel * y * y);
            }
            A00 += w;
            A01 += w * x;
            A11 += w * x * x;
            v0 += w * y;
            v1 += w * x * y;
        }
        TailFit f;
        const double det = A00 * A11 - A01 * A01;
        if (n < 2 || !(det > 0)) return f;
        f.p0 = (v0 * A11 - v1 * A01) / det;
        f.p1 = (A00 * v1 - A01 * v0) / det;
        const bool ok = kind == 0 ? (std::isfinite(f.p0) && std::isfinite(f.p1) && f.p1 > 0)
                                  : (std::isfinite(f.p0) && std::isfinite(f.p1) && f.p0 >= 0 && f.p0 + f.p1 / rho_t > 0);
        if (ok) f.kind = kind;
        return f;
    };
    TailFit tail;
    const int first = std::max(b_one, b_end - 6);
    if (!flux_tail && k_tr * rho_t < 600 && b_end - first >= 3) {
        double best = std::numeric_limits<double>::infinity();
        int choice = -1;
        for (int kind : {0, 1}) {
            const TailFit f = b_end - first >= 5 ? fit(kind, first, b_end - 2) : fit(kind, first, b_end);
            if (f.kind < 0) continue;
            double err = 0;
            for (int b = std::max(first, b_end - 2); b < b_end; ++b) {
                const double c = std::sqrt(bins.inner(b) * bins.outer(b));
                err += sqr(std::log(f.at(c, k_tr) / m[b]));
            }
            if (err < best) {
                best = err;
                choice = kind;
            }
        }
        if (choice >= 0) tail = fit(choice, first, b_end);
    }
    if (std::getenv("SSTOOL_DEBUG"))
        std::fprintf(stderr, "  albedo %.6f: b_end %d rho_t %.3g k %.4g inside %.5g of %.5g, a flux %.4g fit %.4g, tail form %d (%.4g, %.4g)\n",
                     alpha, b_end, rho_t, k_tr, inside, rec.multi, a, a_fit, tail.kind, tail.p0, tail.p1);
    if (a > 0 && a_fit > 0) {
        const double ratio = a / a_fit;
        if (std::fabs(std::log(ratio)) > std::fabs(std::log(diag.worst_tail_ratio))) diag.worst_tail_ratio = ratio;
    }
    rec.tail_k = k_tr;
    rec.tail_a = a;
    rec.rho_tail = rho_t;

    // Node values: the bin means, then corrected until the interpolant's annulus means equal them.
    const std::vector<double> rho = node_positions(bins);
    std::vector<double> y(nb);
    for (int b = 0; b < nb; ++b) {
        double v;
        if (b < b_end) v = m[b];
        else if (tail.kind >= 0) v = tail.at(rho[b], k_tr);
        else v = a * tail_shape(k_tr, rho[b]);
        y[b] = std::log(std::max(v, kTiny));
    }
    RadialCurve c{rho.data(), y.data(), nb, std::log(10.0) / bins.per_decade};
    // The central disc (bin 0) keeps its mean as the value at rho = 0: it holds a negligible
    // part of the flux and few samples, and its linear segment cannot follow the noise.
    for (int it = 0; it < 8; ++it) {
        double worst = 0;
        std::vector<double> ratio(b_end, 1.0);
        for (int b = 1; b < b_end; ++b) {
            const double lo = bins.inner(b), hi = std::min(bins.outer(b), rho[nb - 1]);
            const double mean = c.integral(lo, hi) / (kPi * (hi * hi - lo * lo));
            ratio[b] = mean > 0 ? m[b] / mean : 1.0;
            worst = std::max(worst, std::fabs(ratio[b] - 1.0));
        }
        if (it == 7) {
            diag.worst_deconv = std::max(diag.worst_deconv, worst);
            if (std::getenv("SSTOOL_DEBUG") && worst > 0.01)
                for (int b = 1; b < b_end; ++b)
                    if (std::fabs(ratio[b] - 1) > 0.01)
                        std::fprintf(stderr, "  albedo %.6f deconvolution: bin %d [%.3g, %.3g) mean %.4g ratio %.3f (b_end %d)\n", alpha, b,
                                     bins.inner(b), bins.outer(b), m[b], ratio[b], b_end);
        }
        for (int b = 1; b < b_end; ++b) y[b] += std::log(ratio[b]);
    }
    rec.profile.resize(nb);
    for (int b = 0; b < nb; ++b) rec.profile[b] = std::exp(y[b]);

    // Angular distribution of the light reaching the face from inside (inside radiance I(mu)):
    // orders 2 .. radiance_orders from the next-event estimate at the nodes (exact in
    // expectation, low variance), higher orders (diffusive, smooth) from a quadratic fitted to
    // their histogram by weighted least squares.
    const int na = mc.angle_bins;
    const std::vector<double> nodes = mc.radiance_cosines();
    const int J = int(nodes.size());
    std::vector<double> I(J, 0.0);
    for (int j = 0; j < J; ++j) I[j] = f.radiance.empty() ? 0.0 : f.radiance[std::size_t(k) * J + j];
    {
        // flux in bin a = 2 pi integral over the bin of (c0 + c1 mu + c2 mu^2) mu dmu
        double A[3][3] = {{0}}, b[3] = {0};
        double flux = 0;
        for (int ab = 0; ab < na; ++ab) {
            const double v = f.arrivals[std::size_t(k) * na + ab];
            if (!(v > 0)) continue;
            flux += v;
            const double lo = double(ab) / na, hi = double(ab + 1) / na;
            double row[3];
            for (int p = 0; p < 3; ++p) row[p] = 2 * kPi * (std::pow(hi, p + 2) - std::pow(lo, p + 2)) / (p + 2);
            for (int p = 0; p < 3; ++p) {
                for (int q = 0; q < 3; ++q) A[p][q] += row[p] * row[q] / v;  // weight 1 / v (Poisson-like)
                b[p] += row[p];                                             // v * row / v
            }
        }
        double c[3] = {0, 0, 0};
        if (flux > 0) {
            // 3x3 normal equations, Gaussian elimination with partial pivoting
            for (int p = 0; p < 3; ++p) {
                int piv = p;
                for (int q = p + 1; q < 3; ++q)
                    if (std::fabs(A[q][p]) > std::fabs(A[piv][p])) piv = q;
                std::swap(A[p], A[piv]);
                std::swap(b[p], b[piv]);
                if (A[p][p] == 0) continue;
                for (int q = p + 1; q < 3; ++q) {
                    const double m = A[q][p] / A[p][p];
                    for (int r = p; r < 3; ++r) A[q][r] -= m * A[p][r];
                    b[q] -= m * b[p];
                }
            }
            for (int p = 3; p-- > 0;) {
                double v = b[p];
                for (int q = p + 1; q < 3; ++q) v -= A[p][q] * c[q];
                c[p] = A[p][p] != 0 ? v / A[p][p] : 0.0;
            }
            double res = 0;
            for (int ab = 0; ab < na; ++ab) {
                const double v = f.arrivals[std::size_t(k) * na + ab];
                if (!(v > 0)) continue;
                const double lo = double(ab) / na, hi = double(ab + 1) / na;
                double model = 0;
                for (int p = 0; p < 3; ++p) model += c[p] * 2 * kPi * (std::pow(hi, p + 2) - std::pow(lo, p + 2)) / (p + 2);
                res += v * sqr(model / v - 1.0);
            }
            if (flux > 0.1 * rec.multi) diag.worst_angle_rms = std::max(diag.worst_angle_rms, std::sqrt(res / flux));
        }
        for (int j = 0; j < J; ++j) I[j] += std::max(0.0, c[0] + c[1] * nodes[j] + c[2] * nodes[j] * nodes[j]);
    }
    // Exitance implied by I: 2 pi integral of Ft(mu_o) I(mu'(mu_o)) / eta^2 mu_o dmu_o; against
    // the exits' own total it checks the two estimates (diagnostic).
    double norm = 0;
    const int steps = 512;
    for (int i = 0; i < steps; ++i) {
        const double mo = (i + 0.5) / steps;
        const double mi = std::sqrt(std::max(0.0, 1.0 - (1.0 - mo * mo) / (eta * eta)));
        norm += 2.0 * (1.0 - fresnel_dielectric(mo, eta)) * std::max(0.0, angle_poly(I, mi)) * mo / steps;
    }
    const double implied = kPi * norm / (eta * eta);
    if (rec.multi > 1e-4) {
        diag.worst_radiance_flux = std::max(diag.worst_radiance_flux, std::fabs(implied / rec.multi - 1.0));
        if (std::getenv("SSTOOL_DEBUG"))
            std::fprintf(stderr, "  g %.2f eta %.2f albedo %.6f: angular flux %.5g exits %.5g (%+.4f); I/I(1) at nodes:", g, eta, alpha,
                         implied, rec.multi, implied / rec.multi - 1.0);
        if (std::getenv("SSTOOL_DEBUG")) {
            for (int j = 0; j < J; ++j) std::fprintf(stderr, " %.3f", I[j] / I[J - 1]);
            std::fprintf(stderr, "\n");
        }
    }
    // Stored as pi I / M with M the exits' own total: exit_factor = Ft(mu_o) [pi I / M] / eta^2
    // is then pi L / M at every sampled direction without the interpolant's integral in it (that
    // integral is the diagnostic above).
    // Where the two estimates of the face's exitance disagree by more than a factor 2 (a face
    // with a handful of exits: thick slabs' transmission at low albedo), the exits' total is
    // noise and the ratio can reach 1e6; the angular shape is then normalised by its own flux,
    // so exit_factor integrates to the face's total as everywhere else.
    double norm_flux = rec.multi;
    if (rec.multi > 0 && implied > 0 && std::fabs(std::log(implied / rec.multi)) > std::log(2.0)) {
        norm_flux = implied;
        ++diag.noisy_angles;
    }
    rec.angle.resize(J);
    for (int j = 0; j < J; ++j) rec.angle[j] = norm_flux > 0 ? kPi * I[j] / norm_flux : 1.0;
}

std::uint64_t node_seed(std::uint64_t seed, int node, int incidence) {
    std::uint64_t x = seed * 0x9e3779b97f4a7c15ULL + std::uint64_t(node) * 0xbf58476d1ce4e5b9ULL +
                      std::uint64_t(incidence + 1) * 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return x;
}

// ---------------------------------------------------------------- file image helpers

void put32(std::vector<std::uint8_t>& b, std::uint32_t v) {
    for (int k = 0; k < 4; ++k) b.push_back(std::uint8_t(v >> (8 * k)));
}
void put64(std::vector<std::uint8_t>& b, std::uint64_t v) {
    put32(b, std::uint32_t(v));
    put32(b, std::uint32_t(v >> 32));
}
void putf64(std::vector<std::uint8_t>& b, double d) {
    std::uint64_t u;
    std::memcpy(&u, &d, 8);
    put64(b, u);
}
void putf32(std::vector<std::uint8_t>& b, double d) {
    const float f = float(d);
    std::uint32_t u;
    std::memcpy(&u, &f, 4);
    put32(b, u);
}
std::uint32_t get32(const std::uint8_t* p) {
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
std::uint64_t get64(const std::uint8_t* p) { return std::uint64_t(get32(p)) | std::uint64_t(get32(p + 4)) << 32; }
double getf64(const std::uint8_t* p) {
    const std::uint64_t u = get64(p);
    double d;
    std::memcpy(&d, &u, 8);
    return d;
}
float getf32(const std::uint8_t* p) {
    const std::uint32_t u = get32(p);
    float f;
    std::memcpy(&f, &u, 4);
    return f;
}

constexpr char kMagic[8] = {'P', 'V', 'S', 'S', 'P', 'R', 'O', 'F'};
constexpr std::size_t kFixedHeader = 160;
constexpr std::uint32_t kFlagTransmission = 1;
constexpr int kFixedFields = 6;  // multi, single, ballistic, tail_k, tail_a, rho_tail

int record_floats(const ProfileBuildSettings& s) {
    return kFixedFields + s.angle_nodes + int(s.cos_inside.size()) + s.bins.count;
}

}  // namespace

// ---------------------------------------------------------------- settings

ProfileBuildSettings default_profile_build_settings() {
    ProfileBuildSettings s;
    s.g = {0.0, 0.2, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95};
    s.eta = {1.0, 1.1, 1.2, 1.3, 1.33, 1.4, 1.5, 1.6, 1.8, 2.0};
    return s;
}

std::string ProfileBuildSettings::validate() const {
    auto axis = [](const std::vector<double>& v, const char* name, double lo, double hi, bool allow_inf) -> std::string {
        if (v.empty() || v.size() > 64) return std::string(name) + ": expected 1 to 64 values";
        for (std::size_t i = 0; i < v.size(); ++i) {
            const bool ok = (v[i] >= lo && v[i] <= hi) || (allow_inf && v[i] == kInf);
            if (!ok) return std::string(name) + " = " + num(v[i]) + ": expected a value in [" + num(lo) + ", " + num(hi) + "]";
            if (i > 0 && !(v[i] > v[i - 1])) return std::string(name) + ": expected strictly increasing values";
        }
        return "";
    };
    std::string e;
    if (!(e = axis(g, "g", 0.0, 0.99, false)).empty()) return e;
    if (!(e = axis(eta, "eta", 1.0, 4.0, false)).empty()) return e;
    if (!(e = axis(thickness, "thickness", 1e-3, 1e6, true)).empty()) return e;
    if (!(e = axis(cos_inside, "cos_inside", 0.01, 1.0, false)).empty()) return e;
    if (cos_inside.back() != 1.0) return "cos_inside: expected the last value to be 1 (normal incidence)";
    if (!(u_0 >= 0 && u_step > 0 && albedos >= 4 && albedos <= 1000 && u_0 + (albedos - 1) * u_step <= 30))
        return "albedo nodes: expected u_0 >= 0, u_step > 0, 4 to 1000 nodes, u at most 30";
    if (!(bins.rho_0 > 0 && std::isfinite(bins.rho_0)) || bins.per_decade < 1 || bins.per_decade > 100 || bins.count < 4 ||
        bins.count > 1000)
        return "radial bins: expected rho_0 > 0, 1 to 100 per decade, 4 to 1000 bins";
    if (angle_bins < 4 || angle_bins > 1000 || angle_nodes < 2 || angle_nodes > 32 || !(radiance_orders >= 2 && radiance_orders <= 1e5))
        return "angles: expected 4 to 1000 bins, 2 to 32 nodes and radiance_orders in [2, 1e5]";
    if (photons < 1 || !(short_orders >= 1) || !(roulette_order >= 1) || !(oblique_fraction > 0 && oblique_fraction <= 1))
        return "photons: expected photons >= 1, short_orders >= 1, roulette_order >= 1, oblique_fraction in (0, 1]";
    return "";
}

// ---------------------------------------------------------------- tables

const FaceRecord& ProfileTables::record(int ig, int ie, int id, int face, int k) const {
    const std::size_t ne = settings.eta.size(), nd = settings.thickness.size();
    const std::size_t i = (((std::size_t(ig) * ne + ie) * nd + id) * faces + face) * settings.albedos + k;
    return records.at(i);
}

double ProfileTables::angle_cosine(int j) const { return angle_node(j, settings.angle_nodes); }

double ProfileTables::node_rho(int b) const {
    return b <= 0 ? 0.0 : std::sqrt(settings.bins.inner(b) * settings.bins.outer(b));
}

bool ProfileTables::stale(const ProfileBuildSettings& w) const {
    const ProfileBuildSettings& s = settings;
    return generator_version != kProfileGeneratorVersion || s.g != w.g || s.eta != w.eta || s.thickness != w.thickness ||
           s.cos_inside != w.cos_inside || s.u_0 != w.u_0 || s.u_step != w.u_step || s.albedos != w.albedos ||
           s.bins.rho_0 != w.bins.rho_0 || s.bins.per_decade != w.bins.per_decade || s.bins.count != w.bins.count ||
           s.angle_bins != w.angle_bins || s.angle_nodes != w.angle_nodes || s.radiance_orders != w.radiance_orders ||
           s.photons != w.photons ||
           s.short_photons != w.short_photons || s.short_orders != w.short_orders || s.roulette_order != w.roulette_order ||
           s.oblique_fraction != w.oblique_fraction || s.seed != w.seed;
}

std::string ProfileTables::describe() const {
    const ProfileBuildSettings& s = settings;
    std::ostringstream o;
    auto list = [&](const std::vector<double>& v) {
        std::string t;
        for (double x : v) t += (t.empty() ? "" : ",") + (x == kInf ? std::string("inf") : num(x));
        return t;
    };
    o << "exact subsurface profiles, generator " << generator_version << ", " << (faces == 2 ? "slabs" : "semi-infinite")
      << "\n  g: " << list(s.g) << "\n  eta: " << list(s.eta) << "\n  thickness (mfp): " << list(s.thickness)
      << "\n  albedo: " << s.albedos << " nodes, u = -ln(1 - alpha) from " << num(s.u_0) << " step " << num(s.u_step)
      << " (alpha " << num(albedo(0)) << " .. " << num(albedo(s.albedos - 1)) << ")"
      << "\n  radius: " << s.bins.count << " nodes, 0 and " << s.bins.per_decade << " per decade from "
      << num(s.bins.rho_0) << " transport mfp"
      << "\n  inside incidence cosines: " << list(s.cos_inside) << "\n  angle: " << s.angle_nodes
      << " inside-radiance samples (next-event to " << num(s.radiance_orders) << "/(1-g) events, then " << s.angle_bins
      << " bins)"
      << "\n  photons per node: " << s.photons << " + " << s.short_photons << " short (" << num(s.short_orders)
      << "/(1-g) events), roulette from " << num(s.roulette_order) << "/(1-g) events, oblique " << num(s.oblique_fraction)
      << ", seed " << s.seed << "\n  records: " << records.size() << ", " << record_floats(s) << " floats each\n";
    return o.str();
}

std::shared_ptr<ProfileTables> build_profile_tables(const ProfileBuildSettings& s,
                                                    const std::function<void(const std::string&)>& log) {
    const std::string bad = s.validate();
    if (!bad.empty()) throw std::invalid_argument("profile tables: " + bad);
    const auto t0 = std::chrono::steady_clock::now();
    auto t = std::make_shared<ProfileTables>();
    t->settings = s;
    t->faces = 1;
    for (double d : s.thickness)
        if (d != kInf) t->faces = 2;
    t->records.resize(s.g.size() * s.eta.size() * s.thickness.size() * t->faces * s.albedos);
    std::vector<double> albedo_nodes(s.albedos);
    for (int k = 0; k < s.albedos; ++k) albedo_nodes[k] = t->albedo(k);

    // One Monte Carlo run per (g, thickness) serves every eta at once (transport_mc.h).
    const std::size_t ne = s.eta.size(), nd = s.thickness.size();
    auto rec_at = [&](std::size_t ig, std::size_t ie, std::size_t id, int face, int k) -> FaceRecord& {
        return t->records[(((ig * ne + ie) * nd + id) * t->faces + face) * s.albedos + k];
    };
    int run = 0;
    for (std::size_t ig = 0; ig < s.g.size(); ++ig)
        for (std::size_t id = 0; id < nd; ++id, ++run) {
            const double g = s.g[ig];
            const auto tn = std::chrono::steady_clock::now();
            McSettings mc;
            mc.g = g;
            mc.eta = s.eta;
            mc.thickness = s.thickness[id];
            mc.photons = s.photons;
            mc.short_photons = s.short_photons;
            mc.short_orders = int(std::ceil(s.short_orders / (1.0 - g)));
            mc.roulette_order = s.roulette_order / (1.0 - g);
            mc.threads = s.threads;
            mc.albedos = albedo_nodes;
            mc.bins = s.bins;
            mc.angle_bins = s.angle_bins;
            mc.radiance_orders = int(std::ceil(s.radiance_orders / (1.0 - g)));
            mc.radiance_nodes = s.angle_nodes;
            mc.seed = node_seed(s.seed, run, -1);
            const McResult normal = run_transport_mc(mc);
            Diagnostics diag;
            std::uint64_t steps = normal.steps;
            for (std::size_t ie = 0; ie < ne; ++ie)
                for (int face = 0; face < t->faces; ++face)
                    for (int k = 0; k < s.albedos; ++k) {
                        FaceRecord& rec = rec_at(ig, ie, id, face, k);
                        process_face(face == 0 ? normal.top[ie] : normal.bottom[ie], normal.settings, k, g, s.eta[ie], rec,
                                     diag);
                        rec.incidence.assign(s.cos_inside.size(), 1.0);
                    }
            // Incidence factor: totals only, fewer photons.
            int clamped = 0;
            McSettings ob = mc;
            ob.radial = false;
            ob.radiance_orders = 0;
            ob.photons = std::max<std::uint64_t>(1, std::uint64_t(double(s.photons) * s.oblique_fraction));
            ob.short_photons = std::uint64_t(double(s.short_photons) * s.oblique_fraction);
            for (std::size_t ic = 0; ic + 1 < s.cos_inside.size(); ++ic) {
                ob.cos_inside = s.cos_inside[ic];
                ob.seed = node_seed(s.seed, run, int(ic));
                const McResult r = run_transport_mc(ob);
                steps += r.steps;
                for (std::size_t ie = 0; ie < ne; ++ie)
                    for (int face = 0; face < t->faces; ++face)
                        for (int k = 0; k < s.albedos; ++k) {
                            FaceRecord& rec = rec_at(ig, ie, id, face, k);
                            const double m = (face == 0 ? r.top[ie] : r.bottom[ie]).multi[k];
                            // A ratio outside [0.05, 20] is noise of a run with too few paths for
                            // this albedo (the physical factor stays within a few tenths of 1):
                            // clamped, and counted in the log.
                            double ratio = rec.multi > 0 && m > 0 ? m / rec.multi : 1.0;
                            if (ratio < 0.05 || ratio > 20) ++clamped;
                            rec.incidence[ic] = std::clamp(ratio, 0.05, 20.0);
                        }
            }
            if (log) {
                char buf[520];
                const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - tn).count();
                std::snprintf(buf, sizeof buf,
                              "g=%g d=%g (%zu etas): %.2f s, %.3g flights, %d threads; tail amplitude flux/fit worst %.3f, "
                              "deconvolution residual %.1e, high-order angle fit rms residual worst %.3f, angular/exit "
                              "flux mismatch worst %.4f, incidence factors clamped %d, noise-only tails dropped %d, angular "
                              "samples normalised by their own flux %d",
                              g, s.thickness[id], ne, sec, double(steps), normal.threads_used, diag.worst_tail_ratio,
                              diag.worst_deconv, diag.worst_angle_rms, diag.worst_radiance_flux, clamped, diag.dropped_tails,
                              diag.noisy_angles);
                log(buf);
            }
        }
    t->build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return t;
}

// ---------------------------------------------------------------- the file

std::vector<std::uint8_t> ProfileTables::serialize() const {
    const ProfileBuildSettings& s = settings;
    std::vector<std::uint8_t> b(kMagic, kMagic + 8);
    b.reserve(kFixedHeader + 64 * 8 + records.size() * 4 * std::size_t(record_floats(s)));
    put32(b, kProfileFormatVersion);                     // 8
    put32(b, 0);                                         // 12 payload offset (patched)
    put64(b, 0);                                         // 16 payload bytes (patched)
    put64(b, 0);                                         // 24 checksum (patched)
    put32(b, generator_version);                         // 32
    put32(b, faces == 2 ? kFlagTransmission : 0);        // 36
    put32(b, std::uint32_t(s.g.size()));                 // 40
    put32(b, std::uint32_t(s.eta.size()));               // 44
    put32(b, std::uint32_t(s.thickness.size()));         // 48
    put32(b, std::uint32_t(s.albedos));                  // 52
    put32(b, std::uint32_t(s.bins.count));               // 56
    put32(b, std::uint32_t(s.bins.per_decade));          // 60
    put32(b, std::uint32_t(s.cos_inside.size()));     // 64
    put32(b, std::uint32_t(s.angle_nodes));              // 68
    put32(b, std::uint32_t(s.angle_bins));               // 72
    put32(b, 0);                                         // 76 reserved
    putf64(b, s.bins.rho_0);                             // 80
    putf64(b, s.u_0);                                    // 88
    putf64(b, s.u_step);                                 // 96
    putf64(b, s.short_orders);                           // 104
    putf64(b, s.roulette_order);                         // 112
    putf64(b, s.oblique_fraction);                       // 120
    put64(b, s.photons);                                 // 128
    put64(b, s.short_photons);                           // 136
    put64(b, s.seed);                                    // 144
    putf64(b, s.radiance_orders);                        // 152
    for (double v : s.g) putf64(b, v);
    for (double v : s.eta) putf64(b, v);
    for (double v : s.thickness) putf64(b, v);
    for (double v : s.cos_inside) putf64(b, v);
    while (b.size() % 16) b.push_back(0);
    const std::size_t off = b.size();
    for (const FaceRecord& r : records) {
        for (double v : {r.multi, r.single, r.ballistic, r.tail_k, r.tail_a, r.rho_tail}) putf32(b, v);
        for (double v : r.angle) putf32(b, v);
        for (double v : r.incidence) putf32(b, v);
        for (double v : r.profile) putf32(b, v);
    }
    const std::uint64_t bytes = b.size() - off;
    for (int k = 0; k < 4; ++k) b[12 + k] = std::uint8_t(std::uint32_t(off) >> (8 * k));
    for (int k = 0; k < 8; ++k) b[16 + k] = std::uint8_t(bytes >> (8 * k));
    const std::uint64_t sum = profile_file_checksum(b.data(), b.size());  // last: it covers the fields above
    for (int k = 0; k < 8; ++k) b[24 + k] = std::uint8_t(sum >> (8 * k));
    return b;
}

std::uint64_t profile_file_checksum(const std::uint8_t* data, std::size_t size) {
    // fnv1a64 (core/bytes.h) over [0, 24), eight zeros, [32, size): one pass, no copy.
    std::uint64_t h = 0xcbf29ce484222325ULL;
    for (std::size_t i = 0; i < size; ++i) {
        h ^= (i >= 24 && i < 32) ? 0u : data[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

std::shared_ptr<const ProfileTables> load_profile_tables(const std::uint8_t* data, std::size_t size,
                                                         const std::string& name) {
    auto fail = [&](std::size_t offset, const std::string& what) -> void {
        throw ProfileError(name + ": offset " + std::to_string(offset) + ": " + what);
    };
    if (size < kFixedHeader)
        fail(size, "expected a header of " + std::to_string(kFixedHeader) + " bytes, found a file of " + std::to_string(size) +
                       " bytes (truncated, or not a .ssp file)");
    if (std::memcmp(data, kMagic, 8) != 0) fail(0, "expected the magic \"PVSSPROF\" (not an exact-profile table)");
    const std::uint32_t version = get32(data + 8);
    if (version != kProfileFormatVersion)
        fail(8, "expected format version " + std::to_string(kProfileFormatVersion) + ", found " + std::to_string(version) +
                    " (rebuild it: make brdf-data, or sstool build --if-stale -o FILE)");
    // Before any field is believed: a changed header field (a count, a step) would otherwise
    // give a table that loads and evaluates to something else.
    const std::uint64_t sum = profile_file_checksum(data, size), stored_sum = get64(data + 24);
    if (sum != stored_sum)
        fail(24, "expected the file's checksum " + hex64(sum) + ", found " + hex64(stored_sum) +
                     " (the file is damaged or was edited: rebuild it with make brdf-data, or sstool build --if-stale -o FILE)");
    auto t = std::make_shared<ProfileTables>();
    t->name = name;
    ProfileBuildSettings& s = t->settings;
    t->generator_version = get32(data + 32);
    const std::uint32_t flags = get32(data + 36);
    if (flags & ~kFlagTransmission) fail(36, "expected flags 0 or 1, found " + std::to_string(flags));
    t->faces = (flags & kFlagTransmission) ? 2 : 1;
    struct Count {
        std::size_t at;
        const char* what;
        std::uint32_t lo, hi;
    };
    const Count counts[] = {{40, "g nodes", 1, 64},          {44, "eta nodes", 1, 64},     {48, "thickness nodes", 1, 64},
                            {52, "albedo nodes", 4, 1000},   {56, "radial nodes", 4, 1000}, {60, "radial nodes per decade", 1, 100},
                            {64, "incidence nodes", 1, 64}, {68, "angle samples", 2, 32},  {72, "angle bins", 4, 1000}};
    std::uint32_t n[9];
    for (int i = 0; i < 9; ++i) {
        n[i] = get32(data + counts[i].at);
        if (n[i] < counts[i].lo || n[i] > counts[i].hi)
            fail(counts[i].at, std::string("expected ") + std::to_string(counts[i].lo) + " to " + std::to_string(counts[i].hi) +
                                   " " + counts[i].what + ", found " + std::to_string(n[i]));
    }
    s.albedos = int(n[3]);
    s.bins.count = int(n[4]);
    s.bins.per_decade = int(n[5]);
    s.angle_nodes = int(n[7]);
    s.angle_bins = int(n[8]);
    s.bins.rho_0 = getf64(data + 80);
    s.u_0 = getf64(data + 88);
    s.u_step = getf64(data + 96);
    s.short_orders = getf64(data + 104);
    s.roulette_order = getf64(data + 112);
    s.oblique_fraction = getf64(data + 120);
    s.photons = get64(data + 128);
    s.short_photons = get64(data + 136);
    s.seed = get64(data + 144);
    s.radiance_orders = getf64(data + 152);
    if (get32(data + 76) != 0) fail(76, "expected 0 in the reserved field, found " + std::to_string(get32(data + 76)));
    if (!(s.bins.rho_0 > 0 && s.bins.rho_0 < 1e3)) fail(80, "expected the first radius in (0, 1000), found " + num(s.bins.rho_0));
    // The generator's settings (the file's identity for --if-stale): ranges of ProfileBuildSettings.
    if (!(s.short_orders >= 1 && s.short_orders <= 1e6)) fail(104, "expected short orders in [1, 1e6], found " + num(s.short_orders));
    if (!(s.roulette_order >= 1 && s.roulette_order <= 1e9))
        fail(112, "expected a roulette order in [1, 1e9], found " + num(s.roulette_order));
    if (!(s.oblique_fraction > 0 && s.oblique_fraction <= 1))
        fail(120, "expected an oblique fraction in (0, 1], found " + num(s.oblique_fraction));
    if (s.photons < 1) fail(128, "expected at least one photon, found 0");
    if (!(s.radiance_orders >= 2 && s.radiance_orders <= 1e5))
        fail(152, "expected radiance orders in [2, 1e5], found " + num(s.radiance_orders));
    if (!(s.u_0 >= 0 && s.u_0 <= 30)) fail(88, "expected the first albedo node u in [0, 30], found " + num(s.u_0));
    if (!(s.u_step > 0 && s.u_0 + (s.albedos - 1) * s.u_step <= 30))
        fail(96, "expected an albedo step > 0 with the last node u <= 30, found " + num(s.u_step));
    // Axes.
    std::size_t at = kFixedHeader;
    const std::size_t axis_bytes = 8 * (std::size_t(n[0]) + n[1] + n[2] + n[6]);
    if (size < at + axis_bytes)
        fail(size, "expected " + std::to_string(axis_bytes) + " bytes of axes after the header, found " +
                       std::to_string(size - at));
    auto read_axis = [&](std::vector<double>& v, std::uint32_t count, const char* what, double lo, double hi, bool allow_inf) {
        v.resize(count);
        for (std::uint32_t i = 0; i < count; ++i, at += 8) {
            v[i] = getf64(data + at);
            const bool ok = (v[i] >= lo && v[i] <= hi) || (allow_inf && v[i] == kInf);
            if (!ok) fail(at, std::string(what) + " node " + std::to_string(i) + ": expected a value in [" + num(lo) + ", " + num(hi) +
                                  "]" + (allow_inf ? " or inf" : "") + ", found " + num(v[i]));
            if (i > 0 && !(v[i] > v[i - 1]))
                fail(at, std::string(what) + " node " + std::to_string(i) + ": expected increasing values, found " + num(v[i]) +
                             " after " + num(v[i - 1]));
        }
    };
    read_axis(s.g, n[0], "g", 0.0, 0.99, false);
    read_axis(s.eta, n[1], "eta", 1.0, 4.0, false);
    const std::size_t thickness_at = at;
    read_axis(s.thickness, n[2], "thickness", 1e-3, 1e6, true);
    read_axis(s.cos_inside, n[6], "inside incidence cosine", 0.01, 1.0, false);
    if (s.cos_inside.back() != 1.0) fail(at - 8, "expected the last inside incidence cosine to be 1, found " + num(s.cos_inside.back()));
    if (t->faces == 1 && !(s.thickness.size() == 1 && s.thickness[0] == kInf))
        fail(thickness_at, "expected one thickness node, inf, in a reflection-only table (flags 0)");
    const std::size_t off = (at + 15) & ~std::size_t(15);
    const std::uint32_t stored_off = get32(data + 12);
    if (stored_off != off) fail(12, "expected the payload offset " + std::to_string(off) + ", found " + std::to_string(stored_off));
    const std::size_t R = std::size_t(record_floats(s));
    const std::size_t nrec = std::size_t(n[0]) * n[1] * n[2] * t->faces * s.albedos;
    const std::uint64_t bytes = std::uint64_t(nrec) * R * 4;
    const std::uint64_t stored_bytes = get64(data + 16);
    if (stored_bytes != bytes)
        fail(16, "expected " + std::to_string(bytes) + " payload bytes for these axes, found " + std::to_string(stored_bytes));
    if (size < off || size - off != bytes)
        fail(std::min(size, off + std::size_t(bytes)), "expected the file to end after " + std::to_string(bytes) +
                                                           " payload bytes at offset " + std::to_string(off) + ", found a file of " +
                                                           std::to_string(size) + " bytes");
    for (std::size_t p = at; p < off; ++p)
        if (data[p] != 0) fail(p, "expected zero padding before the payload");
    // Records.
    t->records.resize(nrec);
    std::size_t p = off;
    const std::size_t ne = n[1], nd = n[2];
    for (std::size_t i = 0; i < nrec; ++i) {
        const std::size_t k = i % s.albedos, face = (i / s.albedos) % t->faces, rest = i / s.albedos / t->faces;
        const std::size_t id = rest % nd, ie = (rest / nd) % ne, ig = rest / nd / ne;
        auto label = [&](const std::string& field) {
            return "g=" + num(s.g[ig]) + " eta=" + num(s.eta[ie]) + " d=" + num(s.thickness[id]) +
                   (face ? " transmission" : " reflection") + " albedo=" + num(t->albedo(int(k))) + " " + field;
        };
        auto value = [&](const std::string& field, double lo, double hi) {
            const double v = getf32(data + p);
            if (!(v >= lo && v <= hi)) fail(p, label(field) + ": expected a value in [" + num(lo) + ", " + num(hi) + "], found " + num(v));
            p += 4;
            return v;
        };
        FaceRecord& r = t->records[i];
        r.multi = value("total", 0.0, 1.5);
        r.single = value("single", 0.0, 1.5);
        r.ballistic = value("ballistic", 0.0, 1.5);
        r.tail_k = value("tail rate", 0.0, 1e6);
        r.tail_a = value("tail amplitude", 0.0, kMaxTailAmplitude);
        r.rho_tail = value("tail radius", 1e-6, 1e6);
        r.angle.resize(s.angle_nodes);
        for (int j = 0; j < s.angle_nodes; ++j) r.angle[j] = value("angle sample " + std::to_string(j), 0.0, 1e6);
        r.incidence.resize(s.cos_inside.size());
        for (std::size_t j = 0; j < s.cos_inside.size(); ++j)
            r.incidence[j] = value("incidence factor " + std::to_string(j), 1e-6, 1e6);
        if (std::fabs(r.incidence.back() - 1.0) > 1e-6)
            fail(p - 4, label("incidence factor at normal incidence") + ": expected 1, found " + num(r.incidence.back()));
        r.profile.resize(s.bins.count);
        for (int b = 0; b < s.bins.count; ++b) r.profile[b] = value("radius node " + std::to_string(b), 0.0, 1e30);
    }
    return t;
}

std::shared_ptr<const ProfileTables> shared_profile_tables(
    const std::string& key, const std::function<std::shared_ptr<const ProfileTables>()>& load) {
    static std::mutex mutex;
    static std::map<std::string, std::weak_ptr<const ProfileTables>> cache;
    std::lock_guard<std::mutex> lock(mutex);
    if (auto live = cache[key].lock()) return live;
    std::shared_ptr<const ProfileTables> t = load();
    cache[key] = t;
    return t;
}

// ---------------------------------------------------------------- evaluation

namespace {

// Cubic Lagrange weights on up to 4 nodes around x (fewer near the ends or on small grids);
// exact at the nodes, x clamped to the axis.
std::vector<std::pair<int, double>> axis_weights(const std::vector<double>& axis, double x) {
    const int n = int(axis.size());
    if (n == 1) return {{0, 1.0}};
    x = std::clamp(x, axis.front(), axis.back());
    int i = int(std::upper_bound(axis.begin(), axis.end(), x) - axis.begin()) - 1;
    i = std::clamp(i, 0, n - 2);
    for (int j = 0; j < n; ++j)
        if (axis[j] == x) return {{j, 1.0}};
    int first = std::max(0, i - 1), last = std::min(n - 1, i + 2);
    std::vector<std::pair<int, double>> w;
    for (int j = first; j <= last; ++j) {
        double l = 1.0;
        for (int m = first; m <= last; ++m)
            if (m != j) l *= (x - axis[m]) / (axis[j] - axis[m]);
        w.push_back({j, l});
    }
    return w;
}

// Catmull-Rom weights on the uniform albedo grid at fractional index s (clamped inside).
std::vector<std::pair<int, double>> albedo_weights(int n, double s) {
    s = std::clamp(s, 0.0, double(n - 1));
    int i = std::min(int(std::floor(s)), n - 2);
    const double t = s - i;
    if (t == 0) return {{i, 1.0}};
    const double t2 = t * t, t3 = t2 * t;
    double w[4] = {-0.5 * t3 + t2 - 0.5 * t, 1.5 * t3 - 2.5 * t2 + 1, -1.5 * t3 + 2 * t2 + 0.5 * t, 0.5 * t3 - 0.5 * t2};
    std::vector<std::pair<int, double>> out;
    for (int j = 0; j < 4; ++j) {
        int idx = i - 1 + j;
        // ends: mirror the missing neighbour linearly (p[-1] = 2 p0 - p1), i.e. fold its weight
        if (idx < 0) {
            out.push_back({0, 2 * w[j]});
            out.push_back({1, -w[j]});
        } else if (idx > n - 1) {
            out.push_back({n - 1, 2 * w[j]});
            out.push_back({n - 2, -w[j]});
        } else {
            out.push_back({idx, w[j]});
        }
    }
    return out;
}

}  // namespace

std::string ChannelProfile::range_error(const ProfileTables& t, double g, double eta, double thickness) {
    const ProfileBuildSettings& s = t.settings;
    if (!(g >= s.g.front() - 1e-12 && g <= s.g.back() + 1e-12))
        return "g = " + num(g) + " is outside the tables' range [" + num(s.g.front()) + ", " + num(s.g.back()) + "]";
    if (!(eta >= s.eta.front() - 1e-12 && eta <= s.eta.back() + 1e-12))
        return "ior = " + num(eta) + " is outside the tables' range [" + num(s.eta.front()) + ", " + num(s.eta.back()) + "]";
    if (thickness == kInf) {
        if (s.thickness.back() != kInf) return "the tables have no semi-infinite node";
    } else {
        if (!(thickness > 0)) return "thickness = " + num(thickness) + ": expected > 0 transport mfp";
        if (s.thickness.front() == kInf) return "the tables have no slabs";
    }
    return "";
}

ChannelProfile::ChannelProfile(const ProfileTables& t, double alpha_prime, double g, double eta, double thickness, int face)
    : alpha_prime_(alpha_prime), eta_(eta) {
    const std::string err = range_error(t, g, eta, thickness);
    if (!err.empty()) throw std::invalid_argument("exact profile: " + err);
    if (!(alpha_prime >= 0 && alpha_prime <= 1)) throw std::invalid_argument("exact profile: reduced albedo outside [0, 1]");
    if (face < 0 || face >= t.faces) throw std::invalid_argument("exact profile: these tables have no transmission face");
    const ProfileBuildSettings& s = t.settings;
    const int nb = s.bins.count, nci = int(s.cos_inside.size());

    // Node weights: g and eta cubic Lagrange; the thickness (transport mfp, like the radii) is
    // converted per g node to the tables' mean free paths, d / (1 - alpha g), then linear in ln d
    // between the two finite nodes around it.
    auto wg = axis_weights(s.g, g), we = axis_weights(s.eta, eta);
    std::vector<double> lnd;
    for (double d : s.thickness)
        if (d != kInf) lnd.push_back(std::log(d));
    auto thickness_weights = [&](double alpha, double gn) -> std::vector<std::pair<int, double>> {
        if (thickness == kInf) return {{int(s.thickness.size()) - 1, 1.0}};
        const double x = std::log(thickness / (1.0 - alpha * gn));
        if (!(x >= lnd.front() - 1e-9 && x <= lnd.back() + 1e-9))
            throw std::invalid_argument("exact profile: thickness " + num(thickness) + " transport mfp (" + num(std::exp(x)) +
                                        " mfp at g = " + num(gn) + ") is outside the tables' slabs [" + num(std::exp(lnd.front())) +
                                        ", " + num(std::exp(lnd.back())) + "] mfp");
        if (lnd.size() == 1) return {{0, 1.0}};
        int i = int(std::upper_bound(lnd.begin(), lnd.end(), x) - lnd.begin()) - 1;
        i = std::clamp(i, 0, int(lnd.size()) - 2);
        const double f = std::clamp((x - lnd[i]) / (lnd[i + 1] - lnd[i]), 0.0, 1.0);
        return {{i, 1 - f}, {i + 1, f}};
    };

    rho_.resize(nb);
    for (int b = 0; b < nb; ++b) rho_[b] = t.node_rho(b);
    lnv_.assign(nb, 0.0);
    angle_.assign(129, 0.0);  // inside radiance at mu' = mu_c + (1 - mu_c) j / 128 (this channel's eta)
    incidence_.assign(nci, 0.0);
    ci_ = s.cos_inside;
    double ln_total = 0, single = 0, ballistic = 0, tail_k = 0, wsum_total = 0, own_flux = 0;
    const double mu_c = critical_cos(eta);
    for (auto [ig, w1] : wg) {
        const double gn = s.g[ig];
        // The node's albedo at the same reduced albedo: alpha' = alpha (1 - g) / (1 - alpha g).
        const double alpha = alpha_prime / (1.0 - gn + alpha_prime * gn);
        const auto wd = thickness_weights(alpha, gn);
        for (auto [ie, w2] : we)
            for (auto [id, w3] : wd) {
                const double w = w1 * w2 * w3;
                const double u = alpha < 1.0 ? -std::log1p(-alpha) : 1e300;
                // Multiple scattering goes as alpha^2 for small alpha: the profile values and the
                // total are interpolated as ln(v / alpha^2) (smooth in u down to alpha = 0, and
                // below the first node that ratio is held constant).
                const double sidx = (u - s.u_0) / s.u_step;
                const double ln_a2 = alpha > 0 ? 2.0 * std::log(alpha) : std::log(kTiny);
                for (auto [k, wk] : albedo_weights(s.albedos, sidx)) {
                    const FaceRecord& r = t.record(ig, ie, id, face, k);
                    const double ww = w * wk;
                    const double ln_scale = ln_a2 - 2.0 * std::log(t.albedo(k));
                    ln_total += ww * (std::log(std::max(r.multi, kTiny)) + ln_scale);
                    wsum_total += ww;
                    single += ww * r.single;
                    ballistic += ww * r.ballistic;
                    tail_k += ww * r.tail_k;
                    for (int b = 0; b < nb; ++b) lnv_[b] += ww * (std::log(std::max(r.profile[b], kTiny)) + ln_scale);
                    for (int j = 0; j < nci; ++j) incidence_[j] += ww * r.incidence[j];
                    for (int j = 0; j <= 128; ++j) angle_[j] += ww * angle_poly(r.angle, mu_c + (1 - mu_c) * j / 128.0);
                    own_flux += ww * exit_integral(r.angle, s.eta[ie]);
                }
            }
    }
    (void)wsum_total;
    total_ = std::exp(ln_total);
    if (total_ < 1e-30) total_ = 0;
    single_ = std::max(0.0, single);
    ballistic_ = std::max(0.0, ballistic);
    tail_k_ = std::max(0.0, tail_k);
    for (double& v : angle_) v = std::max(0.0, v);
    for (double& v : incidence_) v = std::max(0.0, v);

    // Disc integrals at the nodes, then the tail beyond the last node (continuous there), then
    // one scale so the profile integrates to the interpolated total.
    RadialCurve c{rho_.data(), lnv_.data(), nb, std::log(10.0) / s.bins.per_decade};
    cum_.assign(nb, 0.0);
    for (int b = 1; b < nb; ++b) cum_[b] = cum_[b - 1] + c.integral_in(b - 1, rho_[b - 1], rho_[b]);
    const double last = rho_[nb - 1];
    tail_a_ = std::exp(lnv_[nb - 1]) / tail_shape(tail_k_, last);
    if (!std::isfinite(tail_a_)) tail_a_ = 0;
    const double whole = cum_[nb - 1] + (tail_a_ > 0 ? tail_a_ * tail_flux(tail_k_, last) : 0.0);
    const double fix = whole > 0 && total_ > 0 ? total_ / whole : 0.0;
    for (double& v : lnv_) v += fix > 0 ? std::log(fix) : std::log(kTiny);
    for (double& v : cum_) v *= fix;
    tail_a_ *= fix;

    angle_norm_ = 1.0 / (eta * eta);  // radiance leaving = Ft L_inside / eta^2
    // Mixing the inside radiance of nodes at other etas does not keep its exitance: scale it so
    // that the exit distribution integrates to the weighted integrals of the nodes' own (1 up to
    // their interpolants' error; at a node the scale is 1 and the samples stay as measured).
    double mixed = 0;
    const int steps = 512;
    for (int i = 0; i < steps; ++i) mixed += 2.0 * exit_factor((i + 0.5) / steps) * ((i + 0.5) / steps) / steps;
    if (mixed > 0 && own_flux > 0) angle_norm_ *= own_flux / mixed;
    if (incidence_.back() > 0) {
        const double last = incidence_.back();
        for (double& v : incidence_) v /= last;  // exactly 1 at normal incidence
    }
}

int ChannelProfile::segment_of(double rho) const {
    const int n = int(rho_.size());
    if (!(rho > rho_[1])) return 0;
    const double h = std::log(rho_[2] / rho_[1]);
    return std::clamp(1 + int(std::floor(std::log(rho / rho_[1]) / h)), 1, n - 2);
}

double ChannelProfile::rd(double rho) const {
    if (total_ <= 0 || !(rho >= 0)) return 0.0;
    const int n = int(rho_.size());
    if (rho >= rho_[n - 1]) return rho == kInf ? 0.0 : tail_a_ * tail_shape(tail_k_, rho);
    const RadialCurve c{rho_.data(), lnv_.data(), n, std::log(rho_[2] / rho_[1])};
    return c.eval_in(segment_of(rho), rho);
}

double ChannelProfile::segment_integral(int b, double r1, double r2) const {
    const RadialCurve c{rho_.data(), lnv_.data(), int(rho_.size()), std::log(rho_[2] / rho_[1])};
    return c.integral_in(b, r1, r2);
}

double ChannelProfile::disc(double R) const {
    if (total_ <= 0 || !(R > 0)) return 0.0;
    const int n = int(rho_.size());
    if (R >= rho_[n - 1]) {
        if (R == kInf) return total_;
        const double beyond_last = tail_a_ * tail_flux(tail_k_, rho_[n - 1]);
        const double beyond_R = tail_a_ * tail_flux(tail_k_, R);
        return cum_[n - 1] + (beyond_last - beyond_R);
    }
    const int b = segment_of(R);
    return cum_[b] + segment_integral(b, rho_[b], R);
}

double ChannelProfile::annulus_mean(double r1, double r2) const {
    if (!(r2 > r1)) return rd(r1);
    return (disc(r2) - disc(r1)) / (kPi * (r2 * r2 - r1 * r1));
}

double ChannelProfile::radius_containing(double fraction) const {
    if (total_ <= 0) return 0.0;
    if (!(fraction < 1)) return kInf;
    const double want = fraction * total_;
    double lo = 0, hi = rho_[1];
    while (disc(hi) < want) {
        lo = hi;
        hi *= 2;
        if (hi > 1e15) return hi;
    }
    for (int it = 0; it < 200 && hi - lo > 1e-15 * hi; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (disc(mid) >= want) hi = mid;
        else lo = mid;
    }
    return hi;
}

double ChannelProfile::exit_factor(double cos_o) const {
    if (!(cos_o > 0)) return 0.0;
    cos_o = std::min(cos_o, 1.0);
    const double ft = 1.0 - fresnel_dielectric(cos_o, eta_);
    if (!(ft > 0)) return 0.0;
    const double mu_c = critical_cos(eta_);
    const double mi = std::sqrt(std::max(0.0, 1.0 - (1.0 - cos_o * cos_o) / (eta_ * eta_)));
    const double x = std::clamp((mi - mu_c) / (1 - mu_c) * 128.0, 0.0, 128.0);
    const int j = std::min(127, int(x));
    const double i = angle_[j] + (angle_[j + 1] - angle_[j]) * (x - j);
    return ft * i * angle_norm_;
}

double ChannelProfile::entry_factor(double cos_o) const {
    if (!(cos_o > 0)) return incidence_.front();
    // Snell: the refracted beam's inside cosine
    const double cos_i = std::sqrt(std::max(0.0, 1.0 - (1.0 - std::min(1.0, cos_o * cos_o)) / (eta_ * eta_)));
    const int n = int(ci_.size());
    if (cos_i <= ci_.front()) return incidence_.front();
    if (cos_i >= ci_.back()) return incidence_.back();
    int i = int(std::upper_bound(ci_.begin(), ci_.end(), cos_i) - ci_.begin()) - 1;
    i = std::clamp(i, 0, n - 2);
    const double f = (cos_i - ci_[i]) / (ci_[i + 1] - ci_[i]);
    return incidence_[i] * (1 - f) + incidence_[i + 1] * f;
}

double alpha_prime_for_total(const ProfileTables& t, double total, double g, double eta,
                             const std::function<double(double)>& single) {
    auto f = [&](double ap) { return ChannelProfile(t, ap, g, eta).total() + (single ? single(ap) : 0.0); };
    if (!(total > 0)) return 0.0;
    if (total >= f(1.0)) return 1.0;
    double lo = 0.0, hi = 1.0;  // the total rises monotonically with alpha'
    for (int it = 0; it < 60 && hi - lo > 1e-10; ++it) {
        const double mid = 0.5 * (lo + hi);
        (f(mid) < total ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

}  // namespace shading
