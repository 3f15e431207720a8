// Monte Carlo photon migration without absorption, reweighted for a grid of albedos; see
// transport_mc.h for the model.
#include "shading/subsurface/transport_mc.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "shading/brdf/fresnel.h"
#include "shading/core/random.h"
#include "shading/core/vec.h"

namespace shading {

// ---------------------------------------------------------------- radial bins

double RadialBins::inner(int b) const { return b <= 0 ? 0.0 : rho_0 * std::pow(10.0, double(b - 1) / per_decade); }
double RadialBins::outer(int b) const { return rho_0 * std::pow(10.0, double(b) / per_decade); }
double RadialBins::area(int b) const { return kPi * (sqr(outer(b)) - sqr(inner(b))); }
int RadialBins::index(double rho) const {
    if (!(rho >= rho_0)) return 0;  // also rho = 0
    const double t = std::log10(rho / rho_0) * per_decade;
    return t < count - 1 ? 1 + int(t) : count;
}

std::vector<double> McSettings::radiance_cosines() const {
    std::vector<double> mu(std::max(0, radiance_nodes));
    // Chebyshev-Radau nodes: cosine-spaced, the last exactly 1 (normal exit, measured rather than
    // extrapolated), the first above 0 (the estimate's 1/mu grows at grazing).
    for (int j = 0; j < radiance_nodes; ++j) mu[j] = 0.5 * (1.0 - std::cos(kPi * (j + 0.5) / (radiance_nodes - 0.5)));
    return mu;
}

std::string McSettings::validate() const {
    if (!(g >= 0.0 && g < 1.0)) return "g = " + std::to_string(g) + ": expected a value in [0, 1)";
    if (eta.empty() || eta.size() > std::size_t(kMaxEtas)) return "eta: expected 1 to " + std::to_string(kMaxEtas) + " values";
    for (double e : eta)
        if (!(e >= 1.0 && e <= 4.0)) return "eta = " + std::to_string(e) + ": expected a value in [1, 4]";
    if (!(thickness > 0)) return "thickness = " + std::to_string(thickness) + ": expected > 0 mean free paths (inf: semi-infinite)";
    if (!(cos_inside > 0 && cos_inside <= 1.0)) return "cos_inside: expected a value in (0, 1]";
    if (photons == 0) return "photons: expected at least 1";
    if (short_photons > 0 && short_orders < 1) return "short_orders: expected >= 1 with short photons";
    if (!(roulette_order >= 1.0)) return "roulette_order: expected >= 1";
    if (albedos.empty()) return "albedos: expected at least one";
    for (std::size_t k = 0; k < albedos.size(); ++k) {
        if (!(albedos[k] >= 0.0 && albedos[k] <= 1.0)) return "albedos: expected values in [0, 1]";
        if (k > 0 && !(albedos[k] > albedos[k - 1])) return "albedos: expected strictly increasing values";
    }
    if (!(bins.rho_0 > 0 && std::isfinite(bins.rho_0)) || bins.per_decade < 1 || bins.count < 2 || bins.count > 100000)
        return "radial bins: expected rho_0 > 0, per_decade >= 1, 2 <= count <= 100000";
    if (angle_bins < 1 || angle_bins > 100000) return "angle_bins: expected 1 .. 100000";
    if (radiance_orders < 0 || radiance_orders > 1000000 || radiance_nodes < 1 || radiance_nodes > 32)
        return "radiance: expected 0 .. 1000000 orders and 1 .. 32 nodes";
    if (oblique_azimuths != 0 && (oblique_azimuths < 2 || oblique_azimuths > 32 || radiance_orders == 0))
        return "oblique_azimuths: expected 0, or 2 .. 32 with the radiance estimate";
    if (radiance_orders > 0 && oblique_azimuths == 0 && (cos_inside != 1.0 || !radial))
        return "radiance: the estimate needs normal incidence (cos_inside 1) and the radial tallies";
    if (oblique_azimuths > 0 && !exit_bands.empty()) return "oblique_azimuths: not with exit bands (normal incidence)";
    if (high_from < 0) return "high_from: expected >= 0";
    if (exit_bands.size() > 15) return "exit_bands: expected at most 15 edges";
    for (std::size_t i = 0; i < exit_bands.size(); ++i)
        if (!(exit_bands[i] > (i ? exit_bands[i - 1] : 0.0) && std::isfinite(exit_bands[i])))
            return "exit_bands: expected finite, increasing edges > 0";
    if (!exit_bands.empty() && radiance_orders == 0) return "exit_bands: the bands need the radiance estimate";
    return "";
}

namespace {

// ---------------------------------------------------------------- random numbers
// xoshiro256** (Blackman, Vigna 2018), seeded by splitmix64 (core/random.h).
struct Rng {
    std::uint64_t s[4];
    Rng(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
        std::uint64_t x = seed ^ (stream * 0xd1b54a32d192ed03ULL) ^ (index * 0x8cb92ba72f3d8dd7ULL);
        for (auto& v : s) v = splitmix64(x);
    }
    static std::uint64_t rotl(std::uint64_t v, int k) { return (v << k) | (v >> (64 - k)); }
    std::uint64_t next() {
        const std::uint64_t r = rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = rotl(s[3], 45);
        return r;
    }
    double uniform() { return uniform_double(next()); }  // [0, 1)
    // cos and sin of a uniform azimuth: a point uniform in the unit disc (rejection), without
    // trigonometric calls.
    void azimuth(double* c, double* s) {
        double a, b, rr;
        do {
            a = 2.0 * uniform() - 1.0;
            b = 2.0 * uniform() - 1.0;
            rr = a * a + b * b;
        } while (rr > 1.0 || rr < 1e-300);
        const double inv_r = 1.0 / std::sqrt(rr);
        *c = a * inv_r;
        *s = b * inv_r;
    }
};

// ---------------------------------------------------------------- tallies

struct FaceTally {
    std::vector<double> ballistic, single, multi, single_sq, multi_sq, radial, radial_sq, arrivals;
    std::vector<double> multi_x;  // sum of the multiple-scattering exits' weight times x
    std::vector<double> ne;  // next-event radiance by order: ne[n * nodes + j], n <= radiance_orders
    // Per exit-distance band (B bands; McFace::band_*): ne_band[(n * B + b) * nodes + j] by
    // order, band_multi and band_r [k * B + b], band_arrivals [(k * B + b) * na + a].
    std::vector<double> ne_band, band_multi, band_r, band_arrivals;
    // Oblique incidence (A azimuths): ne_az[(n * A + a) * nodes + j] by order; multi_high [k].
    std::vector<double> ne_az, multi_high;
    // (oblique: the run estimates the azimuths, A of them on this face, instead of `ne`)
    void init(std::size_t K, int nb, int na, bool radial_on, int ne_orders, int ne_nodes, int B, bool oblique, int A, bool high) {
        ne.assign(ne_orders > 0 && !oblique ? std::size_t(ne_orders + 1) * ne_nodes : 0, 0.0);
        ne_az.assign(A > 0 ? std::size_t(ne_orders + 1) * A * ne_nodes : 0, 0.0);
        multi_high.assign(high ? K : 0, 0.0);
        ne_band.assign(B > 0 ? std::size_t(ne_orders + 1) * B * ne_nodes : 0, 0.0);
        band_multi.assign(K * B, 0.0);
        band_r.assign(K * B, 0.0);
        band_arrivals.assign(K * B * na, 0.0);
        ballistic.assign(K, 0.0);
        single.assign(K, 0.0);
        multi.assign(K, 0.0);
        multi_x.assign(K, 0.0);
        single_sq.assign(K, 0.0);
        multi_sq.assign(K, 0.0);
        radial.assign(radial_on ? K * nb : 0, 0.0);
        radial_sq.assign(radial_on ? K * nb : 0, 0.0);
        arrivals.assign(radial_on ? K * na : 0, 0.0);
    }
    void add(const FaceTally& o) {
        auto acc = [](std::vector<double>& a, const std::vector<double>& b) {
            for (std::size_t i = 0; i < a.size(); ++i) a[i] += b[i];
        };
        acc(ballistic, o.ballistic);
        acc(single, o.single);
        acc(multi, o.multi);
        acc(multi_x, o.multi_x);
        acc(single_sq, o.single_sq);
        acc(multi_sq, o.multi_sq);
        acc(radial, o.radial);
        acc(radial_sq, o.radial_sq);
        acc(arrivals, o.arrivals);
        acc(ne, o.ne);
        acc(ne_band, o.ne_band);
        acc(band_multi, o.band_multi);
        acc(band_r, o.band_r);
        acc(band_arrivals, o.band_arrivals);
        acc(ne_az, o.ne_az);
        acc(multi_high, o.multi_high);
    }
    void clear_squares() {
        std::fill(single_sq.begin(), single_sq.end(), 0.0);
        std::fill(multi_sq.begin(), multi_sq.end(), 0.0);
    }
};
// face [0] top, [1] bottom; one per eta
struct Tally {
    std::vector<FaceTally> face[2];
    std::uint64_t steps = 0;
    bool is_short = false;
    void init(const McSettings& s) {
        for (int which = 0; which < 2; ++which) {
            face[which].resize(s.eta.size());
            for (FaceTally& t : face[which])
                t.init(s.albedos.size(), s.bins.count, s.angle_bins, s.radial, s.radiance_orders, s.radiance_nodes,
                       which == 0 ? s.band_count() : 0, s.oblique_azimuths > 0, which == 0 ? s.oblique_azimuths : 0,
                       s.high_from > 0);
        }
    }
    void add(const Tally& o) {
        for (int f = 0; f < 2; ++f)
            for (std::size_t e = 0; e < face[f].size(); ++e) face[f][e].add(o.face[f][e]);
        steps += o.steps;
    }
};

struct Job {
    bool is_short;
    std::uint64_t first, count;
};

class Simulator {
public:
    explicit Simulator(const McSettings& s) : s_(s), K_(s.albedos.size()), E_(s.eta.size()) {
        log_albedo_.resize(K_);
        log_scale_.resize(K_);
        for (std::size_t k = 0; k < K_; ++k) {
            log_albedo_[k] = s.albedos[k] > 0 ? std::log(s.albedos[k]) : -std::numeric_limits<double>::infinity();
            log_scale_[k] = std::log(1.0 - s.albedos[k] * s.g);  // rho = r (1 - alpha g)
        }
        for (std::size_t e = 0; e < E_; ++e) inv_eta_[e] = 1.0 / s.eta[e];
        uz0_ = s.cos_inside;
        ux0_ = std::sqrt(std::max(0.0, 1.0 - uz0_ * uz0_));
        low_factor_ = s.short_photons > 0 ? double(s.photons) / double(s.photons + s.short_photons) : 1.0;
        log_rho0_ = std::log(s.bins.rho_0);
        bins_per_ln_ = s.bins.per_decade / std::log(10.0);
        ne_mu_ = s.radiance_cosines();
        for (double m : ne_mu_) {
            ne_inv_mu_.push_back(1.0 / m);
            ne_sin_.push_back(std::sqrt(std::max(0.0, 1.0 - m * m)));
        }
        hg_norm_ = (1.0 - s.g * s.g) / (4.0 * kPi);
        B_ = s.band_count();
        for (double e : s.exit_bands) band_edge2_.push_back(e * e);
        for (std::size_t j = 0; j < ne_mu_.size(); ++j) ne_tan_.push_back(ne_sin_[j] * ne_inv_mu_[j]);
        // A slab's faces mirror the light inside (Fresnel at 1 / eta): per node and eta the
        // reflectance R, and the sum over round trips between the faces 1 / (1 - R^2 e^(-2 d / mu)).
        // Past 40 mfp a round trip leaves e^(-40) of the light: the plain estimate.
        mirror_ = s.thickness < 40.0;
        if (mirror_) {
            for (std::size_t j = 0; j < ne_mu_.size(); ++j) {
                const double ed = std::exp(-s.thickness * ne_inv_mu_[j]);
                ne_ed_.push_back(ed);
                for (std::size_t e = 0; e < E_; ++e) {
                    const double r = fresnel_dielectric(ne_mu_[j], inv_eta_[e]);
                    ne_sum_.push_back(1.0 / (1.0 - r * r * ed * ed));
                    ne_r_.push_back(r);
                }
            }
        }
        A_ = s.oblique_azimuths;
        for (int a = 0; a < A_; ++a) {
            az_cos_.push_back(std::cos(kPi * a / (A_ - 1)));
            // (exactly 0 at 0 and 180 degrees, where +phi and -phi are one direction)
            az_sin_.push_back(a == 0 || a == A_ - 1 ? 0.0 : std::sin(kPi * a / (A_ - 1)));
        }
    }

    void run_job(const Job& job, Tally& t) const {
        t.is_short = job.is_short;
        t.init(s_);
        Scratch sc;
        sc.pw.resize(K_);
        for (auto& v : sc.ps) v.assign(E_ * K_, 0.0);
        const std::size_t J = ne_mu_.size(), orders = t.face[0][0].ne.size() / std::max<std::size_t>(1, J);
        for (auto& v : sc.ne) v.assign(orders * J * E_, 0.0);
        sc.ne_band.assign(orders * std::size_t(B_) * J * E_, 0.0);
        sc.ne_az.assign(t.face[0][0].ne_az.size() * E_, 0.0);
        for (std::uint64_t i = job.first; i < job.first + job.count; ++i) {
            for (auto& v : sc.ps) std::fill(v.begin(), v.end(), 0.0);
            // (the bands' azimuths: a stream of their own, streams 3 and 4)
            Rng side(s_.seed, job.is_short ? 4 : 3, i);
            trace(Rng(s_.seed, job.is_short ? 2 : 1, i), side, job.is_short, t, sc);
            for (int f = 0; f < 2; ++f)
                for (std::size_t e = 0; e < E_; ++e)
                    for (std::size_t k = 0; k < K_; ++k) {
                        t.face[f][e].single_sq[k] += sqr(sc.ps[2 * f][e * K_ + k]);
                        t.face[f][e].multi_sq[k] += sqr(sc.ps[2 * f + 1][e * K_ + k]);
                    }
        }
        // The next-event sums to the tally's per-eta layout (its cells are 0: a copy is the
        // same sum, added in the same order).
        for (int f = 0; f < 2; ++f)
            for (std::size_t e = 0; e < E_; ++e) {
                std::vector<double>& ne = t.face[f][e].ne;
                for (std::size_t i = 0; i < ne.size(); ++i) ne[i] = sc.ne[f][i * E_ + e];
            }
        for (std::size_t e = 0; e < E_; ++e) {
            std::vector<double>& nb = t.face[0][e].ne_band;
            for (std::size_t i = 0; i < nb.size(); ++i) nb[i] = sc.ne_band[i * E_ + e];
            std::vector<double>& na = t.face[0][e].ne_az;
            for (std::size_t i = 0; i < na.size(); ++i) na[i] = sc.ne_az[i * E_ + e];
        }
    }

private:
    struct Scratch {
        std::vector<double> pw;       // alpha_k^n
        std::vector<double> ps[4];    // per-photon sums: top single, top multi, bottom single, bottom multi [e * K + k]
        // The job's next-event sums, every eta of a cell side by side: ne[face][(n * J + j) * E + e]
        // and ne_band[((n * B + b) * J + j) * E + e]. One event writes every eta's share of a
        // cell; side by side they share a cache line (per eta, the tally's layout, each eta's row
        // lay megabytes from the next: most of a g 0.9 build's time went to those misses).
        std::vector<double> ne[2], ne_band;
        std::vector<double> ne_az;  // oblique incidence: [((n * A + a) * J + j) * E + e]
    };

    // alpha_k^n for every albedo (pw), highest albedo last; returns the lowest k worth adding.
    std::size_t powers(long n, std::vector<double>& pw) const {
        std::size_t lowest = 0;
        for (std::size_t k = K_; k-- > 0;) {
            pw[k] = n == 0 ? 1.0 : std::exp(double(n) * log_albedo_[k]);
            if (pw[k] < 1e-30) {  // every lower albedo is smaller still: negligible
                for (std::size_t j = 0; j <= k; ++j) pw[j] = 0.0;
                lowest = k + 1;
                break;
            }
        }
        return lowest;
    }

    void trace(Rng rng, Rng& side, bool is_short, Tally& t, Scratch& sc) const {
        const double d = s_.thickness, g = s_.g;
        const bool iso = std::fabs(g) < 1e-9;
        const long short_max = s_.short_orders;
        double x = 0, y = 0, z = 0, ux = ux0_, uy = 0, uz = uz0_;
        double w[kMaxEtas];
        for (std::size_t e = 0; e < E_; ++e) w[e] = 1.0;
        long n = 0, pw_n = -1;
        std::size_t lowest = 0;
        double next_roulette = s_.roulette_order;
        std::uint64_t steps = 0;
        for (;;) {
            ++steps;
            const double step = -std::log(1.0 - rng.uniform());
            double to_face = std::numeric_limits<double>::infinity();
            if (uz < 0) to_face = z / -uz;
            else if (uz > 0 && d < std::numeric_limits<double>::infinity()) to_face = (d - z) / uz;
            if (step >= to_face) {
                // Reaches a face: for each eta the transmitted part leaves (tallied), the
                // reflected part goes on along the mirrored direction, shared by all etas.
                x += ux * to_face;
                y += uy * to_face;
                const int face = uz < 0 ? 0 : 1;
                z = face == 0 ? 0.0 : d;
                const double mu = std::fabs(uz);
                if (n != pw_n) {
                    lowest = powers(n, sc.pw);
                    pw_n = n;
                }
                const double f = (s_.short_photons > 0 && n <= short_max) ? low_factor_ : 1.0;
                double wmax = 0;
                for (std::size_t e = 0; e < E_; ++e) {
                    if (!(w[e] > 0)) continue;
                    const double fr = fresnel_dielectric(mu, inv_eta_[e]);
                    tally_exit(t.face[face][e], e, face, n, x, y, mu, w[e], w[e] * (1.0 - fr) * f, f, sc, lowest);
                    w[e] *= fr;
                    wmax = std::max(wmax, w[e]);
                }
                uz = -uz;
                if (!(wmax > 0)) break;
                if (wmax < 0.1) {
                    if (rng.uniform() < 0.5) {
                        for (std::size_t e = 0; e < E_; ++e) w[e] *= 2.0;
                    } else {
                        break;
                    }
                }
                continue;
            }
            x += ux * step;
            y += uy * step;
            z += uz * step;
            ++n;
            if (is_short && n > short_max) break;
            if (double(n) >= next_roulette) {
                next_roulette *= 2.0;
                if (rng.uniform() < 0.5) {
                    for (std::size_t e = 0; e < E_; ++e) w[e] *= 2.0;
                } else {
                    break;
                }
            }
            if (n >= 2 && n <= s_.radiance_orders && A_ > 0) {
                next_event_oblique(sc, n, z, ux, uy, uz, w);
            } else if (n >= 2 && n <= s_.radiance_orders) {
                double att[32];  // the top face's exp(-z / mu_j), for the bands
                next_event(sc, n, z, ux, uz, w, att);
                if (B_ > 0 && z < 40.0) next_event_bands(sc, side, n, x, y, z, ux, uy, uz, w, att);
            }
            // Henyey-Greenstein deflection about the current direction.
            const double xi = rng.uniform();
            double ct;
            if (iso) {
                ct = 1.0 - 2.0 * xi;
            } else {
                const double q = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi);
                ct = std::clamp((1.0 + g * g - q * q) / (2.0 * g), -1.0, 1.0);
            }
            const double st = std::sqrt(std::max(0.0, 1.0 - ct * ct));
            double cp, sp;
            rng.azimuth(&cp, &sp);
            double nx, ny, nz;
            if (std::fabs(uz) > 0.99999) {
                nx = st * cp;
                ny = st * sp;
                nz = uz > 0 ? ct : -ct;  // sign(uz) ct (not copysign, which drops the sign of ct)
            } else {
                const double den = std::sqrt(1.0 - uz * uz);
                nx = st * (ux * uz * cp - uy * sp) / den + ux * ct;
                ny = st * (uy * uz * cp + ux * sp) / den + uy * ct;
                nz = -st * cp * den + uz * ct;
            }
            const double inv = 1.0 / std::sqrt(nx * nx + ny * ny + nz * nz);  // keep unit length over long paths
            ux = nx * inv;
            uy = ny * inv;
            uz = nz * inv;
        }
        t.steps += steps;
    }

    // The radiance the scattering event of order n at depth z sends straight to each face at the
    // inside cosines mu_j: p(u . w_j) exp(-distance / mu_j) / mu_j, per eta times its weight. The
    // azimuth of w_j is fixed (phi = 0): at normal incidence the expectation does not depend on it.
    // att: the top face's exp(-z / mu_j) (where z < 40).
    void next_event(Scratch& sc, long n, double z, double ux, double uz, const double* w, double* att) const {
        const int J = int(ne_mu_.size());
        const double f = (s_.short_photons > 0 && n <= s_.short_orders) ? low_factor_ : 1.0;
        const double g = s_.g;
        if (mirror_) {
            next_event_mirrored(sc, n, z, ux, uz, w, att, f);
            return;
        }
        for (int face = 0; face < 2; ++face) {
            const double dist = face == 0 ? z : s_.thickness - z;
            if (!(dist < 40.0)) continue;  // exp(-40): nothing arrives
            double q[32];
            for (int j = 0; j < J; ++j) {
                // w_j = (sin_j, 0, -mu_j) towards the top face (depth decreasing), +mu_j towards the bottom
                const double c = ux * ne_sin_[j] + (face == 0 ? -uz : uz) * ne_mu_[j];
                const double den = 1.0 + g * g - 2.0 * g * c;
                const double a = std::exp(-dist * ne_inv_mu_[j]);
                if (face == 0) att[j] = a;
                q[j] = f * hg_norm_ / (den * std::sqrt(den)) * a * ne_inv_mu_[j];
            }
            double* b = sc.ne[face].data() + std::size_t(n) * J * E_;
            // (an eta whose weight is 0 adds +0: the same bits, and a loop without a branch)
            for (int j = 0; j < J; ++j)
                for (std::size_t e = 0; e < E_; ++e) b[j * E_ + e] += w[e] * q[j];
        }
    }

    // next_event in a slab under 40 mfp thick: besides the straight path, the event's light
    // reaches each face by way of the other face's mirror (scattered away from the face, turned
    // back by Fresnel reflection at the far face), and both go on between the faces:
    // L_top(mu) = [p_up e^(-z / mu) + R p_down e^(-(2 d - z) / mu)] / (1 - R^2 e^(-2 d / mu)) / mu, and
    // the bottom's alike. Without the mirrored path a thin forward-scattering sheet's lit side
    // lacked the forward lobe its far face turns back toward the normal: Skin1 at g 0.9, ior 1.3,
    // 0.25 mfp' rendered 3.7 % dark at normal view and right from 30 degrees (DIPOLE.md 10.2).
    void next_event_mirrored(Scratch& sc, long n, double z, double ux, double uz, const double* w, double* att,
                             double f) const {
        const int J = int(ne_mu_.size());
        const double g = s_.g, d = s_.thickness;
        double up[32], down[32];  // the straight paths to the top and the bottom face
        for (int j = 0; j < J; ++j) {
            const double cu = ux * ne_sin_[j] - uz * ne_mu_[j], cd = ux * ne_sin_[j] + uz * ne_mu_[j];
            const double du = 1.0 + g * g - 2.0 * g * cu, dd = 1.0 + g * g - 2.0 * g * cd;
            const double at = std::exp(-z * ne_inv_mu_[j]), ab = std::exp(-(d - z) * ne_inv_mu_[j]);
            att[j] = at;
            const double scale = f * hg_norm_ * ne_inv_mu_[j];
            up[j] = scale / (du * std::sqrt(du)) * at;
            down[j] = scale / (dd * std::sqrt(dd)) * ab;
        }
        double* top = sc.ne[0].data() + std::size_t(n) * J * E_;
        double* bottom = sc.ne[1].data() + std::size_t(n) * J * E_;
        for (int j = 0; j < J; ++j)
            for (std::size_t e = 0; e < E_; ++e) {
                const std::size_t i = std::size_t(j) * E_ + e;
                const double r = ne_r_[i] * ne_ed_[std::size_t(j)], sum = ne_sum_[i];
                top[i] += w[e] * (up[j] + r * down[j]) * sum;
                bottom[i] += w[e] * (down[j] + r * up[j]) * sum;
            }
    }

    // Oblique incidence: next_event's estimate for the top face toward w_ja = (sin_j cos phi_a,
    // +-sin_j sin phi_a, -mu_j), the mean of the two signs (the expectation's mirror symmetry
    // about the plane of incidence, y = 0, halves the noise of its odd part for free).
    void next_event_oblique(Scratch& sc, long n, double z, double ux, double uy, double uz, const double* w) const {
        if (!(z < 40.0)) return;  // exp(-40): nothing arrives
        const int J = int(ne_mu_.size());
        const double f = (s_.short_photons > 0 && n <= s_.short_orders) ? low_factor_ : 1.0;
        const double g = s_.g;
        double* base = sc.ne_az.data() + std::size_t(n) * A_ * J * E_;
        for (int j = 0; j < J; ++j) {
            const double a = f * hg_norm_ * std::exp(-z * ne_inv_mu_[j]) * ne_inv_mu_[j];
            const double along = -uz * ne_mu_[j];
            double same = -1;  // toward the normal every azimuth is one direction: its value once
            for (int k = 0; k < A_; ++k) {
                double q;
                if (same >= 0) {
                    q = same;
                } else {
                    const double cx = ux * ne_sin_[j] * az_cos_[k], cy = uy * ne_sin_[j] * az_sin_[k];
                    const double d1 = 1.0 + g * g - 2.0 * g * (along + cx + cy);
                    if (cy == 0.0) {
                        q = a / (d1 * std::sqrt(d1));
                    } else {
                        const double d2 = 1.0 + g * g - 2.0 * g * (along + cx - cy);
                        q = 0.5 * a * (1.0 / (d1 * std::sqrt(d1)) + 1.0 / (d2 * std::sqrt(d2)));
                    }
                    if (ne_sin_[j] == 0.0) same = q;
                }
                double* cell = base + std::size_t(k * J + j) * E_;
                for (std::size_t e = 0; e < E_; ++e) cell[e] += w[e] * q;
            }
        }
    }

    // Band of an exit at squared distance r2 from the entry point (mean free paths^2).
    int band_of(double r2) const {
        int b = 0;
        while (b < B_ - 1 && r2 >= band_edge2_[std::size_t(b)]) ++b;
        return b;
    }

    // next_event's estimate for the top face, at an azimuth phi of its own (stream `side`), each
    // node's radiance tallied in the band where its direction w_j = (sin_j cos phi, sin_j sin phi,
    // -mu_j) meets the face: at (x, y) + z tan_j (cos phi, sin phi).
    void next_event_bands(Scratch& sc, Rng& side, long n, double x, double y, double z, double ux, double uy, double uz,
                          const double* w, const double* att) const {
        const int J = int(ne_mu_.size());
        const double f = (s_.short_photons > 0 && n <= s_.short_orders) ? low_factor_ : 1.0;
        const double g = s_.g;
        double cp, sp;
        side.azimuth(&cp, &sp);
        const double u_phi = ux * cp + uy * sp;
        double q[32];
        int band[32];
        for (int j = 0; j < J; ++j) {
            const double c = u_phi * ne_sin_[j] - uz * ne_mu_[j];
            const double den = 1.0 + g * g - 2.0 * g * c;
            q[j] = f * hg_norm_ / (den * std::sqrt(den)) * att[j] * ne_inv_mu_[j];
            const double o = z * ne_tan_[j], px = x + o * cp, py = y + o * sp;
            band[j] = band_of(px * px + py * py);
        }
        double* base = sc.ne_band.data() + std::size_t(n) * B_ * J * E_;
        for (int j = 0; j < J; ++j) {
            double* cell = base + std::size_t(band[j] * J + j) * E_;
            for (std::size_t e = 0; e < E_; ++e) cell[e] += w[e] * q[j];
        }
    }

    void tally_exit(FaceTally& face, std::size_t e, int which, long n, double x, double y, double mu, double w_arrival,
                    double w_exit, double f, Scratch& sc, std::size_t lowest) const {
        const std::vector<double>& pw = sc.pw;
        if (n == 0) {
            for (std::size_t k = 0; k < K_; ++k) face.ballistic[k] += w_exit;
            return;
        }
        if (n == 1) {
            double* ps = sc.ps[2 * which].data() + e * K_;
            for (std::size_t k = lowest; k < K_; ++k) {
                const double c = w_exit * pw[k];
                face.single[k] += c;
                ps[k] += c;
            }
            return;
        }
        double* ps = sc.ps[2 * which + 1].data() + e * K_;
        for (std::size_t k = lowest; k < K_; ++k) {
            const double c = w_exit * pw[k];
            face.multi[k] += c;
            face.multi_x[k] += c * x;
            ps[k] += c;
        }
        if (s_.high_from > 0 && n > s_.high_from)
            for (std::size_t k = lowest; k < K_; ++k) face.multi_high[k] += w_exit * pw[k];
        if (!s_.radial) return;
        const int nb = s_.bins.count, na = s_.angle_bins;
        const double r = std::sqrt(x * x + y * y);
        const double log_r = r > 0 ? std::log(r) : -std::numeric_limits<double>::infinity();
        const int a = std::min(na - 1, int(mu * na));
        if (which == 0 && B_ > 0) {
            const int band = band_of(x * x + y * y);
            for (std::size_t k = lowest; k < K_; ++k) {
                const double c = w_exit * pw[k];
                face.band_multi[k * B_ + band] += c;
                face.band_r[k * B_ + band] += c * r;
                if (n > s_.radiance_orders) face.band_arrivals[(k * B_ + band) * na + a] += w_arrival * f * pw[k];
            }
        }
        for (std::size_t k = lowest; k < K_; ++k) {
            const double c = w_exit * pw[k];
            const double t = (log_r + log_scale_[k] - log_rho0_) * bins_per_ln_;
            int b;
            if (!(t >= 0)) b = 0;
            else if (t < nb - 1) b = 1 + int(t);
            else b = nb;
            if (b < nb) {
                face.radial[k * nb + b] += c;
                face.radial_sq[k * nb + b] += c * c;
            }
            if (n > s_.radiance_orders) face.arrivals[k * na + a] += w_arrival * f * pw[k];
        }
    }

    const McSettings& s_;
    std::size_t K_, E_;
    std::vector<double> log_albedo_, log_scale_;
    double inv_eta_[kMaxEtas] = {};
    std::vector<double> ne_mu_, ne_inv_mu_, ne_sin_, ne_tan_;
    // A slab under 40 mfp (next_event_mirrored): e^(-d / mu_j); per node and eta [j * E + e] the
    // faces' reflectance and the sum over round trips.
    bool mirror_ = false;
    std::vector<double> ne_ed_, ne_r_, ne_sum_;
    int B_ = 0;                        // exit-distance bands (0: off)
    int A_ = 0;                        // oblique incidence's azimuths (0: off)
    std::vector<double> az_cos_, az_sin_;
    std::vector<double> band_edge2_;   // their squared outer edges
    double hg_norm_ = 0;
    double ux0_ = 0, uz0_ = 1, low_factor_ = 1, log_rho0_ = 0, bins_per_ln_ = 1;
};

void finish_face(const FaceTally& t, const FaceTally* sq_short, const McSettings& s, McFace& out) {
    // The estimate is (sum over full photons + sum over short photons) / N_full; each class's
    // per-photon contributions are independent samples, so its variance adds N var(class) / N_full^2.
    // t's *_sq hold the full photons' squares, sq_short the short photons' (sums in t are over both).
    const double nf = double(s.photons), ns = double(s.short_photons);
    const std::size_t K = s.albedos.size();
    auto se = [&](double sum_full, double sq_full, double sum_short, double sq_short_v) {
        double var = 0;
        if (nf > 1) var += std::max(0.0, sq_full - sum_full * sum_full / nf);
        if (ns > 1) var += std::max(0.0, sq_short_v - sum_short * sum_short / ns);
        return std::sqrt(var) / nf;
    };
    out.ballistic.resize(K);
    out.single.resize(K);
    out.multi.resize(K);
    out.multi_x.resize(K);
    out.single_se.resize(K);
    out.multi_se.resize(K);
    for (std::size_t k = 0; k < K; ++k) {
        out.ballistic[k] = t.ballistic[k] / nf;
        out.single[k] = t.single[k] / nf;
        out.multi[k] = t.multi[k] / nf;
        out.multi_x[k] = t.multi_x[k] / nf;
        const double ss = sq_short ? sq_short->single[k] : 0.0, ms = sq_short ? sq_short->multi[k] : 0.0;
        out.single_se[k] = se(t.single[k] - ss, t.single_sq[k], ss, sq_short ? sq_short->single_sq[k] : 0.0);
        out.multi_se[k] = se(t.multi[k] - ms, t.multi_sq[k], ms, sq_short ? sq_short->multi_sq[k] : 0.0);
    }
    const int nb = s.bins.count;
    out.radial.assign(t.radial.size(), 0.0);
    out.radial_se.assign(t.radial.size(), 0.0);
    for (std::size_t k = 0; k < K && s.radial; ++k)
        for (int b = 0; b < nb; ++b) {
            const double a = s.bins.area(b);
            out.radial[k * nb + b] = t.radial[k * nb + b] / (nf * a);
            out.radial_se[k * nb + b] = std::sqrt(t.radial_sq[k * nb + b]) / (nf * a);
        }
    out.arrivals.resize(t.arrivals.size());
    for (std::size_t i = 0; i < t.arrivals.size(); ++i) out.arrivals[i] = t.arrivals[i] / nf;
    // The next-event radiance per albedo: sum over orders of alpha^n times the order's tally.
    const int J = s.radiance_nodes, N = s.radiance_orders;
    out.radiance.assign(N > 0 && !t.ne.empty() ? K * J : 0, 0.0);
    for (std::size_t k = 0; k < K && !out.radiance.empty(); ++k) {
        const double la = s.albedos[k] > 0 ? std::log(s.albedos[k]) : -std::numeric_limits<double>::infinity();
        for (int n = 2; n <= N; ++n) {
            const double p = std::exp(n * la);
            if (p < 1e-30) break;
            for (int j = 0; j < J; ++j) out.radiance[k * J + j] += p * t.ne[std::size_t(n) * J + j] / nf;
        }
    }
    // Oblique incidence's azimuths (top face), and the high orders (McSettings::high_from).
    const int A = s.oblique_azimuths;
    out.radiance_azimuth.assign(!t.ne_az.empty() ? K * A * J : 0, 0.0);
    out.radiance_high.assign(s.high_from > 0 && !t.ne.empty() ? K * J : 0, 0.0);
    out.multi_high.resize(t.multi_high.size());
    for (std::size_t k = 0; k < t.multi_high.size(); ++k) out.multi_high[k] = t.multi_high[k] / nf;
    for (std::size_t k = 0; k < K && N > 0; ++k) {
        const double la = s.albedos[k] > 0 ? std::log(s.albedos[k]) : -std::numeric_limits<double>::infinity();
        for (int n = 2; n <= N; ++n) {
            const double p = std::exp(n * la);
            if (p < 1e-30) break;
            if (!out.radiance_azimuth.empty())
                for (int i = 0; i < A * J; ++i)
                    out.radiance_azimuth[k * A * J + i] += p * t.ne_az[std::size_t(n) * A * J + i] / nf;
            if (!out.radiance_high.empty() && n > s.high_from)
                for (int j = 0; j < J; ++j) out.radiance_high[k * J + j] += p * t.ne[std::size_t(n) * J + j] / nf;
        }
    }
    // The bands (top face): as above, per band.
    const std::size_t B = t.band_multi.size() / std::max<std::size_t>(1, K);
    out.band_multi.resize(t.band_multi.size());
    out.band_r.resize(t.band_r.size());
    for (std::size_t i = 0; i < t.band_multi.size(); ++i) {
        out.band_multi[i] = t.band_multi[i] / nf;
        out.band_r[i] = t.band_r[i] / nf;
    }
    out.band_arrivals.resize(t.band_arrivals.size());
    for (std::size_t i = 0; i < t.band_arrivals.size(); ++i) out.band_arrivals[i] = t.band_arrivals[i] / nf;
    out.band_radiance.assign(B > 0 && N > 0 ? K * B * J : 0, 0.0);
    for (std::size_t k = 0; k < K && B > 0 && N > 0; ++k) {
        const double la = s.albedos[k] > 0 ? std::log(s.albedos[k]) : -std::numeric_limits<double>::infinity();
        for (int n = 2; n <= N; ++n) {
            const double p = std::exp(n * la);
            if (p < 1e-30) break;
            const double* src = t.ne_band.data() + std::size_t(n) * B * J;
            double* dst = out.band_radiance.data() + k * B * J;
            for (std::size_t i = 0; i < B * std::size_t(J); ++i) dst[i] += p * src[i] / nf;
        }
    }
}

}  // namespace

McResult run_transport_mc(const McSettings& settings) {
    const std::string bad = settings.validate();
    if (!bad.empty()) throw std::invalid_argument("transport Monte Carlo: " + bad);
    const auto t0 = std::chrono::steady_clock::now();
    McResult res;
    res.settings = settings;
    const McSettings& s = res.settings;
    Simulator sim(s);

    // Fixed chunks, independent of the thread count; merged in order.
    std::vector<Job> jobs;
    const std::uint64_t full_chunk = 1024, short_chunk = 8192;
    for (std::uint64_t i = 0; i < s.photons; i += full_chunk) jobs.push_back({false, i, std::min(full_chunk, s.photons - i)});
    for (std::uint64_t i = 0; i < s.short_photons; i += short_chunk)
        jobs.push_back({true, i, std::min(short_chunk, s.short_photons - i)});

    int threads = s.threads > 0 ? s.threads : int(std::max(1u, std::thread::hardware_concurrency()));
    threads = int(std::min<std::size_t>(std::size_t(threads), jobs.size()));
    res.threads_used = threads;

    // `total` sums everything except that its *_sq fields collect the full photons only; the
    // short photons' sums and squares go to `shorts` as well (for the standard errors).
    Tally total, shorts;
    total.init(s);
    shorts.init(s);
    std::vector<std::unique_ptr<Tally>> done(jobs.size());
    std::size_t next_merge = 0;
    std::mutex mutex;
    std::atomic<std::size_t> next_job{0};
    auto merge = [&](Tally& t) {
        if (t.is_short) {
            shorts.add(t);
            for (auto& f : t.face)
                for (FaceTally& ft : f) ft.clear_squares();
        }
        total.add(t);
    };
    auto worker = [&] {
        for (;;) {
            const std::size_t j = next_job.fetch_add(1);
            if (j >= jobs.size()) return;
            auto t = std::make_unique<Tally>();
            sim.run_job(jobs[j], *t);
            std::lock_guard<std::mutex> lock(mutex);
            done[j] = std::move(t);
            while (next_merge < jobs.size() && done[next_merge]) {
                merge(*done[next_merge]);
                done[next_merge].reset();
                ++next_merge;
            }
        }
    };
    if (threads <= 1) {
        worker();
    } else {
        std::vector<std::thread> pool;
        for (int i = 0; i < threads; ++i) pool.emplace_back(worker);
        for (auto& th : pool) th.join();
    }
    const bool any_short = s.short_photons > 0;
    res.top.resize(s.eta.size());
    res.bottom.resize(s.eta.size());
    for (std::size_t e = 0; e < s.eta.size(); ++e) {
        finish_face(total.face[0][e], any_short ? &shorts.face[0][e] : nullptr, s, res.top[e]);
        finish_face(total.face[1][e], any_short ? &shorts.face[1][e] : nullptr, s, res.bottom[e]);
    }
    res.steps = total.steps;
    res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return res;
}

// ---------------------------------------------------------------- asymptotic decay rate

double transport_decay_rate(double albedo, double g, int moments) {
    if (!(albedo < 1.0)) return 0.0;
    if (!(albedo > 0.0)) return 1.0;  // no scattering: the uncollided beam, exp(-x)
    const int N = std::max(2, moments);
    // B_l = (2l + 1)(1 - alpha g^l) > 0; A_{l,l+1} = A_{l+1,l} = l + 1. Largest nu of
    // A phi = nu B phi, i.e. of the symmetric tridiagonal T = B^-1/2 A B^-1/2 (zero diagonal).
    std::vector<double> off(N - 1);
    double gl = 1.0;
    std::vector<double> b(N);
    for (int l = 0; l < N; ++l) {
        b[l] = (2.0 * l + 1.0) * (1.0 - albedo * gl);
        gl *= g;
    }
    for (int l = 0; l + 1 < N; ++l) off[l] = (l + 1.0) / std::sqrt(b[l] * b[l + 1]);
    // Sturm count: eigenvalues of T greater than x (zero diagonal).
    auto count_above = [&](double x) {
        int neg = 0;  // number of negative pivots of T - x I = eigenvalues below x
        double q = -x;
        if (q < 0) ++neg;
        for (int l = 1; l < N; ++l) {
            if (q == 0) q = 1e-300;
            q = -x - off[l - 1] * off[l - 1] / q;
            if (q < 0) ++neg;
        }
        return N - neg;
    };
    double hi = 0;
    for (double o : off) hi = std::max(hi, 2.0 * o);  // Gershgorin
    hi += 1.0;
    double lo = 0.0;
    for (int it = 0; it < 200 && hi - lo > 1e-14 * hi; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (count_above(mid) >= 1) lo = mid;
        else hi = mid;
    }
    const double nu = 0.5 * (lo + hi);
    return nu > 1.0 ? 1.0 / nu : 1.0;
}

}  // namespace shading
