// Importance sampling of tables from their own data: their own cells (isotropic tables) or a
// grid over the half vector (half/difference and anisotropic tables); table_sampler.h.
#include "shading/tables/table_sampler.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>

#include "shading/tables/table.h"

namespace shading {

namespace {

std::atomic<size_t> g_live_bytes{0}, g_peak_bytes{0};

void account_add(size_t bytes) {
    const size_t now = g_live_bytes.fetch_add(bytes) + bytes;
    size_t peak = g_peak_bytes.load();
    while (now > peak && !g_peak_bytes.compare_exchange_weak(peak, now)) {
    }
}

// The half-vector grid: rows x columns per viewer node. Half/difference columns cover [0, pi],
// anisotropic ones [0, 2 pi) (and their viewer nodes are 12 times as many, so fewer rows).
// Measured (table_sampler.h): the per-sample spread of f cos / pdf falls with the rows
// squared (bilinear cells), hardly with the columns; 256 rows warped by 2.5 resolve a
// Beckmann m = 0.02 lobe to 0.3-0.5 % per sample.
constexpr int kRowsHalfDiff = 256, kColsHalfDiff = 48;
constexpr int kRowsAniso = 64, kColsAniso = 64;
constexpr double kRowWarp = 2.5;
constexpr int kAzimuthNodesAniso = 12;

// The support: a grid node where the table is zero keeps a small value so that every direction
// where the table can be positive between the nodes has a positive density (the estimator
// stays unbiased), yet the samples spent where the table is zero stay rare (each one is a
// zero weight, and a fraction p of them adds p to the relative variance):
//  * next to a positive node (8-neighbourhood): kEdgeFloor of its largest neighbour (a lobe's
//    edge, where the table tapers to zero between the nodes);
//  * elsewhere with wi above the horizon, or below it by less than a cell (a cell whose corners
//    are all below can still reach above it): kFloor of the node's mean density.
constexpr double kEdgeFloor = 1e-2;
constexpr double kFloor = 1e-6;
constexpr double kFloorHorizon = -0.15;

// Resolution of the integer CDFs: a node's rows, and a row's cells, share 2^30 units; every
// positive weight is rounded up to at least one unit (its cell stays reachable), so that
// rounding gives a cell of negligible weight at most 2^-30 of its row. (With 16-bit columns,
// one unit in 65535 per cell, the empty cells of a row holding a narrow lobe drew 0.3 % of the
// samples, each a zero weight: 5 % of relative spread per sample.)
constexpr double kCdfUnits = double(1u << 30);

// Units of a positive weight: its rounded share, at least 1.
uint32_t units(double w, double total, double scale) {
    if (!(w > 0) || !(total > 0)) return 0;
    return uint32_t(std::max(1.0, std::round(w / total * scale)));
}

// x in [0, 1) with density proportional to (1 - x) a + x b (a, b >= 0, a + b > 0), from u in
// [0, 1): the root of the quadratic CDF in the form without cancellation.
double sample_linear(double u, double a, double b) {
    if (u == 0 && a == 0) return 0.0;
    const double x = u * (a + b) / (a + std::sqrt((1.0 - u) * a * a + u * b * b));
    return std::min(x, kOneMinusEps);
}

double lerp(double a, double b, double t) { return a + t * (b - a); }

// Fraction of the way from an integer CDF's entry below the chosen one to the chosen one.
template <class T>
int pick(const T* cdf, int n, double u, double* frac) {
    const double target = u * double(cdf[n - 1]);
    const int i = int(std::upper_bound(cdf, cdf + n, target) - cdf);
    if (i >= n) return n;
    const double lo = i ? double(cdf[i - 1]) : 0.0;
    *frac = std::clamp((target - lo) / (double(cdf[i]) - lo), 0.0, kOneMinusEps);
    return i;
}

// Either side of the viewer's plane of incidence with probability 1/2, v folded so that the
// map stays continuous: v = 1/2 is phi = 0 on both sides, v = 0 and 1 are phi = -pi and pi,
// the same half plane (stratified u keep their spacing). Returns the side (true: +phi) and
// stretches v back to [0, 1).
bool fold_side(double* v) {
    const bool plus = *v >= 0.5;
    *v = std::clamp(plus ? 2.0 * *v - 1.0 : 1.0 - 2.0 * *v, 0.0, kOneMinusEps);
    return plus;
}

}  // namespace

TableSampler::TableSampler(const BrdfTable& table) {
    const TableGeometry& g = table.geometry();
    if (g.layout == TableLayout::Isotropic) {
        build_cells(table);
        return;
    }
    mirror_ = g.layout != TableLayout::Anisotropic;
    n_to_ = mirror_ ? 91 : int(g.n[2]);  // half/difference: every degree; anisotropic: theta_r nodes
    n_po_ = mirror_ ? 1 : kAzimuthNodesAniso;
    step_to_ = (kPi / 2) / (n_to_ - 1);
    step_po_ = 2 * kPi / n_po_;
    cells_h_ = mirror_ ? kRowsHalfDiff : kRowsAniso;
    cells_p_ = mirror_ ? kColsHalfDiff : kColsAniso;
    dphi_ = (mirror_ ? kPi : 2 * kPi) / cells_p_;
    place_rows();
    const int nodes = n_to_ * n_po_;
    total_.assign(nodes, 0.0);
    value_.assign(size_t(nodes) * (cells_h_ + 1) * (cells_p_ + 1), 0.0f);
    marginal_.assign(size_t(nodes) * cells_h_, 0);
    conditional_.assign(size_t(nodes) * cells_h_ * cells_p_, 0);
    std::vector<double> work;
    for (int k = 0; k < nodes; ++k) build_node(table, k, node_direction(k), work);
    bytes_ = sizeof(*this) + omc_.capacity() * sizeof(double) + total_.capacity() * sizeof(double) +
             value_.capacity() * sizeof(float) + marginal_.capacity() * sizeof(uint32_t) +
             conditional_.capacity() * sizeof(uint32_t);
    account_add(bytes_);
}

Vec3 TableSampler::node_direction(int k) const {
    const int j = k / n_po_, q = k % n_po_;
    // The grazing node a thousandth of a radian inside: wo exactly in the surface has no
    // reflection.
    return spherical_direction(std::min(j * step_to_, kPi / 2 - 1e-3), q * step_po_);
}

void TableSampler::place_rows() {
    // Row edges at theta_h = (pi/2) (a / H)^kRowWarp: uniform in u = (theta_h / (pi/2))^(1/kRowWarp).
    const int H = cells_h_;
    omc_.assign(H + 1, 0.0);
    for (int a = 1; a < H; ++a)
        omc_[a] = 2.0 * sqr(std::sin(0.5 * (kPi / 2) * std::pow(double(a) / H, kRowWarp)));
    omc_[H] = 1.0;
}

void TableSampler::build_node(const BrdfTable& table, int k, const Vec3& wo, std::vector<double>& g) {
    const int H = cells_h_, P = cells_p_, W = P + 1;
    // The viewer's azimuth: isotropic grids are measured from it (wo at phi 0 here),
    // anisotropic ones from the tangent.
    const double phi_o = std::atan2(wo.y, wo.x);
    g.assign(size_t(H + 1) * W, 0.0);
    std::vector<char> near_horizon(g.size(), 0);
    for (int a = 0; a <= H; ++a) {
        const double cos_h = 1.0 - omc_[a], sin_h = std::sqrt(std::max(0.0, omc_[a] * (2.0 - omc_[a])));
        for (int b = 0; b <= P; ++b) {
            const double phi = b * dphi_ + (mirror_ ? phi_o : 0.0);
            const Vec3 h(sin_h * std::cos(phi), sin_h * std::sin(phi), cos_h);
            const double d = dot(wo, h);
            const Vec3 wi = h * (2.0 * d) - wo;
            const size_t at = size_t(a) * W + b;
            near_horizon[at] = d > 0 && wi.z > kFloorHorizon;
            if (!(d > 0) || !(wi.z > 0)) continue;
            const double v = table.f(wo, normalize(wi)).average() * wi.z * 4.0 * d;
            g[at] = std::isfinite(v) && v > 0 ? v : 0.0;
        }
    }
    // Mass of each cell: its solid angle (one side) times the mean of its corners.
    auto mass = [&](int a, int b) {
        const double* c = &g[size_t(a) * W + b];
        return 0.25 * (c[0] + c[1] + c[W] + c[W + 1]) * (omc_[a + 1] - omc_[a]) * dphi_;
    };
    double raw = 0;
    for (int a = 0; a < H; ++a)
        for (int b = 0; b < P; ++b) raw += mass(a, b);
    if (!(raw > 0)) return;  // a table that is zero for this viewer: the node is never chosen
    const double floor = kFloor * raw / (omc_[H] * P * dphi_);
    std::vector<double> v(g.size(), 0.0);
    for (int a = 0; a <= H; ++a)
        for (int b = 0; b <= P; ++b) {
            const size_t at = size_t(a) * W + b;
            if (g[at] > 0) {
                v[at] = g[at];
                continue;
            }
            if (!near_horizon[at]) continue;
            double edge = 0;
            for (int da = -1; da <= 1; ++da)
                for (int db = -1; db <= 1; ++db) {
                    const int aa = a + da, bb = b + db;
                    if (aa >= 0 && aa <= H && bb >= 0 && bb <= P) edge = std::max(edge, g[size_t(aa) * W + bb]);
                }
            v[at] = std::max(kEdgeFloor * edge, floor);
        }
    g.swap(v);
    float* val = &value_[size_t(k) * (H + 1) * W];
    for (size_t i = 0; i < g.size(); ++i) {
        val[i] = float(g[i]);
        g[i] = double(val[i]);  // the masses below are those of the stored values
    }
    std::vector<double> w(size_t(H) * P);
    for (int a = 0; a < H; ++a)
        for (int b = 0; b < P; ++b) w[size_t(a) * P + b] = mass(a, b);
    fill_cdfs(k, w);
}

void TableSampler::fill_cdfs(int k, const std::vector<double>& mass) {
    const int H = cells_h_, P = cells_p_;
    std::vector<double> rows(H);
    double node_total = 0;
    for (int a = 0; a < H; ++a) {
        const double* w = &mass[size_t(a) * P];
        double row_total = 0;
        for (int b = 0; b < P; ++b) row_total += w[b];
        uint32_t* cdf = &conditional_[(size_t(k) * H + a) * P];
        uint32_t acc = 0;
        for (int b = 0; b < P; ++b) cdf[b] = (acc += units(w[b], row_total, kCdfUnits));
        rows[a] = row_total;
        node_total += row_total;
    }
    total_[k] = node_total;
    uint32_t acc = 0;
    for (int a = 0; a < H; ++a) marginal_[size_t(k) * H + a] = (acc += units(rows[a], node_total, kCdfUnits));
}

double TableSampler::cell_probability(int k, int a, int b) const {
    const int H = cells_h_, P = cells_p_;
    const uint32_t* rows = &marginal_[size_t(k) * H];
    const uint32_t q_a = rows[a] - (a ? rows[a - 1] : 0u);
    if (q_a == 0) return 0.0;
    const uint32_t* cells = &conditional_[(size_t(k) * H + a) * P];
    const uint32_t r_b = cells[b] - (b ? cells[b - 1] : 0u);
    return (double(q_a) / rows[H - 1]) * (double(r_b) / cells[P - 1]);
}

int TableSampler::choose_node(const Mixture& m, double u2, double* v) const {
    // u2 split at the nodes' probabilities and stretched back to [0, 1).
    int i = 0;
    double x = std::clamp(u2, 0.0, kOneMinusEps);
    while (i < m.count - 1 && x >= m.p[i]) x -= m.p[i++];
    *v = std::clamp(x / m.p[i], 0.0, kOneMinusEps);
    return i;
}

TableSampler::~TableSampler() { g_live_bytes.fetch_sub(bytes_); }

TableSampler::Memory TableSampler::memory() { return {g_live_bytes.load(), g_peak_bytes.load()}; }

size_t TableSampler::bytes_used() const { return bytes_; }

bool TableSampler::mixture(const Vec3& wo, Mixture* m) const {
    const double x = std::acos(std::clamp(wo.z, 0.0, 1.0)) / step_to_;
    const int j0 = std::clamp(int(x), 0, n_to_ - 2);
    const double t = std::clamp(x - j0, 0.0, 1.0);
    int q0 = 0, q1 = 0;
    double tq = 0;
    if (n_po_ > 1) {
        double phi = std::atan2(wo.y, wo.x);
        if (phi < 0) phi += 2 * kPi;
        const double y = phi / step_po_;
        q0 = std::clamp(int(y), 0, n_po_ - 1);
        tq = std::clamp(y - q0, 0.0, 1.0);
        q1 = (q0 + 1) % n_po_;
    }
    const int nodes[4] = {j0 * n_po_ + q0, (j0 + 1) * n_po_ + q0, j0 * n_po_ + q1, (j0 + 1) * n_po_ + q1};
    const double wts[4] = {(1 - t) * (1 - tq), t * (1 - tq), (1 - t) * tq, t * tq};
    double sum = 0;
    m->count = 0;
    const double so = std::hypot(wo.x, wo.y);
    const double co = so > 0 ? wo.x / so : 1.0, sn = so > 0 ? wo.y / so : 0.0;
    for (int i = 0; i < (n_po_ > 1 ? 4 : 2); ++i) {
        const double p = wts[i] * total_[nodes[i]];
        if (!(p > 0)) continue;
        Vec3 ref = wo;
        if (!mirror_) {  // anisotropic grids: the node's theta_o at the viewer's azimuth
            const double th = std::min((nodes[i] / n_po_) * step_to_, kPi / 2 - 1e-3);
            ref = Vec3(std::sin(th) * co, std::sin(th) * sn, std::cos(th));
        }
        m->ref[m->count] = ref;
        m->node[m->count] = nodes[i];
        m->p[m->count++] = p;
        sum += p;
    }
    if (!(sum > 0)) return false;
    for (int i = 0; i < m->count; ++i) m->p[i] /= sum;
    return true;
}

double TableSampler::node_density(int k, const HPos& pos) const {
    const double p = cell_probability(k, pos.a, pos.b);
    if (p == 0) return 0.0;
    const int W = cells_p_ + 1;
    const float* c = &value_[(size_t(k) * (cells_h_ + 1) + pos.a) * W + pos.b];
    const double v00 = c[0], v01 = c[1], v10 = c[W], v11 = c[W + 1];
    const double mean = 0.25 * (v00 + v01 + v10 + v11);
    const double here = lerp(lerp(v00, v01, pos.t), lerp(v10, v11, pos.t), pos.s);
    return p * here / mean;
}

Vec3 TableSampler::sample(const Vec3& wo, double u1, double u2) const {
    if (!(wo.z > 0)) return {};
    Mixture m;
    if (!mixture(wo, &m)) return {};
    if (cells_mode_) return sample_cells(wo, m, u1, u2);
    double v = 0;
    const int i = choose_node(m, u2, &v);
    const int k = m.node[i], H = cells_h_, P = cells_p_, W = P + 1;
    u1 = std::clamp(u1, 0.0, kOneMinusEps);

    // Row a by the marginal (u1), column b by the conditional (v); the remainders place the
    // half vector inside the cell.
    double fs = 0, ft = 0;
    const int a = pick(&marginal_[size_t(k) * H], H, u1, &fs);
    if (a >= H) return {};  // a node of total mass 0 (never chosen: its probability is 0)
    const bool plus = mirror_ ? fold_side(&v) : true;
    const int b = pick(&conditional_[(size_t(k) * H + a) * P], P, v, &ft);
    if (b >= P) return {};
    // Bilinear density inside the cell: s (along 1 - cos theta_h) by its linear marginal,
    // then t (along phi_h) by its linear conditional.
    const float* c = &value_[(size_t(k) * (H + 1) + a) * W + b];
    const double v00 = c[0], v01 = c[1], v10 = c[W], v11 = c[W + 1];
    const double s = sample_linear(fs, v00 + v01, v10 + v11);
    const double t = sample_linear(ft, lerp(v00, v10, s), lerp(v01, v11, s));
    const double omc = lerp(omc_[a], omc_[a + 1], s);
    const double cos_h = 1.0 - omc, sin_h = std::sqrt(std::max(0.0, omc * (2.0 - omc)));
    double phi = (b + t) * dphi_;
    if (!plus) phi = -phi;
    double cp = std::cos(phi), sp = std::sin(phi);
    const Vec3& ref = m.ref[i];  // wi is the reflection of this direction
    if (mirror_) {  // measured from the viewer's azimuth
        const double so = std::hypot(ref.x, ref.y);
        const double co = so > 0 ? ref.x / so : 1.0, sn = so > 0 ? ref.y / so : 0.0;
        const double c2 = co * cp - sn * sp, s2 = sn * cp + co * sp;
        cp = c2;
        sp = s2;
    }
    const Vec3 h(sin_h * cp, sin_h * sp, cos_h);
    const double d = dot(ref, h);
    if (!(d > 0)) return {};
    const Vec3 wi = normalize(h * (2.0 * d) - ref);
    if (!(wi.z > 0)) return {};
    return wi;
}

double TableSampler::pdf(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0.0;
    Mixture m;
    if (!mixture(wo, &m)) return 0.0;
    if (cells_mode_) return pdf_cells(wo, wi, m);
    double p = 0;
    for (int i = 0; i < m.count; ++i) {
        const Vec3& ref = m.ref[i];
        const Vec3 sum = ref + wi;
        const double len = length(sum);
        if (!(len > 0)) continue;
        const Vec3 h = sum * (1.0 / len);
        const double d = dot(ref, h);
        if (!(d > 0)) continue;
        const double sin_h = std::hypot(h.x, h.y);
        const double omc = 2.0 * sqr(std::sin(0.5 * std::atan2(sin_h, h.z)));
        HPos pos;
        pos.a = std::clamp(int(std::upper_bound(omc_.begin(), omc_.end(), omc) - omc_.begin()) - 1, 0, cells_h_ - 1);
        pos.s = std::clamp((omc - omc_[pos.a]) / (omc_[pos.a + 1] - omc_[pos.a]), 0.0, 1.0);
        // phi_h: from the viewer's azimuth folded to [0, pi] (isotropic), or from the tangent.
        double phi = 0;
        if (sin_h > 0) {
            if (mirror_) {
                const double so = std::hypot(ref.x, ref.y);
                const double co = so > 0 ? ref.x / so : 1.0, sn = so > 0 ? ref.y / so : 0.0;
                phi = std::abs(std::atan2(co * h.y - sn * h.x, co * h.x + sn * h.y));
            } else {
                phi = std::atan2(h.y, h.x);
                if (phi < 0) phi += 2 * kPi;
            }
        }
        const double x = phi / dphi_;
        pos.b = std::clamp(int(x), 0, cells_p_ - 1);
        pos.t = std::clamp(x - pos.b, 0.0, 1.0);
        // Per unit solid angle of h: the cell's (both sides when mirrored), then the
        // reflection's Jacobian dw_i = 4 (ref . h) dw_h.
        const double area = (omc_[pos.a + 1] - omc_[pos.a]) * dphi_ * (mirror_ ? 2.0 : 1.0);
        p += m.p[i] * node_density(m.node[i], pos) / (area * 4.0 * d);
    }
    return p;
}

// ---------------------------------------------------------------- isotropic tables: the table's own cells
//
// Inside cell (a, b) of node j, with s = (theta_i - theta_a) / step in [0, 1] and t the same
// along phi, the table is bilinear: f(s, t) from the corners v00 (a, b), v01 (a, b+1),
// v10 (a+1, b), v11 (a+1, b+1). The proposal density per unit of (theta_i, phi) is
// f(s, t) L(s), L the linear interpolation of sin theta cos theta between the cell's edges
// (the solid angle's sin times the cosine), so f cos / pdf = const x sin theta cos theta / L(s):
// within 1.5e-4 of the constant over a 1 deg cell (exact at the edges and at the pole and
// grazing cells, where sin theta cos theta is linear in theta). The marginal in s is the
// quadratic f(s) L(s) (f averaged over t), sampled by Newton's method on its cubic CDF inside
// [0, 1]; t by the linear conditional at s.

namespace {
// The quadratic q(s) = (A0 + (A1 - A0) s)(c0 + (c1 - c0) s): coefficients and its integral.
struct Quad {
    double k0, k1, k2;
    double at(double s) const { return k0 + s * (k1 + s * k2); }
    double integral(double s) const { return s * (k0 + s * (0.5 * k1 + s * k2 / 3.0)); }
};
Quad row_quad(double A0, double A1, double c0, double c1) {
    return {A0 * c0, A0 * (c1 - c0) + c0 * (A1 - A0), (A1 - A0) * (c1 - c0)};
}
}  // namespace

const float* TableSampler::row(int j, int a) const {
    const uint32_t idx[4] = {uint32_t(a), uint32_t(j), 0, 0};
    return table_->values().data() + table_->offset(idx);
}

void TableSampler::corners(int j, int a, int b, double v[4]) const {
    const int C = channels_;
    const float* lo = row(j, a) + size_t(b) * C;
    const float* hi = row(j, a + 1) + size_t(b) * C;
    if (C == 1) {
        v[0] = lo[0], v[1] = lo[1], v[2] = hi[0], v[3] = hi[1];
        return;
    }
    v[0] = (double(lo[0]) + lo[1] + lo[2]) / 3.0;
    v[1] = (double(lo[3]) + lo[4] + lo[5]) / 3.0;
    v[2] = (double(hi[0]) + hi[1] + hi[2]) / 3.0;
    v[3] = (double(hi[3]) + hi[4] + hi[5]) / 3.0;
}

void TableSampler::build_cells(const BrdfTable& table) {
    cells_mode_ = true;
    table_ = &table;
    const TableGeometry& g = table.geometry();
    channels_ = g.channels;
    n_ti_ = int(g.n[0]);
    n_to_ = int(g.n[1]);
    n_po_ = 1;
    step_to_ = g.step_deg(1) * kDegree;
    step_ti_ = g.step_deg(0) * kDegree;
    cells_h_ = n_ti_ - 1;
    cells_p_ = int(g.n[2]) - 1;
    dphi_ = g.step_deg(2) * kDegree;
    const int H = cells_h_, P = cells_p_;
    sincos_.resize(n_ti_);
    for (int a = 0; a < n_ti_; ++a) sincos_[a] = 0.5 * std::sin(2.0 * a * step_ti_);
    sincos_[n_ti_ - 1] = 0.0;  // exactly grazing
    total_.assign(n_to_, 0.0);
    marginal_.assign(size_t(n_to_) * H, 0);
    conditional_.assign(size_t(n_to_) * H * P, 0);
    std::vector<double> w(size_t(H) * P);
    for (int j = 0; j < n_to_; ++j) {
        for (int a = 0; a < H; ++a)
            for (int b = 0; b < P; ++b) {
                double v[4];
                corners(j, a, b, v);
                w[size_t(a) * P + b] = cell_mass(a, v);
            }
        fill_cdfs(j, w);
    }
    bytes_ = sizeof(*this) + (total_.capacity() + sincos_.capacity()) * sizeof(double) +
             marginal_.capacity() * sizeof(uint32_t) + conditional_.capacity() * sizeof(uint32_t);
    account_add(bytes_);
}

double TableSampler::cell_mass(int a, const double v[4]) const {
    // The proposal's integral over the cell (one side of the plane), per unit of s and t
    // times step x dphi: the quadratic's integral over [0, 1] (f averaged over t).
    const Quad q = row_quad(0.5 * (v[0] + v[1]), 0.5 * (v[2] + v[3]), sincos_[a], sincos_[a + 1]);
    return q.integral(1.0) * step_ti_ * dphi_;
}

double TableSampler::cell_density(int j, int a, int b, double s, double t) const {
    const double p = cell_probability(j, a, b);
    if (p == 0) return 0.0;
    double v[4];
    corners(j, a, b, v);
    const double here = lerp(lerp(v[0], v[1], t), lerp(v[2], v[3], t), s);
    return p * here / cell_mass(a, v);
}

Vec3 TableSampler::sample_cells(const Vec3& wo, const Mixture& m, double u1, double u2) const {
    double v = 0;
    const int j = m.node[choose_node(m, u2, &v)], H = cells_h_, P = cells_p_;
    double fs = 0, ft = 0;
    const int a = pick(&marginal_[size_t(j) * H], H, std::clamp(u1, 0.0, kOneMinusEps), &fs);
    if (a >= H) return {};
    const bool plus = fold_side(&v);
    const int b = pick(&conditional_[(size_t(j) * H + a) * P], P, v, &ft);
    if (b >= P) return {};
    double c[4];
    corners(j, a, b, c);
    // s by the quadratic marginal: Newton's method on its CDF, kept inside a bracket, from the
    // linear density through the ends' values.
    const Quad q = row_quad(0.5 * (c[0] + c[1]), 0.5 * (c[2] + c[3]), sincos_[a], sincos_[a + 1]);
    const double target = fs * q.integral(1.0);
    double lo = 0, hi = 1, s = sample_linear(fs, std::max(q.at(0), 0.0), std::max(q.at(1), 0.0));
    for (int it = 0; it < 20; ++it) {
        const double g = q.integral(s) - target, dg = q.at(s);
        if (g > 0) hi = s; else lo = s;
        double next = dg > 0 ? s - g / dg : 0.5 * (lo + hi);
        if (!(next >= lo && next <= hi)) next = 0.5 * (lo + hi);
        const bool done = std::abs(next - s) <= 1e-13;
        s = next;
        if (done) break;
    }
    const double t = sample_linear(ft, lerp(c[0], c[2], s), lerp(c[1], c[3], s));
    const double th = (a + s) * step_ti_;
    const double cos_i = std::cos(th), sin_i = std::sin(th);
    if (!(cos_i > 0)) return {};  // exactly grazing: a set of measure zero
    const double phi = std::min((b + t) * dphi_, kPi);
    // phi = phi_o - phi_i (the table's phi_r - phi_i): wi's azimuth is phi_o -+ phi.
    const double so = std::hypot(wo.x, wo.y);
    const double co = so > 0 ? wo.x / so : 1.0, sn = so > 0 ? wo.y / so : 0.0;
    const double cp = std::cos(phi), sp = plus ? std::sin(phi) : -std::sin(phi);
    return {sin_i * (co * cp + sn * sp), sin_i * (sn * cp - co * sp), cos_i};
}

double TableSampler::pdf_cells(const Vec3& wo, const Vec3& wi, const Mixture& m) const {
    const double sin_i = std::hypot(wi.x, wi.y);
    const double x = std::atan2(sin_i, wi.z) / step_ti_;
    const int a = std::clamp(int(x), 0, cells_h_ - 1);
    const double s = std::clamp(x - a, 0.0, 1.0);
    // phi between the projections of wo and wi (0 at a pole, where nothing depends on it).
    const double so = std::hypot(wo.x, wo.y);
    const double cphi = so > 0 && sin_i > 0 ? std::clamp((wo.x * wi.x + wo.y * wi.y) / (so * sin_i), -1.0, 1.0) : 1.0;
    const double y = std::acos(cphi) / dphi_;
    const int b = std::clamp(int(y), 0, cells_p_ - 1);
    const double t = std::clamp(y - b, 0.0, 1.0);
    double p = 0;
    for (int i = 0; i < m.count; ++i) p += m.p[i] * cell_density(m.node[i], a, b, s, t);
    // Per unit of (theta_i, phi): P(cell) f L(s) / mass; per solid angle / sin theta_i; either
    // side of the plane 1/2. At the pole (cell 0, where L(s) = c1 s) L / sin theta_i tends to
    // c1 / step.
    const double L = lerp(sincos_[a], sincos_[a + 1], s);
    const double ratio = sin_i > 0 ? L / sin_i : sincos_[1] / step_ti_;
    return 0.5 * p * ratio;
}

// ---------------------------------------------------------------- the table's sampling

const TableSampler* BrdfTable::sampler() const {
    if (const TableSampler* s = sampler_ready_.load(std::memory_order_acquire)) return s;
    std::call_once(sampler_once_, [this] {
        sampler_ = std::unique_ptr<const TableSampler, SamplerDeleter>(new TableSampler(*this));
        sampler_ready_.store(sampler_.get(), std::memory_order_release);
    });
    return sampler_.get();
}

size_t BrdfTable::sampler_bytes() const {
    const TableSampler* s = sampler_ready_.load(std::memory_order_acquire);
    return s ? s->bytes_used() : 0;
}

Vec3 BrdfTable::sample(const Vec3& wo, double u1, double u2) const {
    const TableSampler* s = sampler();
    return s ? s->sample(wo, u1, u2) : Brdf::sample(wo, u1, u2);
}

double BrdfTable::pdf(const Vec3& wo, const Vec3& wi) const {
    const TableSampler* s = sampler();
    return s ? s->pdf(wo, wi) : Brdf::pdf(wo, wi);
}

void BrdfTable::SamplerDeleter::operator()(const TableSampler* s) const { delete s; }

}  // namespace shading
