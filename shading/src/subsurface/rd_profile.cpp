// RdProfile: the node table, its Hermite reads, the disc integrals; see rd_profile.h.
#include "shading/subsurface/rd_profile.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "shading/core/quadrature.h"

namespace shading {

namespace {

// Nodes: 2^kSubBits per octave of s = 1 + r / scale.
constexpr int kSubBits = 6;
constexpr int kPerOctave = 1 << kSubBits;
constexpr int kMaxOctaves = 1000;  // s < 2^1000: far inside the double range
// sample_every > 1: an interval whose quintic misses its middle node by more than this part of
// the node's value (plus 1 % of the peak's times (scale / r)^2, about what a far tail's share of
// the total would make of it: rounding in a far tail does not count) is sampled whole.
constexpr double kSparseTolerance = 1e-7;

// The node interval i of r >= 0 and r's place u in [0, 1) within it: with s = 1 + r / scale
// >= 1, the octave and the node inside it are the exponent and the top kSubBits mantissa bits
// of s; the rest of the mantissa is u.
inline void locate(double r, double inv_scale, std::size_t* i, double* u) {
    const double s = 1.0 + std::max(0.0, r) * inv_scale;
    std::uint64_t bits;
    std::memcpy(&bits, &s, sizeof bits);
    *i = std::size_t((bits >> (52 - kSubBits)) - (std::uint64_t(1023) << kSubBits));
    *u = double(bits & ((std::uint64_t(1) << (52 - kSubBits)) - 1)) * (1.0 / double(std::uint64_t(1) << (52 - kSubBits)));
}

}  // namespace

RdProfile::RdProfile(Fn rd, Fn disc, double scale, double r_max, int sample_every)
    : rd_(std::move(rd)), disc_(std::move(disc)), scale_(scale), r_max_(r_max) {
    if (!rd_) throw std::invalid_argument("RdProfile: no profile");
    if (!(scale > 0) || !std::isfinite(scale) || !(r_max > 0) || !std::isfinite(r_max))
        throw std::invalid_argument("RdProfile: scale and r_max must be finite and > 0");
    if (!(sample_every >= 1 && sample_every <= 16 && (sample_every & (sample_every - 1)) == 0))
        throw std::invalid_argument("RdProfile: sample_every must be 1, 2, 4, 8 or 16");
    inv_scale_ = 1.0 / scale;
    const double smax = 1.0 + r_max / scale;
    const int octaves = std::max(1, int(std::ceil(std::log2(smax))));
    if (octaves > kMaxOctaves) throw std::invalid_argument("RdProfile: r_max / scale out of range");
    const int n = octaves * kPerOctave;
    nodes_.resize(n + 1);
    node_r_.resize(n + 1);
    // A node from the profile itself: its value and its derivatives by central differences,
    // step 1e-3 of the local scale r + scale (about a tenth of the node interval); below r = e
    // the even extension of Rd (a function of |r|) supplies the point at r - e. The third
    // derivative (for the Hermite interpolation of f'') takes a 10x larger step: its rounding
    // error grows as 1/e^3.
    auto sample = [&](int i) {
        const double r = node_r_[i];
        const double e = 1e-3 * (r + scale), e3 = 1e-2 * (r + scale);
        const Rgb f0 = rd_(r), fp = rd_(r + e), fm = rd_(std::fabs(r - e));
        const Rgb gp = rd_(r + e3), gm = rd_(std::fabs(r - e3)), gpp = rd_(r + 2 * e3), gmm = rd_(std::fabs(r - 2 * e3));
        Node& nd = nodes_[i];
        for (int k = 0; k < 3; ++k) {
            nd.f[k] = f0[k];
            nd.d1[k] = (fp[k] - fm[k]) / (2 * e);
            nd.d2[k] = (fp[k] - 2 * f0[k] + fm[k]) / (e * e);
            nd.d3[k] = (gpp[k] - 2 * gp[k] + 2 * gm[k] - gmm[k]) / (2 * e3 * e3 * e3);
        }
    };
    for (int i = 0; i <= n; ++i) {
        node_r_[i] = scale * (std::ldexp(1.0 + double(i % kPerOctave) / kPerOctave, i / kPerOctave) - 1.0);
        if (i % sample_every == 0) sample(i);  // the others filled below from the sampled nodes around them
    }
    if (sample_every > 1) {
        // The nodes between sampled ones: the quintic Hermite through the two sampled nodes
        // around them (their f, f', f''), in t = (r - r_a) / H over [r_a, r_b]: p(t) = sum
        // c_j t^j with c0 = f_a, c1 = H f'_a, c2 = H^2 f''_a / 2 and c3..c5 matching f_b, H f'_b,
        // H^2 f''_b. Sampled nodes are kPerOctave / 2^k apart inside one octave, where the
        // nodes are evenly spaced in r. Where the profile is not smooth on that scale (it drops
        // to 0 at r_max, where the differences above straddle the drop), the quintic misses its
        // middle node: checked there by one more call, and such an interval is sampled whole.
        integrate_table_ = !disc_;
        double peak = 0;
        for (int a = 0; a <= n; a += sample_every)
            for (int k = 0; k < 3; ++k) peak = std::max(peak, std::fabs(nodes_[a].f[k]));
        for (int a = 0; a < n; a += sample_every) {
            const int b = a + sample_every, mid = a + sample_every / 2;
            const double H = node_r_[b] - node_r_[a];
            for (int k = 0; k < 3; ++k) {
                const double f0 = nodes_[a].f[k], f1 = nodes_[b].f[k], g0 = H * nodes_[a].d1[k], g1 = H * nodes_[b].d1[k],
                             h0 = H * H * nodes_[a].d2[k], h1 = H * H * nodes_[b].d2[k], df = f1 - f0;
                const double c[6] = {f0, g0, 0.5 * h0, 10 * df - 6 * g0 - 4 * g1 - 1.5 * h0 + 0.5 * h1,
                                     -15 * df + 8 * g0 + 7 * g1 + 1.5 * h0 - h1, 6 * df - 3 * g0 - 3 * g1 - 0.5 * h0 + 0.5 * h1};
                for (int i = a + 1; i < b; ++i) {
                    const double t = (node_r_[i] - node_r_[a]) / H;
                    Node& nd = nodes_[i];
                    nd.f[k] = c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
                    nd.d1[k] = (c[1] + t * (2 * c[2] + t * (3 * c[3] + t * (4 * c[4] + t * 5 * c[5])))) / H;
                    nd.d2[k] = (2 * c[2] + t * (6 * c[3] + t * (12 * c[4] + t * 20 * c[5]))) / (H * H);
                    nd.d3[k] = (6 * c[3] + t * (24 * c[4] + t * 60 * c[5])) / (H * H * H);
                }
            }
            const Rgb direct = rd_(node_r_[mid]);
            const double q = scale / std::max(scale, node_r_[mid]), floor = 0.01 * peak * q * q;
            bool smooth = true;
            for (int k = 0; k < 3; ++k)
                if (!(std::fabs(nodes_[mid].f[k] - direct[k]) <= kSparseTolerance * (std::fabs(direct[k]) + floor)))
                    smooth = false;
            if (!smooth)
                for (int i = a + 1; i < b; ++i) sample(i);
        }
    }
    if (!disc_) {
        cumulative_.assign(n + 1, Rgb(0.0));
        for (int i = 0; i < n; ++i) cumulative_[i + 1] = cumulative_[i] + interval_integral(node_r_[i], node_r_[i + 1]);
    }
    total_ = RdProfile::disc(kInf);  // (the parameter `disc` was moved into disc_)

    // Aggregation may widen where the profile's share per unit log r, 2 pi r^2 Rd(r) / total,
    // has fallen below its peak (angle_gain2).
    std::vector<double> share(n + 1, 0.0);
    double peak = 0;
    std::size_t at_peak = 0;
    for (int i = 0; i <= n; ++i) {
        for (int k = 0; k < 3; ++k)
            if (total_[k] > 0) share[i] = std::max(share[i], 2 * kPi * node_r_[i] * node_r_[i] * nodes_[i].f[k] / total_[k]);
        if (share[i] > peak) {
            peak = share[i];
            at_peak = std::size_t(i);
        }
    }
    const double max_gain2 = 2.0;  // the angle at most sqrt 2 times wider
    std::vector<double> g2(n + 1, 1.0);
    for (int i = n; i >= 0; --i) {
        double g = std::size_t(i) <= at_peak ? 1.0 : (share[i] > 0 ? std::min(max_gain2, std::sqrt(peak / share[i])) : max_gain2);
        g2[i] = std::size_t(i) == std::size_t(n) ? g : std::min(g, g2[i + 1]);  // smallest from here on
    }
    // Octave e of s2 = 1 + d^2/scale^2 starts at d = scale sqrt(2^e - 1).
    for (int e = 0; e < 2 * octaves + 2; ++e) {
        const double d = scale * std::sqrt(std::ldexp(1.0, e) - 1.0);
        const auto it = std::lower_bound(node_r_.begin(), node_r_.end(), d);
        gain2_.push_back(it == node_r_.end() ? g2[n] : g2[std::size_t(it - node_r_.begin())]);
    }
}

std::shared_ptr<const RdProfile> RdProfile::tabulated(std::vector<double> r, std::vector<Rgb> rd, double scale) {
    const std::size_t n = r.size();
    if (n < 2 || rd.size() != n) throw std::invalid_argument("RdProfile::tabulated: need at least two radii, one Rd per radius");
    if (r[0] != 0.0) throw std::invalid_argument("RdProfile::tabulated: the first radius must be 0");
    for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(r[i]) || (i > 0 && !(r[i] > r[i - 1])))
            throw std::invalid_argument("RdProfile::tabulated: radii must be finite and increasing (index " + std::to_string(i) + ")");
        for (int k = 0; k < 3; ++k)
            if (!(rd[i][k] >= 0) || !std::isfinite(rd[i][k]))
                throw std::invalid_argument("RdProfile::tabulated: Rd must be finite and >= 0 (index " + std::to_string(i) + ")");
    }
    // Fritsch-Carlson monotone slopes of log Rd per channel (intervals with a zero end are
    // linear in Rd instead).
    struct Table {
        std::vector<double> r;
        std::vector<Rgb> y, m, v;  // log rd, its slopes, rd
    };
    auto t = std::make_shared<Table>();
    t->r = std::move(r);
    t->v = std::move(rd);
    t->y.resize(n);
    t->m.resize(n);
    for (int k = 0; k < 3; ++k) {
        for (std::size_t i = 0; i < n; ++i) t->y[i][k] = t->v[i][k] > 0 ? std::log(t->v[i][k]) : 0.0;
        std::vector<double> delta(n - 1);
        for (std::size_t i = 0; i + 1 < n; ++i) delta[i] = (t->y[i + 1][k] - t->y[i][k]) / (t->r[i + 1] - t->r[i]);
        t->m[0][k] = delta[0];
        t->m[n - 1][k] = delta[n - 2];
        for (std::size_t i = 1; i + 1 < n; ++i)
            t->m[i][k] = delta[i - 1] * delta[i] <= 0 ? 0.0 : 0.5 * (delta[i - 1] + delta[i]);
        for (std::size_t i = 0; i + 1 < n; ++i) {
            if (delta[i] == 0) {
                t->m[i][k] = t->m[i + 1][k] = 0;
                continue;
            }
            const double a = t->m[i][k] / delta[i], b = t->m[i + 1][k] / delta[i];
            if (a * a + b * b > 9) {
                const double tau = 3.0 / std::sqrt(a * a + b * b);
                t->m[i][k] = tau * a * delta[i];
                t->m[i + 1][k] = tau * b * delta[i];
            }
        }
    }
    auto fn = [t](double x) {
        const std::size_t n = t->r.size();
        if (!(x >= 0)) x = 0;
        if (!(x < t->r[n - 1])) return Rgb(0.0);
        const std::size_t i = std::size_t(std::upper_bound(t->r.begin(), t->r.end(), x) - t->r.begin()) - 1;
        const double dx = t->r[i + 1] - t->r[i], u = (x - t->r[i]) / dx;
        Rgb out;
        for (int k = 0; k < 3; ++k) {
            const double a = t->v[i][k], b = t->v[i + 1][k];
            if (!(a > 0) || !(b > 0)) {
                out[k] = a + (b - a) * u;
                continue;
            }
            const double u2 = u * u, u3 = u2 * u;
            const double y = (2 * u3 - 3 * u2 + 1) * t->y[i][k] + (u3 - 2 * u2 + u) * dx * t->m[i][k] +
                             (-2 * u3 + 3 * u2) * t->y[i + 1][k] + (u3 - u2) * dx * t->m[i + 1][k];
            out[k] = std::exp(y);
        }
        return out;
    };
    return std::make_shared<const RdProfile>(fn, Fn(), scale, t->r[n - 1]);
}

RdProfile::Hermite RdProfile::hermite(double r) const {
    std::size_t i;
    double u;
    locate(r, inv_scale_, &i, &u);
    Hermite h;
    h.a = &nodes_[i];
    h.b = &nodes_[i + 1];
    const double dr = node_r_[i + 1] - node_r_[i];
    const double u2 = u * u, u3 = u2 * u;
    h.h00 = 2 * u3 - 3 * u2 + 1, h.h10 = (u3 - 2 * u2 + u) * dr, h.h01 = 3 * u2 - 2 * u3, h.h11 = (u3 - u2) * dr;
    // the basis's derivative per unit r
    h.g00 = (6 * u2 - 6 * u) * (1.0 / dr), h.g10 = 3 * u2 - 4 * u + 1, h.g11 = 3 * u2 - 2 * u;
    return h;
}

inline RdProfile::Values RdProfile::values(double r) const {
    Values v;
    std::size_t i;
    locate(r, inv_scale_, &i, &v.u);
    v.a = &nodes_[i];
    v.b = &nodes_[i + 1];
    v.dr = node_r_[i + 1] - node_r_[i];
    const double u = v.u, u2 = u * u, u3 = u2 * u;
    v.h00 = 2 * u3 - 3 * u2 + 1, v.h10 = (u3 - 2 * u2 + u) * v.dr, v.h01 = 3 * u2 - 2 * u3, v.h11 = (u3 - u2) * v.dr;
    return v;
}

Rgb RdProfile::rd(double r) const {
    if (!(r < r_max_)) return Rgb(0.0);
    const Values v = values(r);
    // Cubic Hermite can dip a hair below 0 where Rd itself is ~0 (the far tail): clamp.
    return Rgb(std::max(0.0, v.f(0)), std::max(0.0, v.f(1)), std::max(0.0, v.f(2)));
}

void RdProfile::eval(double r, Rgb* f, Rgb* d1, Rgb* d2) const {
    if (!(r < r_max_)) {
        *f = *d1 = *d2 = Rgb(0.0);
        return;
    }
    const Hermite h = hermite(r);
    *f = Rgb(h.f(0), h.f(1), h.f(2));
    *d1 = Rgb(h.d1(0), h.d1(1), h.d1(2));
    *d2 = Rgb(h.d2(0), h.d2(1), h.d2(2));
}

double RdProfile::rd_channel(int c, double r) const {
    if (!(r < r_max_)) return 0.0;
    return std::max(0.0, values(r).f(c));
}

void RdProfile::eval_channel(int c, double r, double* f, double* d1, double* d2) const {
    if (!(r < r_max_)) {
        *f = *d1 = *d2 = 0.0;
        return;
    }
    const Values v = values(r);
    const double u = v.u, u2 = u * u;
    // hermite()'s slope weights
    const double g00 = (6 * u2 - 6 * u) * (1.0 / v.dr), g10 = 3 * u2 - 4 * u + 1, g11 = 3 * u2 - 2 * u;
    const Node& a = *v.a;
    const Node& b = *v.b;
    *f = v.f(c);
    *d1 = g00 * (a.f[c] - b.f[c]) + g10 * a.d1[c] + g11 * b.d1[c];
    *d2 = v.h00 * a.d2[c] + v.h10 * a.d3[c] + v.h01 * b.d2[c] + v.h11 * b.d3[c];
}

Rgb RdProfile::disc(double R) const {
    if (!(R > 0)) return Rgb(0.0);
    if (disc_) return disc_(R);
    // Gauss-Legendre on the node intervals (the nodes follow the profile's own scale: uniform
    // within the peak, geometric along the tail): whole intervals from the running sums made
    // once, the last part here.
    const double end = std::min(R, r_max_);
    const std::size_t i = std::size_t(std::upper_bound(node_r_.begin(), node_r_.end(), end) - node_r_.begin()) - 1;
    Rgb sum = cumulative_[i];
    if (i + 1 < node_r_.size() && end > node_r_[i]) sum += interval_integral(node_r_[i], end);
    return sum;
}

Rgb RdProfile::interval_integral(double a, double b) const {
    const double c = 0.5 * (a + b), w = 0.5 * (b - a);
    Rgb sum;
    for (int g = 0; g < 4; ++g) {
        const double r = c + w * kGaussLegendre4X[g];
        // The table is cubic in r inside a node interval: 4 points integrate r f exactly.
        Rgb f;
        if (integrate_table_) {
            const Hermite h = hermite(r);
            f = Rgb(h.f(0), h.f(1), h.f(2));
        } else {
            f = rd_(r);
        }
        sum += f * (kGaussLegendre4W[g] * w * 2 * kPi * r);
    }
    return sum;
}

Rgb RdProfile::near_reflectance(double h) const {
    // (1 - w) = 1 below R0 - h: the disc integral; over the ramp, Simpson.
    const double r0 = 2.0 * h, a = std::max(0.0, r0 - h), b = r0 + h;
    Rgb sum = disc(a);
    const int n = 256;
    const double step = (b - a) / n;
    for (int i = 0; i <= n; ++i) {
        const double r = a + i * step;
        const double wt = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
        sum += rd_(r) * ((1.0 - far_window(r, r0, h)) * 2.0 * kPi * r * wt * step / 3.0);
    }
    return sum;
}

double RdProfile::radius_containing(double fraction) const {
    double lo = 0, hi = r_max_;
    for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi);
        const Rgb d = disc(mid);
        bool enough = true;
        for (int c = 0; c < 3; ++c) enough = enough && d[c] >= fraction * total_[c];
        (enough ? hi : lo) = mid;
    }
    return hi;
}

}  // namespace shading
