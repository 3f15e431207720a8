// Hierarchical subsurface scattering over sampled surface points; see subsurface.h. The
// sampling itself (lines, refinement) is subsurface_sampling.cpp.
#include "shading/subsurface/subsurface.h"

#include "shading/core/quadrature.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <stdexcept>

namespace shading {

namespace {

// ---------------------------------------------------------------- statistics
// Build counters change once per object; lookup counters once per shaded point, so each
// thread counts its lookups in a block of its own (no shared cache line, no atomic
// read-modify-write on the hot path) and subsurface_stats() adds the blocks up.
std::atomic<std::size_t> g_clouds{0}, g_points{0}, g_refined{0};
std::atomic<std::int64_t> g_build_ns{0};
std::atomic<std::size_t> g_unbounded{0}, g_thin{0}, g_slab_objects{0};
std::atomic<int> g_max_levels{0};

struct alignas(64) LookupCounter {
    std::atomic<std::uint64_t> lookups{0}, visited{0}, slab{0};
};

struct Notes {
    std::mutex mutex;
    std::vector<std::unique_ptr<LookupCounter>> counters;
    std::vector<std::string> notes;
    double finest = 0;
    double thinnest = 0, thinnest_mfp = 0;  // over the objects with slab lookups (0: none)
};
Notes& notes() {
    static Notes n;
    return n;
}

LookupCounter& thread_counter() {
    thread_local LookupCounter* mine = nullptr;
    if (!mine) {
        Notes& n = notes();
        std::lock_guard<std::mutex> lock(n.mutex);
        n.counters.push_back(std::make_unique<LookupCounter>());
        mine = n.counters.back().get();
    }
    return *mine;
}

// Only this thread writes its counter: a relaxed load and store, no locked instruction.
void bump(std::atomic<std::uint64_t>& c, std::uint64_t by) {
    c.store(c.load(std::memory_order_relaxed) + by, std::memory_order_relaxed);
}

constexpr int kLeafSize = 8;

// Thin geometry (slab.h): slabs within 0.5 % of the half-space are the half-space; thickness
// nodes 32 per octave (neighbours 2.2 % apart: the profile of the nearest is used) from 0.01
// transport mean free paths (thinner is taken as that).
constexpr double kSlabTolerance = 0.005;
constexpr double kSlabPerOctave = 32;
constexpr double kSlabMinMfp = 0.01;
constexpr int kMaxDepth = 48;

// RdProfile nodes: 2^kSubBits per octave of s = 1 + r / scale.
constexpr int kSubBits = 6;
constexpr int kPerOctave = 1 << kSubBits;
constexpr int kMaxOctaves = 1000;  // s < 2^1000: far inside the double range

std::string fmt3(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", v);
    return buf;
}

// The profile averaged over an aggregate's points, to second order: f(|x - p|) ~ f(d) +
// (1/2) tr(H Sigma), H the Hessian in p: f'' u u^T + (f'/d)(I - u u^T), u = (c - x)/d (f', f''
// tabulated with f), Sigma the points' covariance `cov` (xx yy zz xy xz yz); v = c - x, dc2 =
// |v|^2. Times the aggregate's flux, never below 0 (the expansion can undershoot where Rd ~ 0).
Rgb aggregate_exitance(const RdProfile& rd, const double* C, const Rgb& flux, const Vec3& v, double dc2) {
    const double dc = std::sqrt(dc2), inv = 1.0 / dc;
    const Vec3 u = v * inv;
    const double uCu = u.x * (C[0] * u.x + C[3] * u.y + C[4] * u.z) +
                       u.y * (C[3] * u.x + C[1] * u.y + C[5] * u.z) +
                       u.z * (C[4] * u.x + C[5] * u.y + C[2] * u.z);
    const double a = 0.5 * uCu, b = 0.5 * (C[0] + C[1] + C[2] - uCu) * inv;
    Rgb f0, f1, f2;
    rd.eval(dc, &f0, &f1, &f2);
    Rgb out;
    out.r = std::max(0.0, f0.r + a * f2.r + b * f1.r) * flux.r;
    out.g = std::max(0.0, f0.g + a * f2.g + b * f1.g) * flux.g;
    out.b = std::max(0.0, f0.b + a * f2.b + b * f1.b) * flux.b;
    return out;
}

}  // namespace

SubsurfaceStats subsurface_stats() {
    SubsurfaceStats s;
    s.clouds = g_clouds.load();
    s.points = g_points.load();
    s.refined_points = g_refined.load();
    s.max_levels = g_max_levels.load();
    s.build_seconds = double(g_build_ns.load()) * 1e-9;
    s.unbounded = g_unbounded.load();
    s.thin = g_thin.load();
    Notes& n = notes();
    std::lock_guard<std::mutex> lock(n.mutex);
    for (const auto& c : n.counters) {
        s.lookups += c->lookups.load(std::memory_order_relaxed);
        s.nodes_visited += c->visited.load(std::memory_order_relaxed);
        s.slab_lookups += c->slab.load(std::memory_order_relaxed);
    }
    s.slab_objects = g_slab_objects.load();
    s.thinnest = n.thinnest;
    s.thinnest_mfp = n.thinnest_mfp;
    s.notes = n.notes;
    std::sort(s.notes.begin(), s.notes.end());
    s.finest_spacing = n.finest;
    return s;
}

// ---------------------------------------------------------------- RdProfile

RdProfile::RdProfile(Fn rd, Fn disc, double scale, double r_max)
    : rd_(std::move(rd)), disc_(std::move(disc)), scale_(scale), r_max_(r_max) {
    if (!rd_) throw std::invalid_argument("RdProfile: no profile");
    if (!(scale > 0) || !std::isfinite(scale) || !(r_max > 0) || !std::isfinite(r_max))
        throw std::invalid_argument("RdProfile: scale and r_max must be finite and > 0");
    inv_scale_ = 1.0 / scale;
    const double smax = 1.0 + r_max / scale;
    const int octaves = std::max(1, int(std::ceil(std::log2(smax))));
    if (octaves > kMaxOctaves) throw std::invalid_argument("RdProfile: r_max / scale out of range");
    const int n = octaves * kPerOctave;
    nodes_.resize(n + 1);
    node_r_.resize(n + 1);
    for (int i = 0; i <= n; ++i) {
        const double s = std::ldexp(1.0 + double(i % kPerOctave) / kPerOctave, i / kPerOctave);
        const double r = scale * (s - 1.0);
        node_r_[i] = r;
        // Derivatives by central differences, step 1e-3 of the local scale r + scale (about a
        // tenth of the node interval); below r = e the even extension of Rd (a function of
        // |r|) supplies the point at r - e.
        // The third derivative (for the Hermite interpolation of f'') takes a 10x larger step:
        // its rounding error grows as 1/e^3.
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

std::shared_ptr<const RdProfile> RdProfile::of(std::shared_ptr<const RadialProfile> model) {
    if (!model) throw std::invalid_argument("RdProfile::of: no profile");
    const double cutoff = model->cutoff();
    const double r_max = cutoff > 0 ? cutoff : 1.0;  // every channel empty: Rd = 0 anyway
    const double mfp = model->mean_free_path();  // the dipole's: its smallest zr = 1/sigma_t'
    const double scale = mfp > 0 ? mfp : r_max;
    return std::make_shared<const RdProfile>([model](double r) { return model->rd(r); },
                                             [model](double R) { return model->rd_disc(R); }, scale, r_max);
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

Rgb RdProfile::rd(double r) const {
    if (!(r < r_max_)) return Rgb(0.0);
    // s = 1 + r / scale >= 1: the octave and the node inside it are the exponent and the top
    // kSubBits mantissa bits of s; the rest of the mantissa is the position between nodes.
    const double s = 1.0 + std::max(0.0, r) * inv_scale_;
    std::uint64_t bits;
    std::memcpy(&bits, &s, sizeof bits);
    const std::size_t i = std::size_t((bits >> (52 - kSubBits)) - (std::uint64_t(1023) << kSubBits));
    const double u = double(bits & ((std::uint64_t(1) << (52 - kSubBits)) - 1)) * (1.0 / double(std::uint64_t(1) << (52 - kSubBits)));
    const Node& a = nodes_[i];
    const Node& b = nodes_[i + 1];
    const double dr = node_r_[i + 1] - node_r_[i];
    const double u2 = u * u, u3 = u2 * u;
    const double h00 = 2 * u3 - 3 * u2 + 1, h10 = (u3 - 2 * u2 + u) * dr, h01 = 3 * u2 - 2 * u3, h11 = (u3 - u2) * dr;
    // Cubic Hermite can dip a hair below 0 where Rd itself is ~0 (the far tail): clamp.
    return Rgb(std::max(0.0, h00 * a.f[0] + h10 * a.d1[0] + h01 * b.f[0] + h11 * b.d1[0]),
               std::max(0.0, h00 * a.f[1] + h10 * a.d1[1] + h01 * b.f[1] + h11 * b.d1[1]),
               std::max(0.0, h00 * a.f[2] + h10 * a.d1[2] + h01 * b.f[2] + h11 * b.d1[2]));
}

void RdProfile::eval(double r, Rgb* f, Rgb* d1, Rgb* d2) const {
    if (!(r < r_max_)) {
        *f = *d1 = *d2 = Rgb(0.0);
        return;
    }
    const double s = 1.0 + std::max(0.0, r) * inv_scale_;
    std::uint64_t bits;
    std::memcpy(&bits, &s, sizeof bits);
    const std::size_t i = std::size_t((bits >> (52 - kSubBits)) - (std::uint64_t(1023) << kSubBits));
    const double u = double(bits & ((std::uint64_t(1) << (52 - kSubBits)) - 1)) * (1.0 / double(std::uint64_t(1) << (52 - kSubBits)));
    const Node& a = nodes_[i];
    const Node& b = nodes_[i + 1];
    const double dr = node_r_[i + 1] - node_r_[i], inv_dr = 1.0 / dr;
    const double u2 = u * u, u3 = u2 * u;
    // Hermite basis and its derivative (per unit r)
    const double h00 = 2 * u3 - 3 * u2 + 1, h10 = (u3 - 2 * u2 + u) * dr, h01 = 3 * u2 - 2 * u3, h11 = (u3 - u2) * dr;
    const double g00 = (6 * u2 - 6 * u) * inv_dr, g10 = 3 * u2 - 4 * u + 1, g11 = 3 * u2 - 2 * u;
    *f = Rgb(h00 * a.f[0] + h10 * a.d1[0] + h01 * b.f[0] + h11 * b.d1[0],
             h00 * a.f[1] + h10 * a.d1[1] + h01 * b.f[1] + h11 * b.d1[1],
             h00 * a.f[2] + h10 * a.d1[2] + h01 * b.f[2] + h11 * b.d1[2]);
    *d1 = Rgb(g00 * (a.f[0] - b.f[0]) + g10 * a.d1[0] + g11 * b.d1[0],
              g00 * (a.f[1] - b.f[1]) + g10 * a.d1[1] + g11 * b.d1[1],
              g00 * (a.f[2] - b.f[2]) + g10 * a.d1[2] + g11 * b.d1[2]);
    *d2 = Rgb(h00 * a.d2[0] + h10 * a.d3[0] + h01 * b.d2[0] + h11 * b.d3[0],
              h00 * a.d2[1] + h10 * a.d3[1] + h01 * b.d2[1] + h11 * b.d3[1],
              h00 * a.d2[2] + h10 * a.d3[2] + h01 * b.d2[2] + h11 * b.d3[2]);
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
        sum += rd_(r) * (kGaussLegendre4W[g] * w * 2 * kPi * r);
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
        sum += rd_(r) * ((1.0 - PointCloud::window(r, r0, h)) * 2.0 * kPi * r * wt * step / 3.0);
    }
    return sum;
}

// ---------------------------------------------------------------- PointCloud

namespace {

// Float bounds rounded outwards: distances to them never exceed distances to the true bounds.
float round_down(double v) {
    const float f = float(v);
    return double(f) > v ? std::nextafter(f, -std::numeric_limits<float>::infinity()) : f;
}
float round_up(double v) {
    const float f = float(v);
    return double(f) < v ? std::nextafter(f, std::numeric_limits<float>::infinity()) : f;
}

// Squared distance from x to a box (0 inside).
inline double box_distance2(const Vec3& x, const float* lo, const float* hi) {
    const double dx = x.x < lo[0] ? lo[0] - x.x : (x.x > hi[0] ? x.x - hi[0] : 0.0);
    const double dy = x.y < lo[1] ? lo[1] - x.y : (x.y > hi[1] ? x.y - hi[1] : 0.0);
    const double dz = x.z < lo[2] ? lo[2] - x.z : (x.z > hi[2] ? x.z - hi[2] : 0.0);
    return dx * dx + dy * dy + dz * dz;
}


}  // namespace

PointCloud::PointCloud(std::vector<SurfacePoint> points, double spacing, const Rgb& near)
    : spacing_(spacing), points_(std::move(points)) {
    for (SurfacePoint& p : points_) {
        p.spacing = spacing;
        thinnest_ = std::min(thinnest_, p.thickness);
    }
    levels_.push_back({spacing, near});
    if (!points_.empty()) build_tree(nullptr);
    finish();
}

PointCloud::PointCloud(std::vector<SurfacePoint> points, const NearFn& near, const ParallelFor* parallel)
    : points_(std::move(points)) {
    double coarsest = 0, finest = kInf;
    for (const SurfacePoint& p : points_) {
        if (!(p.spacing > 0) || !std::isfinite(p.spacing)) throw std::invalid_argument("PointCloud: every point needs a spacing > 0");
        coarsest = std::max(coarsest, p.spacing);
        finest = std::min(finest, p.spacing);
        thinnest_ = std::min(thinnest_, p.thickness);
    }
    spacing_ = coarsest > 0 ? coarsest : 1.0;
    if (!points_.empty()) build_tree(parallel);
    if (points_.empty() || finest == coarsest) {
        levels_.push_back({spacing_, near(spacing_)});
        finish();
        return;
    }
    // Each point's lookup spacing: the fixed point of H <- max spacing within 3H (from its own
    // spacing up): the window's ramp [H, 3H] around a lookup there then holds no sample coarser
    // than H. Found once per leaf for the leaf's box (so a point may take the coarser value of
    // a neighbour up to a leaf away). Levels are the distinct values, coarsest first.
    // Each query starts at the smallest node whose octree cell holds the leaf's box widened
    // by 3H: every point that close lies under it (cells, unlike the nodes' tight bounds,
    // partition space).
    std::vector<int> parent(nodes_.size(), -1);
    std::vector<std::array<double, 6>> cell(nodes_.size());
    cell[0] = {-kInf, -kInf, -kInf, kInf, kInf, kInf};
    for (std::size_t k = 0; k < nodes_.size(); ++k) {
        const Node& nd = nodes_[k];
        for (int c = nd.child; c >= 0 && c < nd.child + nd.children; ++c) {
            parent[c] = int(k);
            std::array<double, 6> b = cell[k];
            const Vec3& sp = aux_[k].split;
            const double split[3] = {sp.x, sp.y, sp.z};
            for (int a = 0; a < 3; ++a) {
                if (nodes_[c].octant & (1 << a)) b[a] = split[a];
                else b[3 + a] = split[a];
            }
            cell[c] = b;
        }
    }
    std::vector<int> leaves;
    for (std::size_t k = 0; k < nodes_.size(); ++k)
        if (nodes_[k].child < 0) leaves.push_back(int(k));
    std::vector<double> leaf_h(leaves.size());
    auto settle = [&](std::size_t c, SurfaceSampler*) {
        for (std::size_t l = 64 * c; l < std::min(leaves.size(), 64 * (c + 1)); ++l) {
            const int leaf = leaves[l];
            const Node& nd = nodes_[leaf];
            double H = 0;
            for (int i = nd.first; i < nd.first + nd.count; ++i) H = std::max(H, points_[i].spacing);
            while (H < coarsest) {
                const double r = 3.0 * H;
                int start = leaf;
                auto holds = [&](int k) {
                    const std::array<double, 6>& b = cell[k];
                    for (int a = 0; a < 3; ++a)
                        if (!(b[a] <= nd.lo[a] - r && nd.hi[a] + r < b[3 + a])) return false;
                    return true;
                };
                while (parent[start] >= 0 && !holds(start)) start = parent[start];
                const double m = max_spacing_within(start, nd.lo, nd.hi, r, H);
                if (!(m > H)) break;
                H = m;
            }
            leaf_h[l] = H;
        }
    };
    const std::size_t chunks = (leaves.size() + 63) / 64;
    if (parallel) (*parallel)(chunks, [&](std::size_t c, SurfaceSampler& s) { settle(c, &s); });
    else for (std::size_t c = 0; c < chunks; ++c) settle(c, nullptr);
    std::vector<double> distinct;
    std::vector<double> lookup(points_.size());
    for (std::size_t l = 0; l < leaves.size(); ++l) {
        const Node& nd = nodes_[leaves[l]];
        const double H = leaf_h[l];
        for (int i = nd.first; i < nd.first + nd.count; ++i) lookup[i] = H;
        if (std::find(distinct.begin(), distinct.end(), H) == distinct.end()) distinct.push_back(H);
    }
    std::sort(distinct.begin(), distinct.end(), std::greater<double>());
    if (distinct.size() > 127) throw std::invalid_argument("PointCloud: more than 127 distinct spacings");
    for (double h : distinct) levels_.push_back({h, near(h)});
    level_of_.resize(points_.size());
    for (std::size_t i = 0; i < points_.size(); ++i)
        level_of_[i] = std::uint8_t(std::find(distinct.begin(), distinct.end(), lookup[i]) - distinct.begin());
    finish();
}

struct PointCloud::Tree {
    std::vector<Node> nodes;
    std::vector<Agg> aggs;
    std::vector<Aux> aux;
    std::vector<Merge> merge;
    std::vector<Cone> cones;
    int grow(int n) {
        const int at = int(nodes.size());
        nodes.resize(at + n);
        aggs.resize(at + n);
        aux.resize(at + n);
        merge.resize(at + n);
        cones.resize(at + n);
        return at;
    }
};

// The root splits here; its (at most 8) subtrees build in parallel, each into a tree of its
// own, and are spliced in behind the root and its children in octant order: the same tree for
// any number of threads.
void PointCloud::build_tree(const ParallelFor* parallel) {
    Tree t;
    t.grow(1);
    const int n_points = int(points_.size());
    int ranges[8][3];
    const int n = split(t, 0, 0, n_points, 0, ranges);
    if (n > 1) {
        std::vector<Tree> sub(n);
        auto one = [&](std::size_t k) {
            sub[k].grow(1);
            build(sub[k], 0, ranges[k][0], ranges[k][1], 1);
        };
        if (parallel) (*parallel)(std::size_t(n), [&](std::size_t k, SurfaceSampler&) { one(k); });
        else for (int k = 0; k < n; ++k) one(std::size_t(k));
        std::size_t total = 1 + n;
        for (const Tree& s : sub) total += s.nodes.size() - 1;
        t.nodes.reserve(total);
        t.aggs.reserve(total);
        t.aux.reserve(total);
        t.merge.reserve(total);
        t.cones.reserve(total);
        t.grow(n);
        t.nodes[0].child = 1;
        t.nodes[0].children = std::int16_t(n);
        int base = 1 + n;  // where subtree k's node 1 goes
        for (int k = 0; k < n; ++k) {
            const Tree& s = sub[k];
            const int shift = base - 1;  // local j >= 1 -> base + j - 1
            auto place = [&](int to, int from) {
                t.nodes[to] = s.nodes[from];
                if (t.nodes[to].child >= 0) t.nodes[to].child += shift;
                t.aggs[to] = s.aggs[from];
                t.aux[to] = s.aux[from];
                t.merge[to] = s.merge[from];
                t.cones[to] = s.cones[from];
            };
            place(1 + k, 0);
            t.nodes[1 + k].octant = std::uint8_t(ranges[k][2]);
            const int at = t.grow(int(s.nodes.size()) - 1);
            for (int j = 1; j < int(s.nodes.size()); ++j) place(at + j - 1, j);
            base += int(s.nodes.size()) - 1;
        }
    }
    aggregate(t, 0, 0, n_points, n);
    nodes_ = std::move(t.nodes);
    aggs_ = std::move(t.aggs);
    aux_ = std::move(t.aux);
    cones_ = std::move(t.cones);
}

// Bounds top-down (the split needs them), aggregates bottom-up: a leaf's from its points, a
// parent's by merging its children's (weights, means and covariances, the parallel-axis rule),
// so each point is read O(1) times for the aggregates whatever the depth.
void PointCloud::build(Tree& t, int index, int first, int count, int depth) {
    int ranges[8][3];
    const int n = split(t, index, first, count, depth, ranges);
    if (n > 1) {
        const int child = t.grow(n);
        t.nodes[index].child = child;
        t.nodes[index].children = std::int16_t(n);
        for (int k = 0; k < n; ++k) {
            t.nodes[child + k].octant = std::uint8_t(ranges[k][2]);
            build(t, child + k, ranges[k][0], ranges[k][1], depth + 1);
        }
    }
    aggregate(t, index, first, count, n);
}

// The node's bounds, and its points partitioned in place into the non-empty octants about the
// centre of the bounds: ranges (first, count, octant), how many (<= 1: a leaf).
int PointCloud::split(Tree& t, int index, int first, int count, int depth, int ranges[8][3]) {
    Vec3 lo = points_[first].p, hi = lo;
    for (int i = first + 1; i < first + count; ++i) {
        const Vec3& p = points_[i].p;
        lo = Vec3(std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z));
        hi = Vec3(std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z));
    }
    Node& nd = t.nodes[index];
    nd.lo[0] = round_down(lo.x), nd.lo[1] = round_down(lo.y), nd.lo[2] = round_down(lo.z);
    nd.hi[0] = round_up(hi.x), nd.hi[1] = round_up(hi.y), nd.hi[2] = round_up(hi.z);
    const Vec3 span = hi - lo;
    nd.diag2 = round_up(dot(span, span));
    nd.first = first;
    nd.count = count;
    t.aux[index].split = (lo + hi) * 0.5;
    t.aggs[index].centre = lo;  // (the unlit, arealess fallback; aggregate() sets the real one)
    int n = 0;
    if (count <= kLeafSize || depth >= kMaxDepth || !(dot(span, span) > 0)) return 0;
    const Vec3 c = t.aux[index].split;
    auto begin = points_.begin() + first, end = begin + count;
    auto mz = std::partition(begin, end, [&](const SurfacePoint& s) { return s.p.z < c.z; });
    auto my0 = std::partition(begin, mz, [&](const SurfacePoint& s) { return s.p.y < c.y; });
    auto my1 = std::partition(mz, end, [&](const SurfacePoint& s) { return s.p.y < c.y; });
    auto split_x = [&](std::vector<SurfacePoint>::iterator a, std::vector<SurfacePoint>::iterator b) {
        return std::partition(a, b, [&](const SurfacePoint& s) { return s.p.x < c.x; });
    };
    auto mx0 = split_x(begin, my0), mx1 = split_x(my0, mz), mx2 = split_x(mz, my1), mx3 = split_x(my1, end);
    // Range k holds octant k: bit 0 set for x >= c.x, bit 1 for y, bit 2 for z.
    const std::vector<SurfacePoint>::iterator bounds[9] = {begin, mx0, my0, mx1, mz, mx2, my1, mx3, end};
    for (int k = 0; k < 8; ++k) {
        int a = int(bounds[k] - points_.begin()), b = int(bounds[k + 1] - points_.begin());
        if (b > a) {
            ranges[n][0] = a;
            ranges[n][1] = b - a;
            ranges[n][2] = k;
            ++n;
        }
    }
    return n;
}

// A node's aggregate: from its points (a leaf, n <= 1) or by merging its n children's.
void PointCloud::aggregate(Tree& t, int index, int first, int count, int n) {
    // Weights: w = flux summed over channels (the centre and covariance), a = area (the centre
    // of an unlit node).
    double wsum = 0, area = 0;
    Vec3 wmean, amean;
    double cov[6] = {0, 0, 0, 0, 0, 0};
    Rgb flux;
    double max_spacing = 0;
    Vec3 nsum;
    auto add = [&](double w, double a, const Vec3& cw, const Vec3& ca, const double* S, const Rgb& f, double sp) {
        // merge (w, cw, S) into the running (wsum, wmean, cov): parallel-axis rule
        if (w > 0) {
            const double W = wsum + w;
            const Vec3 d = cw - wmean;
            const double tw = wsum * w / W;  // weight of the between-means term
            for (int k = 0; k < 6; ++k) cov[k] = (wsum * cov[k] + w * S[k]) / W;
            cov[0] += tw * d.x * d.x / W, cov[1] += tw * d.y * d.y / W, cov[2] += tw * d.z * d.z / W;
            cov[3] += tw * d.x * d.y / W, cov[4] += tw * d.x * d.z / W, cov[5] += tw * d.y * d.z / W;
            wmean = wmean + d * (w / W);
            wsum = W;
        }
        if (a > 0) {
            const double A = area + a;
            amean = amean + (ca - amean) * (a / A);
            area = A;
        }
        flux += f;
        max_spacing = std::max(max_spacing, sp);
    };
    // The normal cone (thin geometry): axis along the area-weighted normal sum, half-angle the
    // widest normal (a leaf) or child cone (a parent) from it, rounded up; pi when the normals
    // cancel.
    double cone = 0;
    auto angle_to = [](const Vec3& axis, const Vec3& v) { return std::acos(std::max(-1.0, std::min(1.0, dot(axis, v)))); };
    if (n <= 1) {
        static const double zero[6] = {0, 0, 0, 0, 0, 0};
        for (int i = first; i < first + count; ++i) {
            const SurfacePoint& s = points_[i];
            const Rgb f = s.irradiance * s.area;
            add(f.r + f.g + f.b, s.area, s.p, s.p, zero, f, s.spacing);
            nsum = nsum + s.n * std::max(s.area, 1e-300);
        }
        const double len = length(nsum);
        const Vec3 axis = len > 0 ? nsum * (1.0 / len) : Vec3(0, 0, 1);
        if (!(len > 0)) cone = kPi;
        for (int i = first; i < first + count && cone < kPi; ++i) cone = std::max(cone, angle_to(axis, points_[i].n));
    } else {
        const int child = t.nodes[index].child;
        for (int k = 0; k < n; ++k) {
            const Agg& c = t.aggs[child + k];
            const Merge& m = t.merge[child + k];
            add(m.wsum, m.area, c.centre, m.area_centre, c.cov, c.flux, t.aux[child + k].max_spacing);
            nsum = nsum + m.nsum;
        }
        const double len = length(nsum);
        const Vec3 axis = len > 0 ? nsum * (1.0 / len) : Vec3(0, 0, 1);
        if (!(len > 0)) cone = kPi;
        for (int k = 0; k < n && cone < kPi; ++k) {
            const Cone& cc = t.cones[child + k];
            cone = std::max(cone, angle_to(axis, Vec3(cc.axis[0], cc.axis[1], cc.axis[2])) + double(cc.angle));
        }
    }
    {
        const double len = length(nsum);
        const Vec3 axis = len > 0 ? nsum * (1.0 / len) : Vec3(0, 0, 1);
        Cone& cc = t.cones[index];
        cc.axis[0] = float(axis.x), cc.axis[1] = float(axis.y), cc.axis[2] = float(axis.z);
        // float axis and angle: 1e-5 rad covers their rounding
        cc.angle = float(std::min(kPi, cone + 1e-5));
    }
    Agg& g = t.aggs[index];
    t.merge[index] = {wsum, area, amean, nsum};
    // The flux-weighted centre is where an aggregate's light comes from; an unlit node has
    // no flux to place, its area-weighted centre is used.
    if (wsum > 0) g.centre = wmean;
    else if (area > 0) g.centre = amean;
    for (int k = 0; k < 6; ++k) g.cov[k] = wsum > 0 ? cov[k] : 0.0;
    g.flux = flux;
    t.aux[index].max_spacing = max_spacing;
    t.nodes[index].lit = flux.max_component() > 0;
}

void PointCloud::finish() {
    leaves_.resize(points_.size());
    for (std::size_t i = 0; i < points_.size(); ++i) leaves_[i] = {points_[i].p, points_[i].irradiance * points_[i].area};
    // Children come after their parent: one backward pass settles which nodes share one level.
    for (std::size_t k = nodes_.size(); k-- > 0;) {
        Node& nd = nodes_[k];
        if (level_of_.empty()) {
            nd.uniform = 0;
            continue;
        }
        int level = -2;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count && level != -1; ++i)
                level = level == -2 || level == level_of_[i] ? level_of_[i] : -1;
        } else {
            for (int c = nd.child; c < nd.child + nd.children && level != -1; ++c)
                level = nodes_[c].uniform < 0 ? -1 : (level == -2 || level == nodes_[c].uniform ? nodes_[c].uniform : -1);
        }
        nd.uniform = std::int8_t(level < 0 ? -1 : level);
    }
}

double PointCloud::max_spacing_within(int start, const float* lo, const float* hi, double radius, double above) const {
    // The largest spacing above `above` among points within `radius` of the box [lo, hi]
    // (nodes are pruned by the box widened by `radius` in each axis, points by distance).
    double best = above;
    if (nodes_.empty()) return best;
    const double r2 = radius * radius;
    const double qlo[3] = {lo[0] - radius, lo[1] - radius, lo[2] - radius};
    const double qhi[3] = {hi[0] + radius, hi[1] + radius, hi[2] + radius};
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = start;
    while (top > 0) {
        const int k = stack[--top];
        const Node& nd = nodes_[k];
        if (!(aux_[k].max_spacing > best) || nd.hi[0] < qlo[0] || nd.lo[0] > qhi[0] || nd.hi[1] < qlo[1] ||
            nd.lo[1] > qhi[1] || nd.hi[2] < qlo[2] || nd.lo[2] > qhi[2])
            continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                if (!(points_[i].spacing > best)) continue;
                const Vec3& p = points_[i].p;
                const double dx = std::max({double(lo[0]) - p.x, 0.0, p.x - double(hi[0])});
                const double dy = std::max({double(lo[1]) - p.y, 0.0, p.y - double(hi[1])});
                const double dz = std::max({double(lo[2]) - p.z, 0.0, p.z - double(hi[2])});
                if (dx * dx + dy * dy + dz * dz < r2) best = points_[i].spacing;
            }
            continue;
        }
        for (int c = 0; c < nd.children; ++c) stack[top++] = nd.child + c;
    }
    return best;
}

int PointCloud::nearest(const Vec3& x) const {
    int best = -1;
    double best_d2 = kInf;
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& nd = nodes_[stack[--top]];
        if (!(box_distance2(x, nd.lo, nd.hi) < best_d2)) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Vec3 v = points_[i].p - x;
                const double d2 = dot(v, v);
                if (d2 < best_d2) {
                    best_d2 = d2;
                    best = i;
                }
            }
            continue;
        }
        // Push the children farthest first, so the nearest is opened first and prunes the rest.
        int order[8];
        double dist[8];
        for (int k = 0; k < nd.children; ++k) {
            order[k] = nd.child + k;
            dist[k] = box_distance2(x, nodes_[order[k]].lo, nodes_[order[k]].hi);
        }
        for (int a = 1; a < nd.children; ++a)
            for (int b = a; b > 0 && dist[b] > dist[b - 1]; --b) {
                std::swap(dist[b], dist[b - 1]);
                std::swap(order[b], order[b - 1]);
            }
        for (int k = 0; k < nd.children; ++k) stack[top++] = order[k];
    }
    return best;
}

int PointCloud::lookup_level(const Vec3& x) const {
    if (level_of_.empty() || nodes_.empty()) return 0;
    // Down the octants that hold x until a node whose points share one level; where x's
    // octant is empty or a leaf is mixed, the nearest point decides.
    int k = 0;
    for (;;) {
        const Node& nd = nodes_[k];
        if (nd.uniform >= 0) return nd.uniform;
        if (nd.child < 0) break;
        const Vec3& c = aux_[k].split;
        const int oct = int(x.x >= c.x) | (int(x.y >= c.y) << 1) | (int(x.z >= c.z) << 2);
        int next = -1;
        for (int i = nd.child; i < nd.child + nd.children; ++i)
            if (nodes_[i].octant == oct) next = i;
        if (next < 0) break;
        k = next;
    }
    const int i = nearest(x);
    return i < 0 ? 0 : level_of_[i];
}

double PointCloud::window(double r, double r0, double h) {
    double t = (r - (r0 - h)) / (2.0 * h);
    if (t <= 0) return 0.0;
    if (t >= 1) return 1.0;
    return t * t * t * (t * (6.0 * t - 15.0) + 10.0);
}

Rgb PointCloud::far_exitance(const RdProfile& rd, const Vec3& x, double r0, double h, double max_angle,
                             double cutoff, std::size_t* visited) const {
    Rgb sum;
    if (nodes_.empty()) return sum;
    const double inner2 = sqr(std::max(0.0, r0 - h)), outer = r0 + h, outer2 = outer * outer;
    const double cutoff2 = cutoff * cutoff, angle2 = max_angle * max_angle;
    // widened angles (RdProfile::angle_gain2) stay below 1: the expansion's limit
    const double gain_cap = std::max(1.0, 1.0 / angle2);
    std::size_t opened = 0;
    int stack[8 * kMaxDepth + 16];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const int k = stack[--top];
        const Node& nd = nodes_[k];
        ++opened;
        // Unlit nodes (shadowed, facing away from every light) bring nothing.
        if (!nd.lit) continue;
        const double dbox2 = box_distance2(x, nd.lo, nd.hi);
        if (dbox2 > cutoff2) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const Leaf& s = leaves_[i];
                const Vec3 v = x - s.p;
                const double r2 = dot(v, v);
                // w = 0 inside the ramp's start: no square root, no profile
                if (r2 <= inner2 || r2 > cutoff2) continue;
                const double r = std::sqrt(r2);
                const double w = r2 >= outer2 ? 1.0 : window(r, r0, h);
                sum += rd.rd(r) * s.flux * w;
            }
            continue;
        }
        // Aggregate only nodes wholly beyond the window's ramp (w = 1 for all their points).
        if (dbox2 > outer2) {
            const Agg& g = aggs_[k];
            const Vec3 v = g.centre - x;
            const double dc2 = dot(v, v);
            if (double(nd.diag2) < angle2 * std::min(rd.angle_gain2(dc2), gain_cap) * dc2) {
                const Rgb e = aggregate_exitance(rd, g.cov, g.flux, v, dc2);
                sum.r += e.r;
                sum.g += e.g;
                sum.b += e.b;
                continue;
            }
        }
        for (int c = 0; c < nd.children; ++c) stack[top++] = nd.child + c;
    }
    if (visited) *visited += opened;
    return sum;
}

Rgb PointCloud::far_exitance_exact(const RdProfile& rd, const Vec3& x, double r0, double h) const {
    Rgb sum;
    for (const SurfacePoint& s : points_) {
        const double r = length(x - s.p);
        const double w = window(r, r0, h);
        if (w > 0) sum += rd.exact(r) * s.irradiance * (s.area * w);
    }
    return sum;
}

Rgb PointCloud::far_exitance_sided(const RdProfile& same, const RdProfile& transmit, const Vec3& x, const Vec3& nx,
                                   double d, double r0, double h, double max_angle, const Rgb& near_opposite,
                                   std::size_t* visited, Rgb* opposite) const {
    Rgb sum, opp_sum;  // the opposite face's part of sum (added to both: sum's order as before)
    if (opposite) *opposite = Rgb(0.0);
    if (nodes_.empty()) return sum;
    const double inner2 = sqr(std::max(0.0, r0 - h)), outer = r0 + h, outer2 = outer * outer;
    const double d2 = d * d;
    const double cut_same2 = sqr(same.r_max()), cut_t = transmit.r_max();
    // rho >= sqrt(s^2 - d^2): nothing of T beyond s^2 = r_max^2 + d^2
    const double cut_opp2 = cut_t * cut_t + d2;
    const double cut2 = std::max(cut_same2, cut_opp2);
    const double angle2 = max_angle * max_angle;
    const double gain_cap = std::max(1.0, 1.0 / angle2);
    constexpr double kHalfPi = 0.5 * kPi;
    // The lateral distance of p from x for the transmission profile: rho^2 = s^2 - min(v.nx, d)^2
    // (v = x - p): a flat slab's sqrt(s^2 - d^2) on its opposite face, the distance across
    // x's normal line where the far side is closer than d (a curved object), and never below
    // the lateral distance, which moves by at most |p - q| between points p, q.
    auto rho_of = [&](const Vec3& p) {
        const Vec3 v = x - p;
        const double vn = std::min(std::fabs(dot(v, nx)), d);
        return std::sqrt(std::max(0.0, dot(v, v) - vn * vn));
    };
    // The opposite face's near field: inside the window (in rho) its points only give their
    // irradiance to a (1 - w)-weighted mean, which lights the part of T inside the window
    // (near_opposite, integrated, not sampled: T's peak is as narrow as the slab and would
    // fall between samples).
    double near_area = 0;
    Rgb near_flux;
    std::size_t opened = 0;
    // Stack entries: node, side (0: not known yet, 1: every normal on nx's side, 2: every
    // normal on the other side; a side, once known, holds for the subtree).
    int stack[8 * kMaxDepth + 16];
    std::uint8_t sides[8 * kMaxDepth + 16];
    int top = 0;
    stack[top] = 0;
    sides[top++] = 0;
    auto add_point = [&](int i, bool opp) {
        const Leaf& s = leaves_[i];
        const Vec3 v = x - s.p;
        const double r2 = dot(v, v);
        if (opp) {
            if (r2 > cut_opp2) return;
            const double rho = rho_of(s.p);
            double w = 1.0;
            if (rho < outer) {
                w = rho * rho <= inner2 ? 0.0 : window(rho, r0, h);
                near_area += (1.0 - w) * points_[i].area;
                near_flux += s.flux * (1.0 - w);
            }
            if (w > 0) {
                const Rgb t = transmit.rd(rho) * s.flux * w;
                sum += t;
                opp_sum += t;
            }
            return;
        }
        if (r2 <= inner2 || r2 > cut_same2) return;
        const double r = std::sqrt(r2);
        const double w = r2 >= outer2 ? 1.0 : window(r, r0, h);
        sum += same.rd(r) * s.flux * w;
    };
    while (top > 0) {
        --top;
        const int k = stack[top];
        int side = sides[top];
        const Node& nd = nodes_[k];
        ++opened;
        if (!nd.lit) continue;
        const double dbox2 = box_distance2(x, nd.lo, nd.hi);
        if (dbox2 > cut2) continue;
        // The side an aggregate of this node takes: `side` where known; else, for a node of
        // one sheet (its normals within 90 degrees of its axis: a curved surface crossing the
        // plane of nx, e.g. the rim of a sphere seen from x), its axis's side (its points on
        // the other side are few, at the seam of the two profiles); a node whose normals
        // spread wider (both faces of a sheet) has none and is opened.
        int agg_side = side;
        if (side == 0) {
            // The cone's axis at angle phi from nx, half-angle c: every normal has dot > 0 with
            // nx when phi + c < pi/2, dot < 0 when phi - c > pi/2.
            const Cone& cc = cones_[k];
            const double phi = std::acos(std::max(-1.0, std::min(1.0, cc.axis[0] * nx.x + cc.axis[1] * nx.y + cc.axis[2] * nx.z)));
            if (phi + cc.angle < kHalfPi) side = 1;
            else if (phi - cc.angle > kHalfPi) side = 2;
            agg_side = side != 0 ? side : (cc.angle < kHalfPi ? (phi < kHalfPi ? 1 : 2) : 0);
        }
        if (side == 1 && dbox2 > cut_same2) continue;
        if (side == 2 && dbox2 > cut_opp2) continue;
        if (nd.child < 0) {
            for (int i = nd.first; i < nd.first + nd.count; ++i) {
                const bool opp = side == 2 || (side == 0 && !(dot(points_[i].n, nx) > 0));
                add_point(i, opp);
            }
            continue;
        }
        if (agg_side == 1 && dbox2 > outer2) {
            // As far_exitance: Rd at the centre plus (1/2) tr(H Sigma).
            const Agg& g = aggs_[k];
            const Vec3 v = g.centre - x;
            const double dc2 = dot(v, v);
            if (double(nd.diag2) < angle2 * std::min(same.angle_gain2(dc2), gain_cap) * dc2) {
                const Rgb e = aggregate_exitance(same, g.cov, g.flux, v, dc2);
                sum.r += e.r;
                sum.g += e.g;
                sum.b += e.b;
                continue;
            }
        } else if (agg_side == 2) {
            // T at the centre's rho plus the second-order term of its expansion in the plane
            // across nx (exact geometry for a flat slab, where rho is the in-plane distance):
            // (1/2) tr(H Sigma_p), H = T'' u u^T + (T'/rho)(I - u u^T) in that plane, Sigma_p
            // the covariance projected onto it, u the in-plane direction to the centre. For a
            // node wholly beyond the window in rho (rho of any of its points >= the centre's -
            // the diagonal) and small as seen from x.
            const Agg& g = aggs_[k];
            const Vec3 v = g.centre - x;
            const double dc2 = dot(v, v), diag = std::sqrt(double(nd.diag2));
            const double rho = rho_of(g.centre);
            if (rho - diag > outer && double(nd.diag2) < angle2 * dc2) {
                const Vec3 lat = v - nx * dot(v, nx);
                const double ll = length(lat);
                const Vec3 u = ll > 0 ? lat * (1.0 / ll) : Vec3(0, 0, 0);
                const double* C = g.cov;
                auto quad = [C](const Vec3& a) {
                    return a.x * (C[0] * a.x + C[3] * a.y + C[4] * a.z) + a.y * (C[3] * a.x + C[1] * a.y + C[5] * a.z) +
                           a.z * (C[4] * a.x + C[5] * a.y + C[2] * a.z);
                };
                const double uCu = quad(u), nCn = quad(nx);
                const double a = 0.5 * uCu, b = 0.5 * std::max(0.0, C[0] + C[1] + C[2] - nCn - uCu) / rho;
                Rgb f0, f1, f2;
                transmit.eval(rho, &f0, &f1, &f2);
                const Rgb t(std::max(0.0, f0.r + a * f2.r + b * f1.r) * g.flux.r,
                            std::max(0.0, f0.g + a * f2.g + b * f1.g) * g.flux.g,
                            std::max(0.0, f0.b + a * f2.b + b * f1.b) * g.flux.b);
                sum.r += t.r;
                sum.g += t.g;
                sum.b += t.b;
                opp_sum += t;
                continue;
            }
        }
        for (int c = 0; c < nd.children; ++c) {
            stack[top] = nd.child + c;
            sides[top++] = std::uint8_t(side);
        }
    }
    if (visited) *visited += opened;
    if (near_area > 0) {
        const Rgb t = near_opposite * near_flux * (1.0 / near_area);
        sum += t;
        opp_sum += t;
    }
    if (opposite) *opposite = opp_sum;
    return sum;
}

Rgb PointCloud::far_exitance_sided_exact(const RdProfile& same, const RdProfile& transmit, const Vec3& x,
                                         const Vec3& nx, double d, double r0, double h, const Rgb& near_opposite) const {
    Rgb sum, near_flux;
    double near_area = 0;
    for (const SurfacePoint& s : points_) {
        const Vec3 v = x - s.p;
        const double r = length(v);
        if (dot(s.n, nx) > 0) {
            const double w = window(r, r0, h);
            if (w > 0) sum += same.exact(r) * s.irradiance * (s.area * w);
        } else {
            const double vn = std::min(std::fabs(dot(v, nx)), d);
            const double rho = std::sqrt(std::max(0.0, r * r - vn * vn));
            const double w = window(rho, r0, h);
            sum += transmit.exact(rho) * s.irradiance * (s.area * w);
            near_area += (1.0 - w) * s.area;
            near_flux += s.irradiance * ((1.0 - w) * s.area);
        }
    }
    if (near_area > 0) sum += near_opposite * near_flux * (1.0 / near_area);
    return sum;
}

CloudStats PointCloud::stats() const {
    CloudStats s;
    s.points = points_.size();
    s.nodes = nodes_.size();
    s.levels = levels_.size();
    s.finest_spacing = levels_.empty() ? spacing_ : levels_.back().h;
    for (const SurfacePoint& p : points_) s.total_area += p.area;
    return s;
}

// ---------------------------------------------------------------- Subsurface: the clouds
//
// Lookups read an immutable sorted index (key -> entry) through one atomic pointer and the
// entry's `ready` pointer: no lock once a cloud exists. A new key copies the index under the
// mutex and publishes the copy; old copies stay alive until the Subsurface goes (a reader may
// still be looking at one). Building: the first thread to ask is the leader and runs the
// sampling; it hands each parallel stage (lines, irradiance) to every thread that asks for the
// same cloud meanwhile: they take chunks of the stage with their own sampler until it is done
// and return when the cloud is.

namespace {

using Task = std::function<void(std::size_t, SurfaceSampler&)>;

struct Stage {
    Stage(std::size_t n_, const Task& f) : n(n_), fn(f) {}
    std::size_t n;
    Task fn;
    std::atomic<std::size_t> next{0};
    std::size_t done = 0;       // guarded by the entry's mutex
    std::exception_ptr error;   // the same
};

}  // namespace

struct Subsurface::Entry {
    const void* key = nullptr;
    std::atomic<const PointCloud*> ready{nullptr};
    std::shared_ptr<const PointCloud> cloud;
    std::mutex m;
    std::condition_variable cv;
    bool started = false, finished = false;
    std::exception_ptr error;
    std::shared_ptr<Stage> stage;
    std::uint64_t generation = 0;

    // Take chunks of `st` until none is left.
    void work(Stage& st, SurfaceSampler& sampler) {
        const std::size_t chunk = std::max<std::size_t>(1, std::min<std::size_t>(256, st.n / 64));
        for (;;) {
            const std::size_t i0 = st.next.fetch_add(chunk);
            if (i0 >= st.n) return;
            const std::size_t i1 = std::min(st.n, i0 + chunk);
            std::exception_ptr err;
            for (std::size_t i = i0; i < i1; ++i) {
                try {
                    st.fn(i, sampler);
                } catch (...) {
                    if (!err) err = std::current_exception();
                }
            }
            std::lock_guard<std::mutex> lock(m);
            if (err && !st.error) st.error = err;
            st.done += i1 - i0;
            if (st.done == st.n) cv.notify_all();
        }
    }
};

struct Subsurface::Index {
    std::vector<std::pair<const void*, Entry*>> sorted;
    Entry* find(const void* key) const {
        auto it = std::lower_bound(sorted.begin(), sorted.end(), key,
                                   [](const std::pair<const void*, Entry*>& a, const void* k) { return std::less<const void*>()(a.first, k); });
        return it != sorted.end() && it->first == key ? it->second : nullptr;
    }
};

Subsurface::Subsurface(const Medium& medium, const SubsurfaceSettings& settings, FdrModel fdr,
                       std::shared_ptr<const RadialProfile> model)
    : dipole_(medium, fdr), settings_(settings), model_(std::move(model)) {
    if (!(settings_.max_angle > 0 && settings_.max_angle <= 2.0))
        throw std::invalid_argument("dipole: error threshold must be in (0, 2], got " + std::to_string(settings_.max_angle));
    if (!(settings_.spacing >= 0) || !std::isfinite(settings_.spacing))
        throw std::invalid_argument("dipole: spacing must be >= 0 (0: automatic)");
    if (!model_) model_ = std::make_shared<const DipoleRadialProfile>(dipole_);
    profile_ = RdProfile::of(model_);
    reach_ = profile_->radius_containing(0.99);
    if (settings_.thin) {
        slab_threshold_ = shading::slab_threshold(dipole_, kSlabTolerance);
        // Another model than the dipole (the exact profile): the multipole's R scaled per
        // channel to that model's half-space total, so a slab at the threshold reflects what
        // the half-space does (DIPOLE.md 6a); T as it is. The dipole's own: 1.
        const Rgb model_total = profile_->total(), dipole_total = dipole_.rd_total();
        for (int c = 0; c < 3; ++c)
            slab_scale_[c] = dynamic_cast<const DipoleRadialProfile*>(model_.get()) || !(dipole_total[c] > 0)
                                 ? 1.0
                                 : model_total[c] / dipole_total[c];
        slab_min_ = kSlabMinMfp * mean_free_path();
        if (slab_threshold_ > slab_min_ && slab_min_ > 0) {
            slab_count_ = std::size_t(std::ceil(kSlabPerOctave * std::log2(slab_threshold_ / slab_min_))) + 1;
            slab_nodes_.reset(new std::atomic<const SlabNode*>[slab_count_]);
            for (std::size_t k = 0; k < slab_count_; ++k) slab_nodes_[k].store(nullptr, std::memory_order_relaxed);
        } else {
            slab_threshold_ = 0;  // (a medium without scattering: nothing to do)
        }
    }
}

// ---------------------------------------------------------------- Subsurface: thin geometry

// One slab thickness: its profiles and the near reflectance of R per lookup spacing h (a list
// that only grows, pushed with compare-exchange: lookups read it without a lock).
struct Subsurface::SlabNode {
    SlabProfiles p;
    struct Near {
        double h;
        Rgb same, opposite;  // near_reflectance(h) of R and of T (in rho)
        const Near* next;
    };
    mutable std::atomic<const Near*> near_list{nullptr};
    ~SlabNode() {
        for (const Near* n = near_list.load(); n;) {
            const Near* next = n->next;
            delete n;
            n = next;
        }
    }
    void near(double h, Rgb* same, Rgb* opposite) const {
        const Near* head = near_list.load(std::memory_order_acquire);
        for (const Near* n = head; n; n = n->next)
            if (n->h == h) {
                *same = n->same;
                *opposite = n->opposite;
                return;
            }
        Near* made = new Near{h, p.same->near_reflectance(h), p.transmit->near_reflectance(h), head};
        // Another thread may have pushed meanwhile (maybe the same h: harmless, equal values).
        while (!near_list.compare_exchange_weak(made->next, made, std::memory_order_acq_rel)) {
        }
        *same = made->same;
        *opposite = made->opposite;
    }
};

const Subsurface::SlabNode& Subsurface::slab_node(double d) const {
    if (!(slab_count_ > 0)) throw std::logic_error("Subsurface::slab: thin geometry is off");
    const double k = std::round(kSlabPerOctave * std::log2(std::max(d, slab_min_) / slab_min_));
    const std::size_t i = std::size_t(std::min(double(slab_count_ - 1), std::max(0.0, k)));
    if (const SlabNode* n = slab_nodes_[i].load(std::memory_order_acquire)) return *n;
    std::lock_guard<std::mutex> lock(slab_mutex_);
    if (const SlabNode* n = slab_nodes_[i].load(std::memory_order_acquire)) return *n;
    auto made = std::make_unique<SlabNode>();
    const double d_node = slab_min_ * std::exp2(double(i) / kSlabPerOctave);
    // The exact profile with slab tables covering (g, eta): its own slabs (DIPOLE.md 6a), the
    // multipole where a channel's thickness lies outside the tables' nodes.
    if (const auto* exact = dynamic_cast<const ExactProfile*>(model_.get()))
        made->p = make_exact_slab_profiles(*exact, dipole_, d_node, slab_scale_);
    else
        made->p = make_slab_profiles(dipole_, d_node, slab_scale_);
    const SlabNode* n = made.release();
    slab_nodes_[i].store(n, std::memory_order_release);
    return *n;
}

const SlabProfiles& Subsurface::slab(double d) const { return slab_node(d).p; }

Subsurface::~Subsurface() {
    for (std::size_t k = 0; k < slab_count_; ++k) delete slab_nodes_[k].load();
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

double Subsurface::mean_free_path() const { return model_->mean_free_path(); }

double Subsurface::diffusion_length() const {
    double l = 0;
    for (int c = 0; c < 3; ++c) {
        const DipoleChannel& ch = dipole_.channel(c);
        if (!ch.empty) l = std::max(l, ch.sigma_tr > 0 ? 1.0 / ch.sigma_tr : kInf);
    }
    return l;
}

double Subsurface::sample_spacing(double extent) const {
    if (settings_.spacing > 0) return settings_.spacing;
    double fine = 0.5 * mean_free_path();
    double cap = extent / std::max(1, settings_.max_lines);
    double h = std::max(fine, cap);
    return h > 0 ? h : 1.0;
}

int Subsurface::refinement_levels(double h0) const {
    if (settings_.max_levels >= 0) return std::min(settings_.max_levels, 12);
    // Automatic: halve until the near field (the part of Rd taken from E_t at x alone, wrong by
    // up to half of it next to a shadow edge) holds at most edge_fraction of every channel's
    // total, at most 8 levels.
    const Rgb total = profile_->total();
    int k = 0;
    for (double h = h0; k < 8; h *= 0.5, ++k) {
        const Rgb near = profile_->near_reflectance(h);
        bool ok = true;
        for (int c = 0; c < 3; ++c)
            if (total[c] > 0 && near[c] > settings_.edge_fraction * total[c]) ok = false;
        if (ok) break;
    }
    return k;
}

std::shared_ptr<const PointCloud> Subsurface::build(Entry& e, SurfaceSampler& sampler) const {
    const auto t0 = std::chrono::steady_clock::now();
    ParallelFor parallel = [&e, &sampler](std::size_t n, const Task& task) {
        if (n == 0) return;
        auto st = std::make_shared<Stage>(n, task);
        {
            std::lock_guard<std::mutex> lock(e.m);
            e.stage = st;
            ++e.generation;
        }
        e.cv.notify_all();
        e.work(*st, sampler);
        std::unique_lock<std::mutex> lock(e.m);
        e.cv.wait(lock, [&] { return st->done == st->n; });
        e.stage.reset();
        if (st->error) std::rethrow_exception(st->error);
    };
    CloudReport report;
    std::vector<SurfacePoint> points;
    Vec3 lo, hi;
    double h0 = 1.0;
    int levels = 0;
    if (sampler.bounds(&lo, &hi)) {
        const Vec3 len = hi - lo;
        const double extent = std::max({len.x, len.y, len.z});
        if (extent > 0 && std::isfinite(extent)) {
            h0 = sample_spacing(extent);
            levels = refinement_levels(h0);
            SamplingPlan plan;
            plan.view = sampler.view();
            // Where no part of the image is within reach, the base spacing may be coarser: those
            // samples only light visible points from beyond the reach (1 % of Rd), where a few
            // spacings of 1/4 the reach integrate Rd smoothly. At most 3 halvings, and at least
            // 16 spacings across the object.
            int coarse = 0;
            if (plan.view.kind != ViewVolume::Kind::Everywhere && settings_.max_levels != 0)
                while (coarse < 3 && h0 * std::ldexp(1.0, coarse + 1) <= 0.25 * reach_ &&
                       h0 * std::ldexp(1.0, coarse + 1) <= extent / 16)
                    ++coarse;
            plan.lo = lo;
            plan.hi = hi;
            plan.h0 = h0 * std::ldexp(1.0, coarse);
            plan.levels = levels + coarse;
            plan.view_levels = coarse;
            plan.tolerance = settings_.tolerance;
            plan.max_points = settings_.max_points;
            plan.mean_free_path = mean_free_path();
            plan.thickness = slab_threshold_ > 0;
            plan.reach = reach_;
            points = sample_surface(parallel, plan, &report);
        } else {
            report.unbounded = true;
        }
    } else {
        report.unbounded = true;
    }
    auto cloud = std::make_shared<const PointCloud>(std::move(points), [this](double h) { return near_reflectance(h); },
                                                    &parallel);

    g_clouds += 1;
    g_points += cloud->points().size();
    g_refined += report.refined;
    if (report.unbounded) ++g_unbounded;
    const bool slab_object = cloud->thinnest() < slab_threshold_;
    if (slab_object) ++g_slab_objects;
    // The exact profile without slab tables for this medium: said once (statistics notes).
    std::string slab_note;
    if (slab_object) {
        const auto* exact = dynamic_cast<const ExactProfile*>(model_.get());
        if (exact && !exact->slab_tables())
            slab_note = "Dipole: thin objects with profile exact use the multipole, scaled to the\n"
                        "  exact total; slab tables subsurface_slabs.ssp:\n  " + exact->slab_gap();
    }
    else if (report.thin && !(slab_threshold_ > 0)) ++g_thin;  // thin geometry off: the old warning
    int seen = g_max_levels.load();
    while (report.levels > seen && !g_max_levels.compare_exchange_weak(seen, report.levels)) {
    }
    const double L = diffusion_length();
    std::string note;
    if (!report.unbounded && !cloud->points().empty() && report.extent < 3.0 * L) {
        const double mpu = dipole_.medium().mm_per_unit;
        // (POV wraps statistics at 80 columns: the lines are broken here, indented)
        note = "Dipole warning: " + sampler.describe() + " at <" + fmt3(report.centre.x) + ", " + fmt3(report.centre.y) +
               ", " + fmt3(report.centre.z) + "> (extent " + fmt3(report.extent) +
               " units)\n  is smaller than 3 diffusion lengths (" +
               (std::isfinite(L) ? "1/sigma_tr = " + fmt3(L * mpu) + " mm = " + fmt3(L) + " units\n  at mm_per_unit " + fmt3(mpu)
                                 : "no absorption: unbounded") +
               (slab_object ? "): light through it follows slab profiles\n  (thinnest " + fmt3(cloud->thinnest()) + " units)"
                            : "): light that would glow through it is lost");
    }
    {
        Notes& n = notes();
        std::lock_guard<std::mutex> lock(n.mutex);
        if (!note.empty()) n.notes.push_back(note);
        if (!slab_note.empty() && std::find(n.notes.begin(), n.notes.end(), slab_note) == n.notes.end())
            n.notes.push_back(slab_note);
        const double finest = cloud->stats().finest_spacing;
        if (report.levels > 0 && (n.finest == 0 || finest < n.finest)) n.finest = finest;
        if (slab_object && (n.thinnest == 0 || cloud->thinnest() < n.thinnest)) {
            n.thinnest = cloud->thinnest();
            n.thinnest_mfp = cloud->thinnest() / mean_free_path();
        }
    }
    g_build_ns += std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
    return cloud;
}

const PointCloud& Subsurface::cloud(const void* key, SurfaceSampler& sampler) const {
    if (const Index* ix = index_.load(std::memory_order_acquire))
        if (Entry* e = ix->find(key))
            if (const PointCloud* c = e->ready.load(std::memory_order_acquire)) return *c;

    Entry* e = nullptr;
    bool leader = false;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        const Index* ix = index_.load(std::memory_order_relaxed);
        e = ix ? ix->find(key) : nullptr;
        if (!e) {
            entries_.push_back(std::make_unique<Entry>());
            e = entries_.back().get();
            e->key = key;
            auto next = std::make_unique<Index>();
            if (ix) next->sorted = ix->sorted;
            next->sorted.emplace_back(key, e);
            std::sort(next->sorted.begin(), next->sorted.end(),
                      [](const std::pair<const void*, Entry*>& a, const std::pair<const void*, Entry*>& b) {
                          return std::less<const void*>()(a.first, b.first);
                      });
            index_.store(next.get(), std::memory_order_release);
            indexes_.push_back(std::move(next));
        }
    }
    {
        std::lock_guard<std::mutex> lock(e->m);
        if (!e->started) {
            e->started = true;
            leader = true;
        }
    }
    if (leader) {
        std::shared_ptr<const PointCloud> cloud;
        std::exception_ptr error;
        try {
            cloud = build(*e, sampler);
        } catch (...) {
            error = std::current_exception();
        }
        {
            std::lock_guard<std::mutex> lock(e->m);
            e->cloud = cloud;
            e->error = error;
            e->finished = true;
            if (cloud) e->ready.store(cloud.get(), std::memory_order_release);
        }
        e->cv.notify_all();
        if (error) std::rethrow_exception(error);
        return *cloud;
    }
    // A helper: work on whatever stage the leader publishes until the cloud is done.
    std::unique_lock<std::mutex> lock(e->m);
    std::uint64_t seen = 0;
    while (!e->finished) {
        if (e->stage && e->generation != seen) {
            seen = e->generation;
            std::shared_ptr<Stage> st = e->stage;
            lock.unlock();
            e->work(*st, sampler);
            lock.lock();
            continue;
        }
        e->cv.wait(lock);
    }
    if (e->error) std::rethrow_exception(e->error);
    return *e->cloud;
}

Rgb Subsurface::radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                         const Rgb& irradiance_here) const {
    const double cos_o = dot(n, to_eye);
    if (!(cos_o > 0)) return Rgb(0.0);
    const int level = cloud.lookup_level(x);
    const double h = cloud.level_spacing(level), r0 = near_radius(h);
    std::size_t visited = 0;
    Rgb m = cloud.far_exitance(*profile_, x, r0, h, settings_.max_angle, cutoff(), &visited);
    LookupCounter& c = thread_counter();
    bump(c.lookups, 1);
    bump(c.visited, visited);
    m += irradiance_here * cloud.level_near(level);
    return m * model_->exit_factor(cos_o);
}

Rgb Subsurface::radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                         const Rgb& irradiance_here, double thickness) const {
    if (!(thickness < slab_threshold_)) return radiance(cloud, x, n, to_eye, irradiance_here);
    const double cos_o = dot(n, to_eye);
    if (!(cos_o > 0)) return Rgb(0.0);
    const SlabNode& slab = slab_node(thickness);
    const int level = cloud.lookup_level(x);
    const double h = cloud.level_spacing(level), r0 = near_radius(h);
    std::size_t visited = 0;
    Rgb near_same, near_opposite;
    slab.near(h, &near_same, &near_opposite);
    Rgb opposite;
    Rgb m = cloud.far_exitance_sided(*slab.p.same, *slab.p.transmit, x, n, slab.p.d, r0, h, settings_.max_angle,
                                     near_opposite, &visited, &opposite);
    LookupCounter& c = thread_counter();
    bump(c.lookups, 1);
    bump(c.visited, visited);
    bump(c.slab, 1);
    m += irradiance_here * near_same;
    if (!slab.p.exit) return m * model_->exit_factor(cos_o);
    // The exact slab tables: each face's own exit distribution (DIPOLE.md 6a).
    Rgb same_exit, opposite_exit;
    slab.p.exit(cos_o, &same_exit, &opposite_exit);
    return (m - opposite) * same_exit + opposite * opposite_exit;
}

// ---------------------------------------------------------------- BRDFs

TransmittanceBrdf::TransmittanceBrdf(std::shared_ptr<const RadialProfile> model) : model_(std::move(model)) {
    if (!model_) throw std::invalid_argument("TransmittanceBrdf: no profile");
}
Rgb TransmittanceBrdf::f(const Vec3& wo, const Vec3& wi) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    return model_->entry_factor(wi.z) * kInvPi;
}
std::string TransmittanceBrdf::describe() const { return "transmittance(" + model_->describe() + ")"; }

DipoleSurfaceBrdf::DipoleSurfaceBrdf(std::shared_ptr<const Subsurface> s, BrdfPtr coat)
    : s_(std::move(s)), coat_(std::move(coat)) {
    if (!s_) throw std::invalid_argument("DipoleSurfaceBrdf: no subsurface");
}
Rgb DipoleSurfaceBrdf::f(const Vec3& wo, const Vec3& wi) const {
    Rgb v = s_->settings().single_scatter ? s_->dipole().single_scatter_brdf(wo, wi) : Rgb(0.0);
    if (coat_) v += coat_->f(wo, wi);
    return v;
}
std::string DipoleSurfaceBrdf::describe() const {
    return std::string("dipole(") + (s_->settings().single_scatter ? "single scattering" : "no single scattering") +
           (coat_ ? ", coat " + coat_->describe() : "") + ")";
}

}  // namespace shading
