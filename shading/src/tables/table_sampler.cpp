// Importance sampling of tables from their own data (table_sampler.h).
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

// Resolution of the integer CDFs. A node's rows share 2^30 units; a row's cells share up to
// 65535 - 2 (cells - 1) units, so that rounding up every positive weight to at least one unit
// still fits 16 bits (a 0.01 deg table, 18000 phi cells, keeps 29535 units).
constexpr double kRowUnits = double(1u << 30);

// Units of a positive weight: its rounded share, at least 1.
uint32_t units(double w, double total, double scale) {
    if (!(w > 0) || !(total > 0)) return 0;
    return uint32_t(std::max(1.0, std::round(w / total * scale)));
}

}  // namespace

TableSampler::TableSampler(const BrdfTable& table) {
    // Half/difference tables (isotropic BRDFs on another grid) are sampled on a 1 deg
    // isotropic grid of their own values; their cells get a floor (below) because a lobe
    // narrower than a cell can be positive where all four corners are nearly zero.
    const bool own_grid = table.geometry().layout == TableLayout::Isotropic;
    if (!own_grid && table.geometry().layout != TableLayout::HalfDiff)
        throw std::invalid_argument("TableSampler: isotropic or half/difference tables only");
    const TableGeometry g = own_grid ? table.geometry() : TableGeometry::isotropic(1.0, table.geometry().channels);
    n_theta_i_ = int(g.n[0]);
    n_theta_o_ = int(g.n[1]);
    n_phi_ = int(g.n[2]);
    cells_t_ = n_theta_i_ - 1;
    cells_p_ = n_phi_ - 1;
    step_t_deg_ = g.step_deg(0);
    step_o_deg_ = g.step_deg(1);
    step_p_deg_ = g.step_deg(2);
    const double cell_units = 65535.0 - 2.0 * cells_p_;  // >= 29535 (validate(): <= 18001 phi nodes)

    sin2_.resize(n_theta_i_);
    for (int a = 0; a < n_theta_i_; ++a) sin2_[a] = sqr(std::sin(g.axis_deg(0, uint32_t(a)) * kDegree));
    total_.assign(n_theta_o_, 0.0);
    marginal_.assign(size_t(n_theta_o_) * cells_t_, 0);
    conditional_.assign(size_t(n_theta_o_) * cells_t_ * cells_p_, 0);

    const int C = g.channels;
    const double dphi = step_p_deg_ * kDegree;
    std::vector<double> lum(size_t(n_theta_i_) * n_phi_), w(cells_p_), row(cells_t_);
    for (int j = 0; j < n_theta_o_; ++j) {
        // Channel mean of every node at this theta_o.
        for (int a = 0; a < n_theta_i_; ++a)
            for (int b = 0; b < n_phi_; ++b) {
                double s = 0;
                if (own_grid) {
                    for (int c = 0; c < C; ++c) s += table.node(uint32_t(a), uint32_t(j), uint32_t(b), 0, c);
                    s /= C;
                } else {
                    s = table.eval_iso(g.axis_deg(0, uint32_t(a)) * kDegree, g.axis_deg(1, uint32_t(j)) * kDegree,
                                       g.axis_deg(2, uint32_t(b)) * kDegree, Interp::Linear).average();
                }
                lum[size_t(a) * n_phi_ + b] = s;
            }
        if (!own_grid) {
            // Floor: 1e-3 of the mean node value, so every direction keeps a positive density
            // (the estimator stays unbiased whatever the lobe does between the grid's nodes).
            double mean = 0;
            for (double v : lum) mean += v;
            mean /= double(lum.size());
            for (double& v : lum) v = std::max(v, 1e-3 * mean);
        }
        double node_total = 0;
        for (int a = 0; a < cells_t_; ++a) {
            // Integral of cos over the cell and its mirror image (-phi): dphi (sin^2 - sin^2).
            const double band = dphi * (sin2_[a + 1] - sin2_[a]);
            const double* lo = &lum[size_t(a) * n_phi_];
            const double* hi = lo + n_phi_;
            double row_total = 0;
            for (int b = 0; b < cells_p_; ++b) {
                w[b] = 0.25 * (lo[b] + lo[b + 1] + hi[b] + hi[b + 1]) * band;
                row_total += w[b];
            }
            uint16_t* cdf = &conditional_[(size_t(j) * cells_t_ + a) * cells_p_];
            uint32_t acc = 0;
            for (int b = 0; b < cells_p_; ++b) {
                acc += units(w[b], row_total, cell_units);
                cdf[b] = uint16_t(acc);
            }
            row[a] = row_total;
            node_total += row_total;
        }
        total_[j] = node_total;
        uint32_t acc = 0;
        for (int a = 0; a < cells_t_; ++a) {
            acc += units(row[a], node_total, kRowUnits);
            marginal_[size_t(j) * cells_t_ + a] = acc;
        }
    }
    bytes_ = sizeof(*this) + sin2_.capacity() * sizeof(double) + total_.capacity() * sizeof(double) +
             marginal_.capacity() * sizeof(uint32_t) + conditional_.capacity() * sizeof(uint16_t);
    account_add(bytes_);
}

TableSampler::~TableSampler() { g_live_bytes.fetch_sub(bytes_); }

TableSampler::Memory TableSampler::memory() { return {g_live_bytes.load(), g_peak_bytes.load()}; }

size_t TableSampler::bytes_used() const { return bytes_; }

bool TableSampler::mixture(double cos_o, Mixture* m) const {
    const double x = std::acos(std::clamp(cos_o, 0.0, 1.0)) * kRadToDeg / step_o_deg_;
    const int j0 = std::clamp(int(x), 0, n_theta_o_ - 2);
    const double t = std::clamp(x - j0, 0.0, 1.0);
    // The interpolated table's albedo at theta_o splits between the nodes like this.
    const double a0 = (1.0 - t) * total_[j0], a1 = t * total_[j0 + 1];
    if (!(a0 + a1 > 0)) return false;
    *m = {j0, j0 + 1, a0 / (a0 + a1)};
    return true;
}

double TableSampler::cell_pdf(int j, int a, int b) const {
    const uint32_t* rows = &marginal_[size_t(j) * cells_t_];
    const uint32_t q_all = rows[cells_t_ - 1], q_a = rows[a] - (a ? rows[a - 1] : 0u);
    if (q_a == 0) return 0.0;
    const uint16_t* cells = &conditional_[(size_t(j) * cells_t_ + a) * cells_p_];
    const uint32_t r_all = cells[cells_p_ - 1], r_b = uint32_t(cells[b]) - (b ? cells[b - 1] : 0u);
    return (double(q_a) / q_all) * (double(r_b) / r_all);
}

Vec3 TableSampler::sample(const Vec3& wo, double u1, double u2) const {
    if (!(wo.z > 0)) return {};
    Mixture m;
    if (!mixture(wo.z, &m)) return {};
    // Node: u2 split at alpha and stretched back to [0, 1).
    int j = m.j1;
    double v = u2;
    if (u2 < m.alpha) {
        j = m.j0;
        v = u2 / m.alpha;
    } else {
        v = (u2 - m.alpha) / (1.0 - m.alpha);
    }
    u1 = std::clamp(u1, 0.0, kOneMinusEps);
    v = std::clamp(v, 0.0, kOneMinusEps);

    // Row a by the marginal (u1), cell b by the conditional (v); the remainders place the
    // direction inside the cell.
    const uint32_t* rows = &marginal_[size_t(j) * cells_t_];
    const double target_a = u1 * rows[cells_t_ - 1];
    const int a = int(std::upper_bound(rows, rows + cells_t_, target_a) - rows);
    if (a >= cells_t_) return {};  // a node of total weight 0 (only when alpha is 0 or 1)
    const double lo_a = a ? rows[a - 1] : 0.0;
    const double fu = std::clamp((target_a - lo_a) / (rows[a] - lo_a), 0.0, 1.0);

    const uint16_t* cells = &conditional_[(size_t(j) * cells_t_ + a) * cells_p_];
    const double target_b = v * cells[cells_p_ - 1];
    const int b = int(std::upper_bound(cells, cells + cells_p_, target_b) - cells);
    if (b >= cells_p_) return {};
    const double lo_b = b ? cells[b - 1] : 0.0;
    double fv = std::clamp((target_b - lo_b) / (cells[b] - lo_b), 0.0, 1.0);
    // Half the cell's mass on each side of the viewer's plane of incidence.
    const bool plus = fv < 0.5;
    fv = plus ? 2.0 * fv : 2.0 * fv - 1.0;

    // Density proportional to cos inside the cell: sin^2 theta uniform over the cell.
    const double s2 = sin2_[a] + fu * (sin2_[a + 1] - sin2_[a]);
    const double cos_i = std::sqrt(std::max(0.0, 1.0 - s2)), sin_i = std::sqrt(std::max(0.0, s2));
    if (!(cos_i > 0)) return {};  // exactly grazing: a set of measure zero
    const double phi = std::min((b + fv) * step_p_deg_, 180.0) * kDegree;
    // phi = phi_o - phi_i (the table's phi_r - phi_i): wi's azimuth is phi_o -+ phi.
    const double so = std::hypot(wo.x, wo.y);
    const double co_phi = so > 0 ? wo.x / so : 1.0, so_phi = so > 0 ? wo.y / so : 0.0;
    const double cp = std::cos(phi), sp = plus ? std::sin(phi) : -std::sin(phi);
    const double ci_phi = co_phi * cp + so_phi * sp, si_phi = so_phi * cp - co_phi * sp;
    return {sin_i * ci_phi, sin_i * si_phi, cos_i};
}

double TableSampler::pdf(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0) || !(wi.z > 0)) return 0.0;
    Mixture m;
    if (!mixture(wo.z, &m)) return 0.0;
    const double cos_i = std::min(wi.z, 1.0);
    const int a = std::clamp(int(std::acos(cos_i) * kRadToDeg / step_t_deg_), 0, cells_t_ - 1);
    // phi between the projections of wo and wi (0 at a pole, where nothing depends on it).
    const double so = std::hypot(wo.x, wo.y), si = std::hypot(wi.x, wi.y);
    const double cphi = so > 0 && si > 0 ? std::clamp((wo.x * wi.x + wo.y * wi.y) / (so * si), -1.0, 1.0) : 1.0;
    const int b = std::clamp(int(std::acos(cphi) * kRadToDeg / step_p_deg_), 0, cells_p_ - 1);
    double p = 0;
    if (m.alpha > 0) p += m.alpha * cell_pdf(m.j0, a, b);
    if (m.alpha < 1) p += (1.0 - m.alpha) * cell_pdf(m.j1, a, b);
    // Inside the cell (and its mirror image) the density is cos / integral of cos.
    return p * cos_i / (step_p_deg_ * kDegree * (sin2_[a + 1] - sin2_[a]));
}

// ---------------------------------------------------------------- the table's sampling

const TableSampler* BrdfTable::sampler() const {
    if (geom_.layout == TableLayout::Anisotropic) return nullptr;  // the generic mixture
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
