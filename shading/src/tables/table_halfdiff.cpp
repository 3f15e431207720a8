// Half/difference tables (layout 3): node pairs, lookups with the virtual pole nodes, and
// the directional albedo integrated over the half vector. Grid conventions: table.h; the
// file format: brdf_data/README.md; MERL's bins: merl.h.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "shading/tables/table.h"

namespace shading {

namespace {

constexpr double kHalfPi = kPi / 2;

[[noreturn, gnu::noinline, gnu::cold]] void not_halfdiff(const TableGeometry& g, const char* what) {
    throw std::logic_error(std::string(what) + ": not a half/difference table (" + g.describe() + ")");
}
inline void require_halfdiff(const TableGeometry& g, const char* what) {
    if (g.layout != TableLayout::HalfDiff) not_halfdiff(g, what);
}

// (y, x) -> (-y, -x) where y < 0, else unchanged: the same numbers as the two branches of a
// conditional, by a sign mask (the sign of y is not predictable from pixel to pixel).
inline void turn_to_upper(double& y, double& x) {
#if defined(__SSE2__)
    const __m128d v = _mm_set_pd(x, y);
    const __m128d flip = _mm_and_pd(_mm_cmplt_pd(_mm_set1_pd(y), _mm_setzero_pd()), _mm_set1_pd(-0.0));
    const __m128d t = _mm_xor_pd(v, flip);
    y = _mm_cvtsd_f64(t);
    x = _mm_cvtsd_f64(_mm_unpackhi_pd(t, t));
#else
    if (y < 0) y = -y, x = -x;
#endif
}

// sqrt of a sum of squares or another value >= 0 (or NaN) by the SSE2 instruction alone:
// std::sqrt keeps a test and a libm call (errno) for negative arguments, never taken here.
// Same bits; sqrt_nonneg2 takes two at once.
inline double sqrt_nonneg(double v) {
#if defined(__SSE2__)
    return _mm_cvtsd_f64(_mm_sqrt_sd(_mm_setzero_pd(), _mm_set_sd(v)));
#else
    return std::sqrt(v);
#endif
}
inline void sqrt_nonneg2(double v0, double v1, double* r0, double* r1) {
#if defined(__SSE2__)
    const __m128d r = _mm_sqrt_pd(_mm_set_pd(v1, v0));
    *r0 = _mm_cvtsd_f64(r);
    *r1 = _mm_cvtsd_f64(_mm_unpackhi_pd(r, r));
#else
    *r0 = std::sqrt(v0);
    *r1 = std::sqrt(v1);
#endif
}

}  // namespace

bool TableGeometry::halfdiff_node_pair(const uint32_t idx[4], Vec3& wi, Vec3& wo) const {
    require_halfdiff(*this, "halfdiff_node_pair");
    const double th = axis_deg(0, idx[0]) * kDegree;
    const double st = std::sin(th), ct = std::cos(th);
    // d in the half vector's frame, turned by theta_h about y (phi_h = 0): wi; wo is its
    // mirror image about h (merl.h: from_half_diff with phi_h = 0).
    const Vec3 d = spherical_direction(axis_deg(1, idx[1]) * kDegree, axis_deg(2, idx[2]) * kDegree);
    wi = Vec3(d.x * ct + d.z * st, d.y, -d.x * st + d.z * ct);
    const Vec3 h(st, 0.0, ct);
    wo = h * (2.0 * dot(h, wi)) - wi;
    return wi.z > 0 && wo.z > 0;
}

// `x` is the position in bin units: node k (the centre of bin k) is at x = k + 1/2, so
// floor(x) is MERL's reference bin (merl.h) and x - 1/2 the fractional node index.
[[gnu::always_inline]] inline BrdfTable::HdPos BrdfTable::locate_hd(int axis, double x, Interp interp) const {
    const int32_t n = int32_t(geom_.n[axis]);
    if (axis == 2) {  // phi_d: periodic, x already in [0, n] (or NaN)
        if (!(x >= 0) || x >= double(n)) x = 0;  // NaN, or pi folding onto 0 (same direction pair)
        if (interp == Interp::Nearest) {
            const int32_t i = std::min(int32_t(x), n - 1);
            return {i, i, 0.0};
        }
        double y = x - 0.5;
        if (y < 0) y += double(n);  // between the last node and node 0, across the wrap
        const int32_t i0 = std::min(int32_t(y), n - 1);
        return {i0, i0 + 1 == n ? 0 : i0 + 1, y - double(i0)};
    }
    if (!(x > 0)) x = 0;  // also NaN
    if (interp == Interp::Nearest) {
        const int32_t i = x >= double(n - 1) ? n - 1 : int32_t(x);  // MERL: lower bin, clamped
        return {i, i, 0.0};
    }
    const double y = x - 0.5;
    if (y >= double(n - 1)) return {n - 1, n - 1, 0.0};  // beyond the last node: held
    if (y < 0) return {-1, 0, 2.0 * x};                 // between the pole (x = 0) and node 0
    const int32_t i0 = int32_t(y);
    return {i0, i0 + 1, y - double(i0)};
}

// The rows of a lookup: rows_hd_interior (inline) for a cell of stored rows, the renderer's
// usual case; rows_hd_edge (out of line) where a row is a virtual pole's or interp is Nearest.
[[gnu::always_inline]] inline void BrdfTable::rows_hd(const HdPos pos[3], Interp interp, HdRead* rd) const {
    if (interp == Interp::Linear && pos[0].i0 >= 0 && pos[1].i0 >= 0)
        rows_hd_interior(pos, rd);
    else
        rows_hd_edge(pos, interp, rd);
}

// Bilinear in (theta_h, theta_d) over four rows, each linear in phi_d; no pole row (i1 >= i0):
// offsets written out.
[[gnu::always_inline]] inline void BrdfTable::rows_hd_interior(const HdPos pos[3], HdRead* rd) const {
    rd->channels = geom_.channels;
    rd->nearest = false;
    rd->t_h = pos[0].t;
    rd->t_d = pos[1].t;
    rd->t_phi = pos[2].t;
    const uint64_t k0 = uint64_t(pos[2].i0), k1 = uint64_t(pos[2].i1);
    const float* a = values_.data() + k0 * stride_[2];
    const uint64_t h0 = uint64_t(pos[0].i0) * stride_[0], h1 = uint64_t(pos[0].i1) * stride_[0];
    const uint64_t d0 = uint64_t(pos[1].i0) * stride_[1], d1 = uint64_t(pos[1].i1) * stride_[1];
    const int64_t dk = (int64_t(k1) - int64_t(k0)) * int64_t(stride_[2]);  // < 0 across phi_d's wrap
    rd->a[0] = a + (h0 + d0);
    rd->a[1] = a + (h0 + d1);
    rd->a[2] = a + (h1 + d0);
    rd->a[3] = a + (h1 + d1);
    for (int q = 0; q < 4; ++q) rd->b[q] = rd->a[q] + dk;
}

void BrdfTable::rows_hd_edge(const HdPos pos[3], Interp interp, HdRead* rd) const {
    const int C = geom_.channels;
    rd->channels = C;
    // The (theta_h, theta_d) row of a corner: a pointer to its phi_d = 0 value, and the stride
    // along phi_d (0 for a virtual pole row: its value does not depend on phi_d).
    auto row = [&](int32_t i, int32_t j, uint64_t& stride) -> const float* {
        stride = stride_[2];
        if (i >= 0 && j >= 0) return &values_[uint64_t(i) * stride_[0] + uint64_t(j) * stride_[1]];
        stride = 0;
        if (i < 0 && j < 0) return pole_hd_;
        return i < 0 ? &pole_h_[size_t(j) * C] : &pole_d_[size_t(i) * C];
    };
    uint64_t s;
    if (interp == Interp::Nearest) {
        rd->nearest = true;
        rd->a[0] = row(pos[0].i0, pos[1].i0, s) + uint64_t(pos[2].i0) * s;
        return;
    }
    rd->nearest = false;
    rd->t_h = pos[0].t;
    rd->t_d = pos[1].t;
    rd->t_phi = pos[2].t;
    const uint64_t k0 = uint64_t(pos[2].i0), k1 = uint64_t(pos[2].i1);
    const int32_t ii[4] = {pos[0].i0, pos[0].i0, pos[0].i1, pos[0].i1}, jj[4] = {pos[1].i0, pos[1].i1, pos[1].i0, pos[1].i1};
    for (int q = 0; q < 4; ++q) {
        const float* p = row(ii[q], jj[q], s);
        rd->a[q] = p + k0 * s;
        rd->b[q] = p + k1 * s;
    }
}

Rgb BrdfTable::gather_hd(const HdPos pos[3], Interp interp) const {
    HdRead rd;
    rows_hd(pos, interp, &rd);
    return read_halfdiff(rd);
}

// theta_h, theta_d in [0, pi/2] (clamped), phi_d in [0, pi] (pi is the same pair as 0).
// The bin positions are computed exactly as MERL's reference reader computes its bins.
[[gnu::always_inline]] inline void BrdfTable::locate_all_hd(double theta_h, double theta_d, double phi_d, Interp interp,
                                                            HdPos pos[3]) const {
    theta_h = std::min(theta_h, kHalfPi);
    theta_d = std::min(theta_d, kHalfPi);
    pos[0] = locate_hd(0, theta_h > 0 ? sqrt_nonneg(theta_h / kHalfPi) * double(geom_.n[0]) : 0.0, interp);
    pos[1] = locate_hd(1, theta_d / kHalfPi * double(geom_.n[1]), interp);
    pos[2] = locate_hd(2, phi_d / kPi * double(geom_.n[2]), interp);
}

Rgb BrdfTable::hd_lookup(double theta_h, double theta_d, double phi_d, Interp interp) const {
    HdPos pos[3];
    locate_all_hd(theta_h, theta_d, phi_d, interp, pos);
    return gather_hd(pos, interp);
}

Rgb BrdfTable::eval_halfdiff(double theta_h, double theta_d, double phi_d, Interp interp) const {
    require_halfdiff(geom_, "eval_halfdiff");
    double p = std::fmod(phi_d, kPi);  // period pi (reciprocity)
    if (p < 0) p += kPi;
    if (!(p >= 0 && p < kPi)) p = 0;  // NaN, Inf, or rounding onto pi
    return hd_lookup(theta_h, theta_d, p, interp);
}

Rgb BrdfTable::eval_halfdiff_dirs(const Vec3& n, const Vec3& wi, const Vec3& wo, Interp interp) const {
    HdRead rd;
    prepare_halfdiff_dirs(n, wi, wo, interp, &rd);
    return read_halfdiff(rd);
}

void BrdfTable::prepare_halfdiff_dirs(const Vec3& n, const Vec3& wi, const Vec3& wo, double cos_i, double cos_o,
                                      Interp interp, HdRead* rd) const {
    require_halfdiff(geom_, "prepare_halfdiff_dirs");
    // h = wi + wo, unnormalised. b = n x h is the half frame's y axis times |h| sin(theta_h),
    // so theta_h = atan2(|b|, n.h), n.h = cos_i + cos_o, keeps full precision at the peak
    // (acos would not), and in that frame d.y = wi.b / |b| and d.x = |h| (cos_o - cos_i) /
    // (2 |b|) (expand wi.((n x h) x h) with wi.h = |h|^2 / 2): phi_d needs only their ratio.
    // |h| = 2 cos(theta_d) and |wi - wo| = 2 sin(theta_d): theta_d by atan2 too, precise at
    // both ends (acos_approx's 8e-11 rad would not keep a node exact to 1e-9). The three
    // angles by atan2_upper (vec.h: no libm call, relative error < 3e-16), theta_h and phi_d
    // as one pair (atan2_upper2: the same bits, one division, no branches: where a highlight
    // is and the sign of phi_d's y change from pixel to pixel; theta_d, nearly constant over
    // an object lit by one light, keeps the scalar function's predictable branches); phi_d's
    // y is made >= 0 by turning the pair by pi (reciprocity: phi_d and phi_d + pi are the
    // same pair), by a mask too. At h = 0 (wi = -wo, both on the horizon) everything stays
    // finite; at theta_h = 0 or theta_d = 0 phi_d is undefined and the virtual poles make the
    // value independent of it. The renderer's case (trilinear, a cell of stored rows) is the
    // straight path; nearest lookups, pole rows and atan2's degenerate lanes are out of line,
    // and the square roots skip std::sqrt's errno branch (sqrt_nonneg): 4.8 -> 2.4 KB of code
    // here (shading/MODELS.md).
    const Vec3 h = wi + wo, d = wi - wo;
    const Vec3 b = cross(n, h);
    double hl, dl;
    sqrt_nonneg2(dot(h, h), dot(d, d), &hl, &dl);
    const double theta_d = atan2_upper(dl, hl);
    double y = dot(wi, b), x = 0.5 * hl * (cos_o - cos_i);
    turn_to_upper(y, x);
    double theta_h, phi_d;
    atan2_upper2(sqrt_nonneg(dot(b, b)), cos_i + cos_o, y, x, &theta_h, &phi_d);
    if (interp != Interp::Linear) return prepare_hd_nearest(theta_h, theta_d, phi_d, rd);
    HdPos pos[3];
    locate_all_hd(theta_h, theta_d, phi_d, Interp::Linear, pos);
    rows_hd(pos, Interp::Linear, rd);
#if defined(__GNUC__)
    // Each row segment (two phi_d nodes x channels) may cross a cache line: the first float
    // of its i0 node and the last of its i1 node (apart only across the phi_d wrap).
    const int last = rd->channels - 1;
    for (int q = 0; q < 4; ++q) {
        __builtin_prefetch(rd->a[q]);
        __builtin_prefetch(rd->b[q] + last);
    }
#endif
}

void BrdfTable::prepare_hd_nearest(double theta_h, double theta_d, double phi_d, HdRead* rd) const {
    HdPos pos[3];
    locate_all_hd(theta_h, theta_d, phi_d, Interp::Nearest, pos);
    rows_hd(pos, Interp::Nearest, rd);
#if defined(__GNUC__)
    __builtin_prefetch(rd->a[0]);
    __builtin_prefetch(rd->a[0] + (rd->channels - 1));
#endif
}

void BrdfTable::init_halfdiff() {
    const int C = geom_.channels;
    const uint32_t n0 = geom_.n[0], n1 = geom_.n[1], n2 = geom_.n[2];
    // Mean over phi_d of a row, per channel.
    auto row_mean = [&](uint32_t i, uint32_t j, float* out) {
        double sum[3] = {0, 0, 0};
        for (uint32_t k = 0; k < n2; ++k) {
            const float* p = &values_[i * stride_[0] + j * stride_[1] + k * stride_[2]];
            for (int c = 0; c < C; ++c) sum[c] += p[c];
        }
        for (int c = 0; c < C; ++c) out[c] = float(sum[c] / double(n2));
    };
    pole_h_.assign(size_t(n1) * C, 0.0f);
    pole_d_.assign(size_t(n0) * C, 0.0f);
    for (uint32_t j = 0; j < n1; ++j) row_mean(0, j, &pole_h_[size_t(j) * C]);
    for (uint32_t i = 0; i < n0; ++i) row_mean(i, 0, &pole_d_[size_t(i) * C]);
    for (int c = 0; c < C; ++c) pole_hd_[c] = pole_h_[c];  // the (0, 0) row: both poles at once
    compute_albedo_halfdiff();
}

// a(theta_i) = integral of f cos(theta_o) dw_o, with w_o the mirror image of wi about h:
// dw_o = 4 (wi.h) dw_h. Midpoint cells uniform in u = sqrt(theta_h / 90 deg), the table's
// own spacing (dense where narrow lobes are): 4 per theta_h node, at least 32 and at most
// 192, times 4 per phi_d node in phi_h, at least 32 and at most 96 (a coarse table is a
// smooth interpolant); dw_h = sin(theta_h) (pi u du) dphi_h. Cells whose wo is below the
// horizon contribute 0. Nodes every 2 deg; the grazing one is evaluated at 89.9 deg (wi in
// the surface is degenerate), like the finish's albedo nodes. The cell's theta_h is known,
// so only theta_d and phi_d are computed (d's components on the half frame's axes t, b),
// and all incidence angles run inside one cell, so the lookups stay in two theta_h slabs
// of the table (cache) instead of sweeping it once per angle: 2 ms for an 8 x 6 x 10
// table, 60-70 ms for 90 x 90 x 180 or 256 x 128 x 32 (measured, one core).
void BrdfTable::compute_albedo_halfdiff() {
    constexpr int kNodes = 46;
    const int nu = int(std::clamp<uint64_t>(4 * uint64_t(geom_.n[0]), 32, 192));
    const int np = int(std::clamp<uint64_t>(4 * uint64_t(geom_.n[2]), 32, 96));
    Vec3 wi[kNodes];
    for (int k = 0; k < kNodes; ++k) {
        const double ti = std::min(90.0 * k / (kNodes - 1), 89.9) * kDegree;
        wi[k] = Vec3(std::sin(ti), 0.0, std::cos(ti));
    }
    std::vector<Rgb> sum(kNodes, Rgb(0.0));
    const double du = 1.0 / nu, dphi = 2.0 * kPi / np;
    for (int c = 0; c < nu; ++c) {
        const double u = (c + 0.5) * du, th = kHalfPi * u * u, st = std::sin(th), ct = std::cos(th);
        const double w = st * kPi * u * du * dphi;
        const HdPos ph = locate_hd(0, u * double(geom_.n[0]), Interp::Linear);
        for (int p = 0; p < np; ++p) {
            const double phi = (p + 0.5) * dphi, cp = std::cos(phi), sp = std::sin(phi);
            const Vec3 h(st * cp, st * sp, ct), t(ct * cp, ct * sp, -st), b(-sp, cp, 0.0);  // half frame
            for (int k = 0; k < kNodes; ++k) {
                const double cd = dot(wi[k], h);
                if (!(cd > 0) || !(2.0 * cd * h.z - wi[k].z > 0)) continue;  // wo = 2 (wi.h) h - wi below
                double phi_d = std::atan2(dot(wi[k], b), dot(wi[k], t));
                if (phi_d < 0) phi_d += kPi;
                const HdPos pos[3] = {ph, locate_hd(1, std::acos(std::min(1.0, cd)) / kHalfPi * double(geom_.n[1]),
                                                    Interp::Linear),
                                      locate_hd(2, phi_d / kPi * double(geom_.n[2]), Interp::Linear)};
                sum[k] += gather_hd(pos, Interp::Linear) * ((2.0 * cd * h.z - wi[k].z) * 4.0 * cd * w);
            }
        }
    }
    albedo_ = std::move(sum);
}

}  // namespace shading
