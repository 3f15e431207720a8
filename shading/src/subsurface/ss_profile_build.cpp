// Building the exact-profile tables from the transport Monte Carlo (build_profile_tables): one
// run per (g, thickness) node, its tallies turned into face records (process_face); see
// ss_profile.h and shading/DIPOLE.md 10.3.
#include "shading/subsurface/ss_profile.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "shading/subsurface/ss_profile_curve.h"

namespace shading {

using namespace ss_detail;

namespace {

// Radial node positions of the tables: 0, then the geometric centres of bins 1 .. count-1.
std::vector<double> node_positions(const RadialBins& bins) {
    std::vector<double> r(bins.count);
    r[0] = 0.0;
    for (int b = 1; b < bins.count; ++b) r[b] = std::sqrt(bins.inner(b) * bins.outer(b));
    return r;
}

// ---------------------------------------------------------------- processing of the tallies

struct Diagnostics {
    double worst_tail_ratio = 1;  // flux-matched / fitted tail amplitude, farthest from 1
    double worst_deconv = 0;      // largest relative mismatch of annulus means left after deconvolution
    double worst_angle_rms = 0;   // flux-weighted rms relative residual of the high orders' angular fit
    double worst_radiance_flux = 0;  // |exitance implied by the angular samples / the exits' total - 1|
    int dropped_tails = 0;           // tails whose amplitude would overflow the file (noise-only faces)
    int noisy_angles = 0;            // faces whose angular samples were normalised by their own flux
    int borrowed_bands = 0;          // exit-distance bands with too few exits (the band inside's ratios)
    double worst_oblique_flux = 0;   // as worst_radiance_flux, for the oblique exit distributions
};

// The high orders' inside radiance I(mu) = c0 + c1 mu + c2 mu^2: fitted to their arrivals'
// histogram (na bins of mu) by weighted least squares; flux: the histogram's total; rms: the
// flux-weighted rms relative residual.
struct HighOrders {
    double c[3] = {0, 0, 0};
    double flux = 0, rms = 0;
    double at(double mu) const { return std::max(0.0, c[0] + c[1] * mu + c[2] * mu * mu); }
};

HighOrders fit_high_orders(const double* arrivals, int na) {
    HighOrders out;
    double* c = out.c;
    // flux in bin a = 2 pi integral over the bin of (c0 + c1 mu + c2 mu^2) mu dmu
    double A[3][3] = {{0}}, b[3] = {0};
    double flux = 0;
    for (int ab = 0; ab < na; ++ab) {
        const double v = arrivals[ab];
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
            const double v = arrivals[ab];
            if (!(v > 0)) continue;
            const double lo = double(ab) / na, hi = double(ab + 1) / na;
            double model = 0;
            for (int p = 0; p < 3; ++p) model += c[p] * 2 * kPi * (std::pow(hi, p + 2) - std::pow(lo, p + 2)) / (p + 2);
            res += v * sqr(model / v - 1.0);
        }
        out.rms = std::sqrt(res / flux);
    }
    out.flux = flux;
    return out;
}

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
        const HighOrders c = fit_high_orders(f.arrivals.data() + std::size_t(k) * na, na);
        if (c.flux > 0.1 * rec.multi) diag.worst_angle_rms = std::max(diag.worst_angle_rms, c.rms);
        for (int j = 0; j < J; ++j) I[j] += c.at(nodes[j]);
    }
    // Exitance implied by I: 2 pi integral of Ft(mu_o) I(mu'(mu_o)) / eta^2 mu_o dmu_o; against
    // the exits' own total it checks the two estimates (diagnostic).
    const double implied = kPi * exit_sum(I, eta) / (eta * eta);
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

    // The exit distribution per distance band (DIPOLE.md 10.7): each band's inside radiance as
    // the whole face's (next-event orders, then the high orders' fit), normalised by the
    // exitance it implies, against the sum over the bands normalised the same way.
    const int B = mc.band_count();
    if (B == 0 || f.band_multi.empty()) return;
    std::vector<std::vector<double>> Ib(B, std::vector<double>(J, 0.0));
    std::vector<double> Isum(J, 0.0), implied_b(B, 0.0);
    for (int b = 0; b < B; ++b) {
        const std::size_t kb = std::size_t(k) * B + b;
        const HighOrders c = fit_high_orders(f.band_arrivals.data() + kb * na, na);
        for (int j = 0; j < J; ++j) {
            Ib[b][j] = f.band_radiance[kb * J + j] + c.at(nodes[j]);
            Isum[j] += Ib[b][j];
        }
        implied_b[b] = exit_sum(Ib[b], eta);
    }
    const double implied_sum = exit_sum(Isum, eta);
    rec.band_rho.assign(B, 0.0);
    rec.band_ratio.assign(std::size_t(B) * J, 1.0);
    const double to_transport = 1.0 - alpha * g;
    for (int b = 0; b < B; ++b) {
        const std::size_t kb = std::size_t(k) * B + b;
        const double m = f.band_multi[kb];
        // the band's mean exit distance; an empty band: its edges' middle
        const double lo = b > 0 ? mc.exit_bands[b - 1] : 0.0, hi = b + 1 < B ? mc.exit_bands[b] : 2.0 * lo;
        rec.band_rho[b] = (m > 0 ? f.band_r[kb] / m : 0.5 * (lo + hi)) * to_transport;
        // A band says something where it holds at least 1e-4 of the face's exits and its two
        // estimates of them (the exits, the radiance's implied exitance) agree within a third;
        // otherwise it takes the band inside it (the first band: 1).
        const double implied_exits = kPi * implied_b[b] / (eta * eta);
        const bool ok = rec.multi > 0 && m > 1e-4 * rec.multi && implied_b[b] > 0 && implied_sum > 0 &&
                        std::fabs(implied_exits / m - 1.0) < 1.0 / 3.0;
        for (int j = 0; j < J; ++j) {
            double v = b > 0 ? rec.band_ratio[std::size_t(b - 1) * J + j] : 1.0;
            if (ok && Isum[j] > 0) v = (Ib[b][j] / implied_b[b]) / (Isum[j] / implied_sum);
            rec.band_ratio[std::size_t(b) * J + j] = std::clamp(v, 0.0, 100.0);
        }
        if (!ok) ++diag.borrowed_bands;
    }
}

// The exit distribution of light entering at the oblique run's inside cosine (index ic), per
// azimuth: the orders 2 .. high_from from the oblique run's own estimate (f.radiance_azimuth),
// the higher ones as the normal run's (its next-event radiance above high_from and the fitted
// histogram above radiance_orders) times the oblique run's share of such exits over the normal
// run's. Stored as pi I / M with M the oblique run's own multiple-scattering exitance, as
// `angle` is; where the exitance the samples imply (their azimuthal mean) differs from it by
// more than a factor 2, by that (as process_face). DIPOLE.md 6e.
void oblique_exits(const McFace& normal, const McSettings& mc, const McFace& f, int k, double eta, int ic, int A,
                   FaceRecord& rec, Diagnostics& diag) {
    const std::vector<double> nodes = mc.radiance_cosines();
    const int J = int(nodes.size()), na = mc.angle_bins;
    if (rec.oblique.empty()) rec.oblique.assign(std::size_t(rec.incidence.size() - 1) * A * J, 1.0);
    std::vector<double> high(J, 0.0);
    const HighOrders c = fit_high_orders(normal.arrivals.data() + std::size_t(k) * na, na);
    for (int j = 0; j < J; ++j) high[j] = normal.radiance_high[std::size_t(k) * J + j] + c.at(nodes[j]);
    const double share = normal.multi_high[k] > 0 ? f.multi_high[k] / normal.multi_high[k] : 0.0;
    std::vector<double> I(std::size_t(A) * J), mean(J, 0.0);
    for (int a = 0; a < A; ++a)
        for (int j = 0; j < J; ++j) {
            const double v = f.radiance_azimuth[(std::size_t(k) * A + a) * J + j] + share * high[j];
            I[std::size_t(a) * J + j] = v;
            // the azimuthal mean over [0, pi] (trapezoid)
            mean[j] += v * ((a == 0 || a == A - 1) ? 0.5 : 1.0) / (A - 1);
        }
    const double m = f.multi[k], implied = kPi * exit_sum(mean, eta) / (eta * eta);
    double norm = m;
    if (m > 0 && implied > 0 && std::fabs(std::log(implied / m)) > std::log(2.0)) {
        norm = implied;
        ++diag.noisy_angles;
    }
    if (m > 1e-4 && implied > 0) diag.worst_oblique_flux = std::max(diag.worst_oblique_flux, std::fabs(implied / m - 1.0));
    for (int i = 0; i < A * J; ++i)
        rec.oblique[std::size_t(ic) * A * J + i] = norm > 0 ? std::clamp(kPi * I[i] / norm, 0.0, 1e6) : 1.0;
}

std::uint64_t node_seed(std::uint64_t seed, int node, int incidence) {
    std::uint64_t x = seed * 0x9e3779b97f4a7c15ULL + std::uint64_t(node) * 0xbf58476d1ce4e5b9ULL +
                      std::uint64_t(incidence + 1) * 0x94d049bb133111ebULL;
    x ^= x >> 31;
    return x;
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
    if (exit_bands.size() > 15) return "exit_bands: expected at most 15 edges";
    for (std::size_t i = 0; i < exit_bands.size(); ++i)
        if (!(exit_bands[i] > (i ? exit_bands[i - 1] : 0.0) && exit_bands[i] <= 1e3))
            return "exit_bands: expected increasing edges in (0, 1000] transport mfp";
    if (oblique_azimuths != 0 && (oblique_azimuths < 2 || oblique_azimuths > 32))
        return "oblique_azimuths: expected 0, or 2 to 32";
    if (oblique_orders < 1 || oblique_orders > 100000) return "oblique_orders: expected 1 to 100000";
    if (photons < 1 || !(short_orders >= 1) || !(roulette_order >= 1) || !(oblique_fraction > 0 && oblique_fraction <= 1))
        return "photons: expected photons >= 1, short_orders >= 1, roulette_order >= 1, oblique_fraction in (0, 1]";
    return "";
}

std::uint64_t ProfileBuildSettings::normal_photons(double thickness, double g) const {
    constexpr double kFrom = 1.6, kMost = 8.0;  // transport mfp; the largest factor
    if (!(thickness < kInf)) return photons;
    const double factor = std::clamp(sqr(thickness * (1.0 - g) / kFrom), 1.0, kMost);
    return std::uint64_t(std::llround(double(photons) * factor));
}

ProfileBuildSettings ProfileBuildSettings::recorded() const {
    ProfileBuildSettings r = *this;
    if (std::any_of(thickness.begin(), thickness.end(), [](double d) { return d != kInf; })) {
        r.exit_bands.clear();
        r.oblique_azimuths = 0;
    }
    return r;
}

bool ProfileTables::stale(const ProfileBuildSettings& wanted) const {
    const ProfileBuildSettings& s = settings;
    const ProfileBuildSettings w = wanted.recorded();
    return generator_version != kProfileGeneratorVersion || s.g != w.g || s.eta != w.eta || s.thickness != w.thickness ||
           s.cos_inside != w.cos_inside || s.u_0 != w.u_0 || s.u_step != w.u_step || s.albedos != w.albedos ||
           s.bins.rho_0 != w.bins.rho_0 || s.bins.per_decade != w.bins.per_decade || s.bins.count != w.bins.count ||
           s.angle_bins != w.angle_bins || s.angle_nodes != w.angle_nodes || s.radiance_orders != w.radiance_orders ||
           s.photons != w.photons ||
           s.short_photons != w.short_photons || s.short_orders != w.short_orders || s.roulette_order != w.roulette_order ||
           s.oblique_fraction != w.oblique_fraction || s.seed != w.seed || s.exit_bands != w.exit_bands ||
           s.oblique_azimuths != w.oblique_azimuths || (s.oblique_azimuths > 0 && s.oblique_orders != w.oblique_orders);
}

std::shared_ptr<ProfileTables> build_profile_tables(const ProfileBuildSettings& s,
                                                    const std::function<void(const std::string&)>& log) {
    const std::string bad = s.validate();
    if (!bad.empty()) throw std::invalid_argument("profile tables: " + bad);
    const auto t0 = std::chrono::steady_clock::now();
    auto t = std::make_shared<ProfileTables>();
    t->settings = s.recorded();  // slabs: no exit-distance bands, no oblique exits
    t->faces = 1;
    for (double d : s.thickness)
        if (d != kInf) t->faces = 2;
    const int A = t->settings.oblique_azimuths;
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
            mc.photons = s.normal_photons(s.thickness[id], g);
            mc.short_photons = s.short_photons;
            mc.short_orders = int(std::ceil(s.short_orders / (1.0 - g)));
            mc.roulette_order = s.roulette_order / (1.0 - g);
            mc.threads = s.threads;
            mc.albedos = albedo_nodes;
            mc.bins = s.bins;
            mc.angle_bins = s.angle_bins;
            mc.radiance_orders = int(std::ceil(s.radiance_orders / (1.0 - g)));
            mc.radiance_nodes = s.angle_nodes;
            if (t->faces == 1)
                for (double e : s.exit_bands) mc.exit_bands.push_back(e / (1.0 - g));
            // (the orders the oblique runs estimate themselves)
            const int oblique_orders = int(std::ceil(s.oblique_orders / (1.0 - g)));
            if (A > 0) mc.high_from = oblique_orders;
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
                        rec.shift.assign(s.cos_inside.size(), 0.0);
                    }
            // Incidence factor: totals only, fewer photons.
            int clamped = 0;
            McSettings ob = mc;
            ob.radial = false;
            ob.radiance_orders = A > 0 ? oblique_orders : 0;
            ob.oblique_azimuths = A;
            ob.high_from = A > 0 ? oblique_orders : 0;
            ob.exit_bands.clear();
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
                            const McFace& f = face == 0 ? r.top[ie] : r.bottom[ie];
                            const double m = f.multi[k];
                            // A ratio outside [0.05, 20] is noise of a run with too few paths for
                            // this albedo (the physical factor stays within a few tenths of 1):
                            // clamped, and counted in the log.
                            double ratio = rec.multi > 0 && m > 0 ? m / rec.multi : 1.0;
                            if (ratio < 0.05 || ratio > 20) ++clamped;
                            rec.incidence[ic] = std::clamp(ratio, 0.05, 20.0);
                            // The exits' mean offset along the beam, mean free paths -> transport
                            // mfp (x (1 - alpha g)); a negative mean is noise (the beam pushes
                            // its light forward): 0.
                            const double mean_x = m > 0 ? f.multi_x[k] / m : 0.0;
                            rec.shift[ic] = std::clamp(mean_x * (1.0 - t->albedo(k) * g), 0.0, 100.0);
                            if (A > 0 && face == 0)
                                oblique_exits(normal.top[ie], normal.settings, f, k, s.eta[ie], int(ic), A, rec, diag);
                        }
            }
            if (log) {
                char buf[640];
                const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - tn).count();
                std::snprintf(buf, sizeof buf,
                              "g=%g d=%g (%zu etas): %.2f s, %.3g flights, %d threads; tail amplitude flux/fit worst %.3f, "
                              "deconvolution residual %.1e, high-order angle fit rms residual worst %.3f, angular/exit "
                              "flux mismatch worst %.4f (oblique %.4f), incidence factors clamped %d, noise-only tails dropped %d, angular "
                              "samples normalised by their own flux %d, distance bands borrowed %d",
                              g, s.thickness[id], ne, sec, double(steps), normal.threads_used, diag.worst_tail_ratio,
                              diag.worst_deconv, diag.worst_angle_rms, diag.worst_radiance_flux, diag.worst_oblique_flux, clamped, diag.dropped_tails,
                              diag.noisy_angles, diag.borrowed_bands);
                log(buf);
            }
        }
    t->build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return t;
}

}  // namespace shading
