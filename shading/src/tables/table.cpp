// BrdfTable lookups, albedo, and the tools that build tables (fill, fold, tabulate,
// resample, measurement simulation, checks). The file format lives in table_io.cpp.
#include "shading/tables/table.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

#include "shading/core/format.h"
#include "shading/core/random.h"
#include "shading/tables/table_sampler.h"

namespace shading {

namespace {

// Node counts the format accepts: theta down to 0.01 deg, phi likewise. Anything above is
// a corrupt header, not a table (a 0.01 deg isotropic table is already ~2 TB).
constexpr uint32_t kMaxThetaNodes = 9001;
constexpr uint32_t kMaxIsoPhiNodes = 18001;
constexpr uint32_t kMaxAnisoPhiNodes = 36000;

uint32_t nodes_for_step(double range, double step, bool closed, const char* what) {
    if (!(step > 0) || !std::isfinite(step))
        throw std::invalid_argument(std::string("table step for ") + what + " must be a positive number of degrees");
    double k = range / step;
    double kr = std::round(k);
    if (kr < 1 || std::fabs(k - kr) > 1e-9 * std::max(1.0, k) || kr > 1e6)
        throw std::invalid_argument(std::string("table step ") + std::to_string(step) + " deg does not divide " +
                                    std::to_string(int(range)) + " deg (" + what + ")");
    return uint32_t(kr) + (closed ? 1u : 0u);
}

uint64_t mul_checked(uint64_t a, uint64_t b) {
    uint64_t r;
    if (__builtin_mul_overflow(a, b, &r)) throw std::overflow_error("table size overflows 64 bits");
    return r;
}

bool valid_value(float v) { return std::isfinite(v) && v >= 0.0f; }

// Human-readable node label for error messages.
std::string cell_label(const TableGeometry& g, const uint32_t idx[4], int channel) {
    std::ostringstream s;
    for (int a = 0; a < g.axes(); ++a) s << (a ? " " : "") << g.axis_name(a) << "=" << detail::fmt(g.axis_deg(a, idx[a]), 9);
    s << " deg, channel " << channel;
    return s.str();
}

std::string value_text(float v) {
    if (std::isnan(v)) return "nan";
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    return detail::fmt(v, 9);
}

// Fill the invalid entries of one line from the nearest valid entries on either side
// (linear in the node distance; a copy when only one side has data). `ok` is the
// validity before this pass; `filled` receives which entries were written.
void fill_line(std::vector<double>& v, const std::vector<uint8_t>& ok, std::vector<uint8_t>& filled, bool periodic,
               std::vector<int>& valid) {
    const int n = int(v.size());
    valid.clear();
    for (int p = 0; p < n; ++p)
        if (ok[p]) valid.push_back(p);
    std::fill(filled.begin(), filled.end(), 0);
    if (valid.empty() || int(valid.size()) == n) return;
    for (int p = 0; p < n; ++p) {
        if (ok[p]) continue;
        auto it = std::lower_bound(valid.begin(), valid.end(), p);
        bool has_r = it != valid.end(), has_l = it != valid.begin();
        int r = has_r ? *it : -1, l = has_l ? *(it - 1) : -1;
        double dl = p - l, dr = r - p;
        if (periodic) {
            if (!has_r) { r = valid.front(); dr = r + n - p; has_r = true; }
            if (!has_l) { l = valid.back(); dl = p + n - l; has_l = true; }
        }
        if (has_l && has_r)
            v[p] = (v[l] * dr + v[r] * dl) / (dl + dr);
        else
            v[p] = has_l ? v[l] : v[r];
        filled[p] = 1;
    }
}

ReciprocityStats reciprocity_of(const TableGeometry& g, const float* v) {
    ReciprocityStats s;
    const int C = g.channels;
    double fmax = 0;
    for (uint64_t k = 0, nv = g.values(); k < nv; ++k)
        if (valid_value(v[k])) fmax = std::max(fmax, double(v[k]));
    if (g.folded || g.layout == TableLayout::HalfDiff) {  // reciprocal by construction
        s.applicable = true;
        return s;
    }
    if (g.layout == TableLayout::Isotropic ? g.n[0] != g.n[1] : (g.n[0] != g.n[2] || g.n[1] != g.n[3])) return s;
    s.applicable = true;
    double sum2 = 0;
    uint64_t count = 0;
    const uint64_t cells = g.cells();
    uint32_t idx[4], sw[4];
    for (uint64_t c = 0; c < cells; ++c) {
        g.unravel(c, idx);
        uint64_t other;
        if (g.layout == TableLayout::Isotropic) {
            if (idx[0] >= idx[1]) continue;  // each unordered pair once, diagonal excluded
            sw[0] = idx[1]; sw[1] = idx[0]; sw[2] = idx[2]; sw[3] = 0;
            other = (uint64_t(sw[0]) * g.n[1] + sw[1]) * g.n[2] + sw[2];
        } else {
            sw[0] = idx[2]; sw[1] = idx[3]; sw[2] = idx[0]; sw[3] = idx[1];
            other = ((uint64_t(sw[0]) * g.n[1] + sw[1]) * g.n[2] + sw[2]) * g.n[3] + sw[3];
            if (other <= c) continue;
        }
        for (int ch = 0; ch < C; ++ch) {
            float a = v[c * C + ch], b = v[other * C + ch];
            if (!valid_value(a) || !valid_value(b)) continue;
            double d = std::fabs(double(a) - double(b));
            sum2 += d * d;
            ++count;
            if (d > s.max_abs) {
                s.max_abs = d;
                std::copy(idx, idx + 4, s.worst);
            }
        }
    }
    s.rms_abs = count ? std::sqrt(sum2 / double(count)) : 0.0;
    s.max_rel = fmax > 0 ? s.max_abs / fmax : 0.0;
    return s;
}

// A standard normal deviate by Box-Muller from a fully specified generator (core/random.h), so a
// seed gives the same table everywhere (std::normal_distribution is implementation-defined).
// 1 - u keeps log() away from 0.
double normal_deviate(SplitMix64& rng) {
    double u1 = 1.0 - rng.uniform(), u2 = rng.uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * kPi * u2);
}

}  // namespace

[[noreturn]] void throw_table_error(const std::string& name, uint64_t offset, const std::string& expected,
                                    const std::string& found) {
    throw TableError(name + ": offset " + std::to_string(offset) + ": expected " + expected + ", found " + found);
}

const char* to_string(Interp i) { return i == Interp::Nearest ? "nearest" : "linear"; }
const char* to_string(NoDataPolicy p) { return p == NoDataPolicy::Fill ? "fill" : "reject"; }
Interp parse_interp(const std::string& s) {
    if (s == "nearest") return Interp::Nearest;
    if (s == "linear" || s == "trilinear") return Interp::Linear;
    throw std::invalid_argument("interpolation '" + s + "': expected nearest or linear");
}
NoDataPolicy parse_nodata_policy(const std::string& s) {
    if (s == "fill") return NoDataPolicy::Fill;
    if (s == "reject") return NoDataPolicy::Reject;
    throw std::invalid_argument("no-data policy '" + s + "': expected fill or reject");
}

// ---------------------------------------------------------------- geometry

TableGeometry TableGeometry::isotropic(double step_deg, int channels, bool folded) {
    TableGeometry g;
    g.layout = TableLayout::Isotropic;
    g.channels = channels;
    g.n[0] = g.n[1] = nodes_for_step(90.0, step_deg, true, "theta");
    g.n[2] = nodes_for_step(180.0, step_deg, true, "phi");
    g.n[3] = 1;
    g.folded = folded;
    g.validate();
    return g;
}

TableGeometry TableGeometry::anisotropic(double theta_step_deg, double phi_step_deg, int channels) {
    TableGeometry g;
    g.layout = TableLayout::Anisotropic;
    g.channels = channels;
    g.n[0] = g.n[2] = nodes_for_step(90.0, theta_step_deg, true, "theta");
    g.n[1] = g.n[3] = nodes_for_step(360.0, phi_step_deg, false, "phi");
    g.folded = false;
    g.validate();
    return g;
}

TableGeometry TableGeometry::halfdiff(uint32_t n_h, uint32_t n_d, uint32_t n_p, int channels) {
    TableGeometry g;
    g.layout = TableLayout::HalfDiff;
    g.channels = channels;
    g.n[0] = n_h;
    g.n[1] = n_d;
    g.n[2] = n_p;
    g.n[3] = 1;
    g.folded = false;
    g.validate();
    return g;
}

bool TableGeometry::is_phi_axis(int axis) const {
    return layout == TableLayout::Anisotropic ? (axis == 1 || axis == 3) : axis == 2;
}
bool TableGeometry::is_periodic(int axis) const { return layout != TableLayout::Isotropic && is_phi_axis(axis); }

double TableGeometry::step_deg(int axis) const {
    if (layout == TableLayout::HalfDiff) return (axis == 2 ? 180.0 : 90.0) / double(n[axis]);
    if (!is_phi_axis(axis)) return 90.0 / double(n[axis] - 1);
    if (is_periodic(axis)) return 360.0 / double(n[axis]);
    return 180.0 / double(n[axis] - 1);
}

double TableGeometry::axis_deg(int axis, uint32_t index) const {
    if (layout == TableLayout::HalfDiff) {  // bin centres (table.h)
        const double u = (double(index) + 0.5) / double(n[axis]);
        return axis == 0 ? 90.0 * u * u : (axis == 1 ? 90.0 : 180.0) * u;
    }
    // The last theta/iso-phi node is exactly the range end, not a rounded multiple.
    if (!is_periodic(axis) && index + 1 == n[axis]) return is_phi_axis(axis) ? 180.0 : 90.0;
    return double(index) * step_deg(axis);
}

uint32_t TableGeometry::max_nodes(int axis) const {
    if (layout == TableLayout::HalfDiff) return axis == 2 ? kMaxHalfDiffPhi : kMaxHalfDiffTheta;
    return !is_phi_axis(axis) ? kMaxThetaNodes : (is_periodic(axis) ? kMaxAnisoPhiNodes : kMaxIsoPhiNodes);
}

const char* TableGeometry::axis_name(int a) const {
    static const char* iso[] = {"theta_i", "theta_r", "phi", "unused"};
    static const char* aniso[] = {"theta_i", "phi_i", "theta_r", "phi_r"};
    static const char* hd[] = {"theta_h", "theta_d", "phi_d", "unused"};
    if (a < 0 || a > 3) return "axis";
    return layout == TableLayout::Isotropic ? iso[a] : layout == TableLayout::Anisotropic ? aniso[a] : hd[a];
}

uint64_t TableGeometry::cells() const {
    if (folded) return mul_checked(mul_checked(n[0], uint64_t(n[0]) + 1) / 2, n[2]);
    uint64_t c = 1;
    for (int a = 0; a < axes(); ++a) c = mul_checked(c, n[a]);
    return c;
}
uint64_t TableGeometry::values() const { return mul_checked(cells(), uint64_t(channels)); }

void TableGeometry::validate() const {
    auto bad = [](const std::string& m) { throw std::invalid_argument("table geometry: " + m); };
    if (layout != TableLayout::Isotropic && layout != TableLayout::Anisotropic && layout != TableLayout::HalfDiff)
        bad("unknown layout");
    if (channels != 1 && channels != 3) bad("channels must be 1 or 3, not " + std::to_string(channels));
    for (int a = 0; a < axes(); ++a) {
        uint32_t hi = max_nodes(a);
        if (n[a] < 2 || n[a] > hi)
            bad("axis " + std::to_string(a) + " (" + axis_name(a) + ") has " + std::to_string(n[a]) +
                " nodes, range [2, " + std::to_string(hi) + "]");
    }
    if (layout != TableLayout::Anisotropic && n[3] != 1) bad("three-axis tables have n[3] == 1");
    if (folded && layout != TableLayout::Isotropic) bad("only isotropic tables can be reciprocity-folded");
    if (folded && n[0] != n[1]) bad("a folded table needs as many theta_i as theta_r nodes");
}

std::string TableGeometry::describe() const {
    std::ostringstream s;
    if (layout == TableLayout::HalfDiff) {
        s << "half/difference " << n[0] << "x" << n[1] << "x" << n[2] << " (theta_h ((i+1/2)/" << n[0]
          << ")^2 x 90 deg, theta_d " << detail::fmt(step_deg(1), 9) << " deg, phi_d " << detail::fmt(step_deg(2), 9)
          << " deg), " << channels << (channels == 1 ? " channel" : " channels");
        return s.str();
    }
    s << (layout == TableLayout::Isotropic ? "isotropic " : "anisotropic ");
    for (int a = 0; a < axes(); ++a) s << (a ? "x" : "") << n[a];
    s << " (theta " << detail::fmt(step_deg(0), 9) << " deg, phi " << detail::fmt(step_deg(layout == TableLayout::Isotropic ? 2 : 1), 9)
      << " deg), " << channels << (channels == 1 ? " channel" : " channels");
    if (folded) s << ", reciprocity-folded";
    return s.str();
}

// ---------------------------------------------------------------- BrdfTable

BrdfTable::BrdfTable(const TableGeometry& geometry, std::vector<float> values, TableInfo info, Interp interp)
    : geom_(geometry), values_(std::move(values)), info_(std::move(info)), interp_(interp) {
    geom_.validate();
    if (values_.size() != geom_.values())
        throw std::invalid_argument("BrdfTable: " + std::to_string(values_.size()) + " values for " +
                                    geom_.describe() + " (needs " + std::to_string(geom_.values()) + ")");
    for (size_t k = 0; k < values_.size(); ++k)
        if (!valid_value(values_[k]))
            throw std::invalid_argument("BrdfTable: value " + std::to_string(k) + " is " + value_text(values_[k]) +
                                        "; apply a no-data policy first");
    uint64_t s = uint64_t(geom_.channels);
    for (int a = geom_.axes() - 1; a >= 0; --a) {
        stride_[a] = s;
        s *= geom_.n[a];
    }
    for (int a = 0; a < geom_.axes(); ++a) {
        inv_step_[a] = 1.0 / geom_.step_deg(a);
        last_node_[a] = double(geom_.n[a] - 1);
    }
    if (geom_.layout == TableLayout::HalfDiff) {
        init_halfdiff();  // virtual poles and the albedo over the half vector (table_halfdiff.cpp)
        return;
    }
    if (geom_.folded) {
        // Pair (a, b), a <= b, is pair number a n - a (a - 1) / 2 + (b - a) (see offset()).
        const uint64_t n = geom_.n[0], row = uint64_t(geom_.n[2]) * uint64_t(geom_.channels);
        fold_row_.resize(n);
        for (uint64_t a = 0; a < n; ++a) fold_row_[a] = (a * n - a * (a - 1) / 2 - a) * row;
    }
    average_poles();
    compute_albedo();
}

BrdfTable::~BrdfTable() = default;

BrdfTable::BrdfTable(const BrdfTable& o)
    : Brdf(o), geom_(o.geom_), values_(o.values_), info_(o.info_), interp_(o.interp_), albedo_(o.albedo_),
      fold_row_(o.fold_row_) {
    std::copy(o.stride_, o.stride_ + 4, stride_);
    std::copy(o.inv_step_, o.inv_step_ + 4, inv_step_);
}

const TableSampler* BrdfTable::sampler() const {
    if (geom_.layout == TableLayout::Anisotropic) return nullptr;  // the generic mixture
    if (const TableSampler* s = sampler_ready_.load(std::memory_order_acquire)) return s;
    std::call_once(sampler_once_, [this] {
        sampler_ = std::make_unique<const TableSampler>(*this);
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

uint64_t BrdfTable::offset(const uint32_t idx[4]) const {
    if (!geom_.folded) {
        uint64_t o = 0;
        for (int a = 0; a < geom_.axes(); ++a) o += idx[a] * stride_[a];
        return o;
    }
    // Folded: pairs (i <= r) row-major; row i starts after n + (n-1) + ... + (n-i+1) pairs.
    uint64_t i = std::min(idx[0], idx[1]), r = std::max(idx[0], idx[1]), n = geom_.n[0];
    uint64_t pair = i * n - i * (i - 1) / 2 + (r - i);
    return (pair * geom_.n[2] + idx[2]) * uint64_t(geom_.channels);
}

float BrdfTable::node(uint32_t a0, uint32_t a1, uint32_t a2, uint32_t a3, int channel) const {
    uint32_t idx[4] = {a0, a1, a2, geom_.axes() == 4 ? a3 : 0};
    for (int a = 0; a < geom_.axes(); ++a)
        if (idx[a] >= geom_.n[a]) throw std::out_of_range("BrdfTable::node: index out of range");
    if (channel < 0 || channel >= geom_.channels) throw std::out_of_range("BrdfTable::node: channel out of range");
    return values_[offset(idx) + uint64_t(channel)];
}

BrdfTable::AxisPos BrdfTable::locate(int axis, double deg, Interp interp) const {
    const uint32_t n = geom_.n[axis];
    double x;
    if (geom_.is_periodic(axis)) {
        double d = std::fmod(deg, 360.0);
        if (d < 0) d += 360.0;
        x = d * inv_step_[axis];
        if (!(x >= 0) || x >= double(n)) x = 0;  // NaN, or 360 - ulp rounding up to n
        if (interp == Interp::Nearest) {
            uint32_t i = uint32_t(std::floor(x + 0.5)) % n;
            return {i, i, 0.0};
        }
        uint32_t i0 = std::min(uint32_t(x), n - 1);
        return {i0, (i0 + 1) % n, x - double(i0)};
    }
    double d = deg;
    if (geom_.is_phi_axis(axis)) {
        // Isotropic: f is even in phi and 360-periodic, so fold onto [0, 180].
        if (!(d >= 0.0 && d <= 180.0)) {  // the common case [0, 180] needs no folding
            d = std::fmod(std::fabs(d), 360.0);
            if (d > 180.0) d = 360.0 - d;
        }
    }
    x = d * inv_step_[axis];
    const double last = double(n - 1);
    if (!(x > 0)) x = 0;  // also NaN
    if (x > last) x = last;
    if (interp == Interp::Nearest) {
        uint32_t i = uint32_t(std::floor(x + 0.5));
        return {i, i, 0.0};
    }
    uint32_t i0 = std::min(uint32_t(x), n - 2);  // x == last: (n-2, n-1) with weight 1
    return {i0, i0 + 1, x - double(i0)};
}

Rgb BrdfTable::gather(const AxisPos pos[4], Interp interp) const {
    const int A = geom_.axes(), C = geom_.channels;
    uint32_t idx[4] = {0, 0, 0, 0};
    if (interp == Interp::Nearest) {
        for (int a = 0; a < A; ++a) idx[a] = pos[a].i0;
        const float* p = &values_[offset(idx)];
        return C == 1 ? Rgb(p[0]) : Rgb(p[0], p[1], p[2]);
    }
    double acc[3] = {0, 0, 0};
    for (uint32_t corner = 0; corner < (1u << A); ++corner) {
        double w = 1.0;
        for (int a = 0; a < A; ++a) {
            bool hi = (corner >> a) & 1u;
            idx[a] = hi ? pos[a].i1 : pos[a].i0;
            w *= hi ? pos[a].t : 1.0 - pos[a].t;
        }
        if (w == 0.0) continue;  // exact at nodes, and no read of a weightless corner
        const float* p = &values_[offset(idx)];
        for (int c = 0; c < C; ++c) acc[c] += w * double(p[c]);
    }
    return C == 1 ? Rgb(acc[0]) : Rgb(acc[0], acc[1], acc[2]);
}

namespace {
// A position x (in nodes) on an axis of n nodes that is not periodic: clamped to [0, n - 1];
// the nearest node (ties up: x >= 0, so truncating x + 0.5 is floor), or the two nodes around
// it and the weight of the upper one (x == n - 1: (n - 2, n - 1) with weight 1).
inline BrdfTable::AxisPos locate_nodes(double x, uint32_t n, Interp interp) {
    const double last = double(n - 1);
    if (!(x > 0)) x = 0;  // also NaN
    if (x > last) x = last;
    if (interp == Interp::Nearest) {
        const uint32_t i = uint32_t(x + 0.5);
        return {i, i, 0.0};
    }
    const uint32_t i0 = std::min(uint32_t(x), n - 2);
    return {i0, i0 + 1, x - double(i0)};
}
}  // namespace

inline BrdfTable::AxisPos BrdfTable::locate_in_range(int axis, double deg, Interp interp) const {
    return locate_nodes(deg * inv_step_[axis], geom_.n[axis], interp);
}

inline void BrdfTable::rows_iso(const AxisPos& pi, const AxisPos& pr, const AxisPos& pp, Interp interp,
                                IsoRead* rd) const {
    // Row offsets written out, so each row costs a few integer operations.
    const uint64_t C = uint64_t(geom_.channels), n_phi_values = uint64_t(geom_.n[2]) * C;
    const uint64_t n1 = geom_.n[1];
    const float* v = values_.data() + uint64_t(pp.i0) * C;
    const bool folded = geom_.folded;
    const uint64_t* fold_row = fold_row_.data();
    auto row_of = [&](uint64_t i, uint64_t r) {
        if (!folded) return v + (i * n1 + r) * n_phi_values;
        // Folded: pairs (a <= b) row-major; fold_row_[a] + b * n_phi_values is pair (a, b).
        const uint64_t a = i < r ? i : r, b = i < r ? r : i;
        return v + fold_row[a] + b * n_phi_values;
    };
    rd->channels = int(C);
    rd->nearest = interp == Interp::Nearest;
    rd->row[0] = row_of(pi.i0, pr.i0);
    if (rd->nearest) return;
    rd->row[1] = row_of(pi.i1, pr.i0);
    rd->row[2] = row_of(pi.i0, pr.i1);
    rd->row[3] = row_of(pi.i1, pr.i1);
    rd->dphi = uint32_t((pp.i1 - pp.i0) * C);
    rd->t_i = pi.t;
    rd->t_r = pr.t;
    rd->t_phi = pp.t;
}

inline Rgb BrdfTable::gather_iso(const AxisPos& pi, const AxisPos& pr, const AxisPos& pp, Interp interp) const {
    IsoRead rd;
    rows_iso(pi, pr, pp, interp, &rd);
    return read_iso(rd);
}

Rgb BrdfTable::eval_iso(double theta_i, double theta_r, double phi, Interp interp) const {
    if (geom_.layout == TableLayout::Anisotropic) return eval_aniso(theta_i, 0.0, theta_r, phi, interp);
    if (geom_.layout == TableLayout::HalfDiff)
        return f(spherical_direction(theta_r, phi), spherical_direction(theta_i, 0.0), interp);
    double d = phi * kRadToDeg;
    // f is even in phi and 360-periodic: fold onto [0, 180] (the common case needs nothing).
    if (!(d >= 0.0 && d <= 180.0)) {
        d = std::fmod(std::fabs(d), 360.0);
        if (d > 180.0) d = 360.0 - d;
    }
    return gather_iso(locate_in_range(0, theta_i * kRadToDeg, interp), locate_in_range(1, theta_r * kRadToDeg, interp),
                      locate_in_range(2, d, interp), interp);
}

Rgb BrdfTable::eval_iso_cos(double cos_i, double cos_r, double cos_phi, Interp interp) const {
    if (geom_.layout != TableLayout::Isotropic)  // anisotropic (phi_i = 0) and half/difference tables
        return eval_iso(acos_approx(std::clamp(cos_i, 0.0, 1.0)), acos_approx(std::clamp(cos_r, 0.0, 1.0)),
                        acos_approx(std::clamp(cos_phi, -1.0, 1.0)), interp);
    return eval_iso_cos(cos_i, locate_theta_r_cos(cos_r, interp), cos_phi, interp);
}

BrdfTable::AxisPos BrdfTable::locate_theta_r_cos(double cos_r, Interp interp) const {
    return locate_in_range(1, acos_approx(std::clamp(cos_r, 0.0, 1.0)) * kRadToDeg, interp);
}

Rgb BrdfTable::eval_iso_cos(double cos_i, const AxisPos& theta_r, double cos_phi, Interp interp) const {
    IsoRead rd;
    prepare_iso_cos(cos_i, theta_r, cos_phi, interp, &rd);
    return read_iso(rd);
}

void BrdfTable::prepare_iso_cos(double cos_i, const AxisPos& theta_r, double cos_phi, Interp interp, IsoRead* rd) const {
    // acos_approx keeps theta in [0, 90] and phi in [0, 180] deg: no folding needed. Both
    // angles at once (acos_approx2: the two lanes of one SSE2 register, the same bits).
    double theta_i, phi_angle;
    acos_approx2(std::clamp(cos_i, 0.0, 1.0), cos_phi, &theta_i, &phi_angle);
#if defined(__SSE2__)
    if (interp == Interp::Linear) {
        // locate_nodes on both axes at once, the same operations lane by lane: max(x, 0) is 0
        // for NaN too, and min(trunc x, n - 2) = trunc min(x, n - 2).
        const __m128d x = _mm_mul_pd(_mm_mul_pd(_mm_set_pd(phi_angle, theta_i), _mm_set1_pd(kRadToDeg)),
                                     _mm_set_pd(inv_step_[2], inv_step_[0]));
        const __m128d last = _mm_set_pd(last_node_[2], last_node_[0]);
        const __m128d c = _mm_min_pd(_mm_max_pd(x, _mm_setzero_pd()), last);
        const __m128i i0 = _mm_cvttpd_epi32(_mm_min_pd(c, _mm_sub_pd(last, _mm_set1_pd(1.0))));
        const __m128d t = _mm_sub_pd(c, _mm_cvtepi32_pd(i0));
        const uint32_t a = uint32_t(_mm_cvtsi128_si32(i0)), b = uint32_t(_mm_cvtsi128_si32(_mm_srli_si128(i0, 4)));
        rows_iso(AxisPos{a, a + 1, _mm_cvtsd_f64(t)}, theta_r, AxisPos{b, b + 1, _mm_cvtsd_f64(_mm_unpackhi_pd(t, t))},
                 interp, rd);
    } else
#endif
    {
        const AxisPos ti = locate_nodes(theta_i * kRadToDeg * inv_step_[0], geom_.n[0], interp);
        const AxisPos phi = locate_nodes(phi_angle * kRadToDeg * inv_step_[2], geom_.n[2], interp);
        rows_iso(ti, theta_r, phi, interp, rd);
    }
#if defined(__GNUC__)
    // Each row segment (two phi nodes x channels) may cross a cache line: its first and last float.
    const uint32_t last = rd->nearest ? uint32_t(rd->channels - 1) : rd->dphi + uint32_t(rd->channels - 1);
    for (int k = 0; k < (rd->nearest ? 1 : 4); ++k) {
        __builtin_prefetch(rd->row[k]);
        __builtin_prefetch(rd->row[k] + last);
    }
#endif
}

Rgb BrdfTable::eval_aniso(double theta_i, double phi_i, double theta_r, double phi_r, Interp interp) const {
    if (geom_.layout != TableLayout::Anisotropic) return eval_iso(theta_i, theta_r, phi_r - phi_i, interp);
    AxisPos pos[4] = {locate(0, theta_i * kRadToDeg, interp), locate(1, phi_i * kRadToDeg, interp),
                      locate(2, theta_r * kRadToDeg, interp), locate(3, phi_r * kRadToDeg, interp)};
    return gather(pos, interp);
}

Rgb BrdfTable::f(const Vec3& wo, const Vec3& wi, Interp interp) const {
    if (wo.z <= 0 || wi.z <= 0) return Rgb(0.0);
    if (geom_.layout == TableLayout::HalfDiff) return eval_halfdiff_dirs(Vec3(0, 0, 1), wi, wo, interp);
    // atan2 of (sin, cos) keeps full precision near the pole, where acos(z) does not.
    double ti = std::atan2(std::hypot(wi.x, wi.y), wi.z);
    double tr = std::atan2(std::hypot(wo.x, wo.y), wo.z);
    if (geom_.layout == TableLayout::Isotropic) {
        // |phi_r - phi_i| in [0, pi] from the projected directions; atan2(0, 0) = 0 at a pole,
        // where the pole rows make the value independent of phi anyway.
        double phi = std::atan2(std::fabs(wi.x * wo.y - wi.y * wo.x), wi.x * wo.x + wi.y * wo.y);
        return eval_iso(ti, tr, phi, interp);
    }
    return eval_aniso(ti, std::atan2(wi.y, wi.x), tr, std::atan2(wo.y, wo.x), interp);
}

std::string BrdfTable::describe() const {
    std::string d = info_.description.empty() ? std::string("tabulated") : info_.description;
    return "table(" + d + "; " + geom_.describe() + ")";
}

void BrdfTable::average_poles() {
    const int C = geom_.channels;
    uint32_t idx[4] = {0, 0, 0, 0};
    // Replace the row over axis `vary` through `fixed` by its per-channel mean.
    auto average_row = [&](int vary) {
        double sum[3] = {0, 0, 0};
        for (uint32_t k = 0; k < geom_.n[vary]; ++k) {
            idx[vary] = k;
            const float* p = &values_[offset(idx)];
            for (int c = 0; c < C; ++c) sum[c] += p[c];
        }
        for (uint32_t k = 0; k < geom_.n[vary]; ++k) {
            idx[vary] = k;
            float* p = &values_[offset(idx)];
            for (int c = 0; c < C; ++c) p[c] = float(sum[c] / double(geom_.n[vary]));
        }
    };
    if (geom_.layout == TableLayout::Isotropic) {
        // theta_i = 0: phi is undefined -> one value per theta_r; likewise theta_r = 0.
        for (uint32_t r = 0; r < geom_.n[1]; ++r) { idx[0] = 0; idx[1] = r; average_row(2); }
        for (uint32_t i = 0; i < geom_.n[0]; ++i) { idx[0] = i; idx[1] = 0; average_row(2); }
    } else {
        // theta_i = 0: phi_i undefined (f still depends on the absolute phi_r), and vice versa.
        for (uint32_t r = 0; r < geom_.n[2]; ++r)
            for (uint32_t q = 0; q < geom_.n[3]; ++q) { idx[0] = 0; idx[2] = r; idx[3] = q; average_row(1); }
        for (uint32_t i = 0; i < geom_.n[0]; ++i)
            for (uint32_t p = 0; p < geom_.n[1]; ++p) { idx[0] = i; idx[1] = p; idx[2] = 0; average_row(3); }
    }
}

void BrdfTable::compute_albedo() {
    const bool iso = geom_.layout == TableLayout::Isotropic;
    const int ta = iso ? 1 : 2;  // theta_r axis
    // ~1 deg integration cells (never coarser than the table) for isotropic tables; the
    // 4-D tables integrate at the table's own resolution with a floor of 2 / 5 deg.
    const uint32_t nt = iso ? std::max<uint32_t>(geom_.n[1] - 1, 90) : std::max<uint32_t>(geom_.n[2] - 1, 45);
    const uint32_t np = iso ? std::max<uint32_t>(geom_.n[2] - 1, 180) : std::max<uint32_t>(geom_.n[3], 72);
    const double dt = 90.0 / nt, dp = (iso ? 180.0 : 360.0) / np;
    std::vector<AxisPos> tpos(nt), ppos(np);
    std::vector<double> tw(nt);
    for (uint32_t j = 0; j < nt; ++j) {
        double a = j * dt * kDegree, b = (j + 1) * dt * kDegree;
        // Exact integral of cos(t) sin(t) over the band: a constant f integrates exactly.
        tw[j] = 0.5 * (sqr(std::sin(b)) - sqr(std::sin(a)));
        tpos[j] = locate(ta, (j + 0.5) * dt, Interp::Linear);
    }
    for (uint32_t k = 0; k < np; ++k) ppos[k] = locate(iso ? 2 : 3, (k + 0.5) * dp, Interp::Linear);
    // Isotropic: the phi integral over [0, 2pi) is twice the one over [0, pi].
    const double phi_w = dp * kDegree * (iso ? 2.0 : 1.0);

    // The sum over cells of the interpolated table is linear in the nodes: with theta_i at a
    // node, each theta_r node and each phi node collects the weights of the cells that read it
    // (band weight times its interpolation weight), and the albedo is the doubly weighted sum
    // of the stored values: the same integral as evaluating every cell, a cell's worth of work
    // per node instead of per cell (a 1 deg table loads in milliseconds, not a third of a second).
    const int pa = iso ? 2 : 3;  // phi_r axis
    std::vector<double> wt(geom_.n[ta], 0.0), wp(geom_.n[pa], 0.0);
    for (uint32_t j = 0; j < nt; ++j) {
        wt[tpos[j].i0] += tw[j] * (1.0 - tpos[j].t);
        wt[tpos[j].i1] += tw[j] * tpos[j].t;
    }
    for (uint32_t k = 0; k < np; ++k) {
        wp[ppos[k].i0] += 1.0 - ppos[k].t;
        wp[ppos[k].i1] += ppos[k].t;
    }
    const int C = geom_.channels;
    albedo_.assign(geom_.n[0], Rgb(0.0));
    const uint32_t n_phi_i = iso ? 1 : geom_.n[1];
    for (uint32_t i = 0; i < geom_.n[0]; ++i) {
        double total[3] = {0, 0, 0};
        for (uint32_t pi = 0; pi < n_phi_i; ++pi) {
            uint32_t idx[4] = {i, iso ? 0u : pi, 0, 0};
            for (uint32_t r = 0; r < geom_.n[ta]; ++r) {
                if (wt[r] == 0.0) continue;
                idx[ta] = r;
                double band[3] = {0, 0, 0};
                for (uint32_t k = 0; k < geom_.n[pa]; ++k) {
                    if (wp[k] == 0.0) continue;
                    idx[pa] = k;
                    const float* v = &values_[offset(idx)];
                    for (int c = 0; c < C; ++c) band[c] += wp[k] * double(v[c]);
                }
                for (int c = 0; c < C; ++c) total[c] += wt[r] * band[c];
            }
        }
        const Rgb sum = C == 1 ? Rgb(total[0]) : Rgb(total[0], total[1], total[2]);
        albedo_[i] = sum * phi_w / double(n_phi_i);
    }
}

Rgb BrdfTable::directional_albedo(double theta_i) const {
    if (geom_.layout == TableLayout::HalfDiff) {  // nodes every 90/(size-1) deg
        double x = theta_i * kRadToDeg / 90.0 * double(albedo_.size() - 1);
        if (!(x > 0)) x = 0;  // also NaN
        const size_t i = std::min(size_t(x), albedo_.size() - 2);
        const double t = std::min(x - double(i), 1.0);
        return albedo_[i] * (1.0 - t) + albedo_[i + 1] * t;
    }
    AxisPos p = locate(0, theta_i * kRadToDeg, Interp::Linear);
    return albedo_[p.i0] * (1.0 - p.t) + albedo_[p.i1] * p.t;
}

double BrdfTable::albedo_node_deg(size_t k) const {
    if (geom_.layout == TableLayout::HalfDiff) return 90.0 * double(k) / double(albedo_.size() - 1);
    return geom_.axis_deg(0, uint32_t(k));
}

size_t BrdfTable::bytes_used() const {
    return sizeof(*this) + values_.capacity() * sizeof(float) + albedo_.capacity() * sizeof(Rgb) +
           (pole_h_.capacity() + pole_d_.capacity()) * sizeof(float) + fold_row_.capacity() * sizeof(uint64_t) +
           info_.description.capacity();
}

// ---------------------------------------------------------------- grids

TableGrid::TableGrid(const TableGeometry& g, float init) : geom(g) {
    geom.folded = false;
    geom.validate();
    values.assign(geom.values(), init);
}

uint64_t TableGrid::cell(uint32_t a0, uint32_t a1, uint32_t a2, uint32_t a3) const {
    uint64_t c = (uint64_t(a0) * geom.n[1] + a1) * geom.n[2] + a2;
    return geom.layout == TableLayout::Anisotropic ? c * geom.n[3] + a3 : c;
}

uint64_t apply_nodata_policy(TableGrid& grid, NoDataPolicy policy, const std::string& name) {
    const TableGeometry& g = grid.geom;
    const int C = g.channels, A = g.axes();
    std::vector<float>& v = grid.values;
    if (v.size() != g.values()) throw std::invalid_argument("apply_nodata_policy: grid size does not match geometry");
    uint32_t idx[4];
    uint64_t bad_cells = 0, first_bad = UINT64_MAX, outside_bad = 0;
    const bool hd = g.layout == TableLayout::HalfDiff;
    Vec3 wi, wo;
    for (uint64_t cell = 0, cells = g.cells(); cell < cells; ++cell) {
        bool bad = false;
        for (int c = 0; c < C; ++c) {
            float x = v[cell * C + c];
            if (std::isinf(x)) {
                g.unravel(cell, idx);
                throw_table_error(name, (cell * C + c) * 4,
                                  "a finite value or a no-data marker (NaN or < 0) at " + cell_label(g, idx, c),
                                  value_text(x));
            }
            if (!valid_value(x)) bad = true;
        }
        if (!bad) continue;
        if (hd) {  // outside cells are filled under either policy, and not counted
            g.unravel(cell, idx);
            if (!g.halfdiff_node_pair(idx, wi, wo)) {
                ++outside_bad;
                continue;
            }
        }
        ++bad_cells;
        if (first_bad == UINT64_MAX)
            for (int c = 0; c < C && first_bad == UINT64_MAX; ++c)
                if (!valid_value(v[cell * C + c])) first_bad = cell * C + c;
    }
    if (bad_cells + outside_bad == 0) return 0;
    if (policy == NoDataPolicy::Reject && bad_cells > 0) {
        g.unravel(first_bad / C, idx);
        throw_table_error(name, first_bad * 4,
                          "a value >= 0 at " + cell_label(g, idx, int(first_bad % C)) + " (no-data policy: reject)",
                          value_text(v[first_bad]));
    }

    // Fill passes: phi (phi_r) first, then the remaining axes from last to first.
    std::vector<uint8_t> ok(v.size());
    std::vector<double> line;
    std::vector<uint8_t> line_ok, line_filled;
    std::vector<int> scratch;
    uint64_t stride[4];
    {
        uint64_t s = 1;
        for (int a = A - 1; a >= 0; --a) { stride[a] = s; s *= g.n[a]; }
    }
    for (int axis = A - 1; axis >= 0; --axis) {
        bool any_bad = false;
        for (size_t k = 0; k < v.size(); ++k) {
            ok[k] = valid_value(v[k]);
            any_bad |= !ok[k];
        }
        if (!any_bad) break;
        const uint32_t n = g.n[axis];
        line.resize(n);
        line_ok.resize(n);
        line_filled.resize(n);
        const uint64_t inner = stride[axis], outer = g.cells() / (inner * n);
        for (uint64_t o = 0; o < outer; ++o)
            for (uint64_t in = 0; in < inner; ++in) {
                const uint64_t base = o * n * inner + in;
                for (int c = 0; c < C; ++c) {
                    bool need = false;
                    for (uint32_t p = 0; p < n; ++p) {
                        uint64_t k = (base + p * inner) * C + c;
                        line[p] = v[k];
                        line_ok[p] = ok[k];
                        need |= !ok[k];
                    }
                    if (!need) continue;
                    fill_line(line, line_ok, line_filled, g.is_periodic(axis), scratch);
                    for (uint32_t p = 0; p < n; ++p)
                        if (line_filled[p]) v[(base + p * inner) * C + c] = float(line[p]);
                }
            }
    }
    for (size_t k = 0; k < v.size(); ++k)
        if (!valid_value(v[k])) {
            g.unravel(k / C, idx);
            throw_table_error(name, k * 4,
                              "at least one valid value in channel " + std::to_string(k % C) + " to fill " +
                                  cell_label(g, idx, int(k % C)) + " from",
                              "none");
        }
    return bad_cells;
}

ReciprocityStats reciprocity(const TableGrid& grid) { return reciprocity_of(grid.geom, grid.values.data()); }

ReciprocityStats reciprocity(const BrdfTable& table) {
    return reciprocity_of(table.geometry(), table.values().data());
}

std::unique_ptr<BrdfTable> build_table(TableGrid grid, const BuildOptions& opt) {
    TableInfo info;
    info.description = opt.description;
    info.nodata_filled = opt.prior_nodata_filled + apply_nodata_policy(grid, opt.nodata, opt.name);
    TableGeometry g = grid.geom;
    if (!opt.fold) return std::make_unique<BrdfTable>(g, std::move(grid.values), std::move(info), opt.interp);

    if (g.layout != TableLayout::Isotropic || g.n[0] != g.n[1])
        throw std::invalid_argument("fold: only isotropic tables with equal theta_i/theta_r steps can be folded");
    ReciprocityStats rs = reciprocity(grid);
    if (rs.max_abs > 0) {
        if (!info.description.empty()) info.description += "; ";
        info.description += "symmetrised when folded (reciprocity error max " + detail::fmt(rs.max_abs, 9) + " 1/sr, rel " +
                            detail::fmt(rs.max_rel, 9) + ")";
    }
    g.folded = true;
    const uint32_t n = g.n[0], np = g.n[2];
    const int C = g.channels;
    std::vector<float> folded;
    folded.reserve(g.values());
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t r = i; r < n; ++r)
            for (uint32_t p = 0; p < np; ++p)
                for (int c = 0; c < C; ++c) {
                    float a = grid.values[grid.cell(i, r, p) * C + c], b = grid.values[grid.cell(r, i, p) * C + c];
                    folded.push_back(a == b ? a : float(0.5 * (double(a) + double(b))));
                }
    grid.values.clear();
    grid.values.shrink_to_fit();
    return std::make_unique<BrdfTable>(g, std::move(folded), std::move(info), opt.interp);
}

TableGrid unfold(const BrdfTable& table) {
    TableGrid grid(table.geometry());
    const TableGeometry& g = grid.geom;
    const int C = g.channels;
    uint32_t idx[4];
    for (uint64_t cell = 0, cells = g.cells(); cell < cells; ++cell) {
        g.unravel(cell, idx);
        for (int c = 0; c < C; ++c) grid.values[cell * C + c] = table.node(idx[0], idx[1], idx[2], idx[3], c);
    }
    return grid;
}

// The theta node at exactly 90 deg is sampled half a step inside (90 - step/2). Many models
// diverge there like 1/cos (microfacet f = DGF / (4 cos_i cos_o) at the grazing mirror pair:
// 1.4e6 /sr for a TR lobe with m = 0.15) while f cos_i stays finite; a node holding the
// divergent value would make every lookup in the last cell a firefly (f cos = 3000 instead
// of 11 at 89.5 deg). Nothing renders the node itself: POV's weight has cos_i = 0 there.
double TableGeometry::sample_deg(int axis, uint32_t i) const {
    const double deg = axis_deg(axis, i);
    if (layout == TableLayout::HalfDiff) return deg;  // bin centres: no node on the horizon
    const bool theta = !is_phi_axis(axis);
    return theta && i + 1 == n[axis] ? deg - 0.5 * (90.0 / double(n[axis] - 1)) : deg;
}

void TableGeometry::unravel(uint64_t cell, uint32_t idx[4]) const {
    idx[3] = 0;
    for (int a = axes() - 1; a >= 0; --a) {
        idx[a] = uint32_t(cell % n[a]);
        cell /= n[a];
    }
}

TableGrid tabulate(const Brdf& brdf, const TableGeometry& geometry) {
    TableGrid grid(geometry);
    const TableGeometry& g = grid.geom;
    const int C = g.channels;
    const bool iso = g.layout == TableLayout::Isotropic;
    uint32_t idx[4];
    for (uint64_t cell = 0, cells = g.cells(); cell < cells; ++cell) {
        g.unravel(cell, idx);
        Vec3 wi, wo;
        if (g.layout == TableLayout::HalfDiff) {
            if (!g.halfdiff_node_pair(idx, wi, wo)) {  // outside: left for the no-data fill
                for (int c = 0; c < C; ++c) grid.values[cell * C + c] = std::numeric_limits<float>::quiet_NaN();
                continue;
            }
        } else if (iso) {
            wi = spherical_direction(g.sample_deg(0, idx[0]) * kDegree, 0.0);
            wo = spherical_direction(g.sample_deg(1, idx[1]) * kDegree, g.axis_deg(2, idx[2]) * kDegree);
        } else {
            wi = spherical_direction(g.sample_deg(0, idx[0]) * kDegree, g.axis_deg(1, idx[1]) * kDegree);
            wo = spherical_direction(g.sample_deg(2, idx[2]) * kDegree, g.axis_deg(3, idx[3]) * kDegree);
        }
        Rgb v = brdf.f(wo, wi);
        for (int c = 0; c < 3; ++c)
            if (!std::isfinite(v[c]) || v[c] < 0)
                throw std::runtime_error("tabulate: " + brdf.describe() + " returned " + detail::fmt(v[c], 9) + " at " +
                                         cell_label(g, idx, c));
        if (C == 1)
            grid.values[cell] = float(v.average());
        else
            for (int c = 0; c < 3; ++c) grid.values[cell * 3 + c] = float(v[c]);
    }
    return grid;
}

TableGrid resample(const BrdfTable& src, const TableGeometry& geometry, Interp interp) {
    if (src.anisotropic() && geometry.layout != TableLayout::Anisotropic)
        throw std::invalid_argument("resample: an anisotropic table can only be resampled to the anisotropic layout");
    TableGrid grid(geometry);
    const TableGeometry& g = grid.geom;
    const int C = g.channels;
    uint32_t idx[4];
    for (uint64_t cell = 0, cells = g.cells(); cell < cells; ++cell) {
        g.unravel(cell, idx);
        if (g.layout == TableLayout::HalfDiff) {
            Vec3 wi, wo;
            if (!g.halfdiff_node_pair(idx, wi, wo)) {  // outside: left for the no-data fill
                for (int c = 0; c < C; ++c) grid.values[cell * C + c] = std::numeric_limits<float>::quiet_NaN();
                continue;
            }
            Rgb v = src.f(wo, wi, interp);
            if (C == 1)
                grid.values[cell] = float(src.geometry().channels == 1 ? v.r : v.average());
            else
                for (int c = 0; c < 3; ++c) grid.values[cell * 3 + c] = float(v[c]);
            continue;
        }
        Rgb v = g.layout == TableLayout::Isotropic
                    ? src.eval_iso(g.axis_deg(0, idx[0]) * kDegree, g.axis_deg(1, idx[1]) * kDegree,
                                   g.axis_deg(2, idx[2]) * kDegree, interp)
                    : src.eval_aniso(g.axis_deg(0, idx[0]) * kDegree, g.axis_deg(1, idx[1]) * kDegree,
                                     g.axis_deg(2, idx[2]) * kDegree, g.axis_deg(3, idx[3]) * kDegree, interp);
        if (C == 1)
            grid.values[cell] = float(src.geometry().channels == 1 ? v.r : v.average());
        else
            for (int c = 0; c < 3; ++c) grid.values[cell * 3 + c] = float(v[c]);
    }
    return grid;
}

uint64_t simulate_measurement(TableGrid& grid, const MeasurementSim& sim) {
    if (!(sim.noise >= 0) || !(sim.missing >= 0 && sim.missing <= 1))
        throw std::invalid_argument("measurement simulation: noise must be >= 0 and missing in [0, 1]");
    SplitMix64 rng{sim.seed};
    // Multiplicative gaussian noise; a factor below 0 (a > 1/noise sigma event) is clamped,
    // since a gonioreflectometer reports no negative reflectance for a lit sample.
    for (float& x : grid.values) x = float(double(x) * std::max(0.0, 1.0 + sim.noise * normal_deviate(rng)));
    const int C = grid.geom.channels;
    uint64_t missing = 0;
    for (uint64_t cell = 0, cells = grid.geom.cells(); cell < cells; ++cell)
        if (rng.uniform() < sim.missing) {
            for (int c = 0; c < C; ++c) grid.values[cell * C + c] = std::numeric_limits<float>::quiet_NaN();
            ++missing;
        }
    return missing;
}

CheckReport check_table(const BrdfTable& table, const std::vector<double>& theta_i_deg, double albedo_tolerance) {
    CheckReport r;
    r.recip = reciprocity(table);
    for (double t : theta_i_deg) {
        r.theta_i_deg.push_back(t);
        r.albedo.push_back(table.directional_albedo(t * kDegree));
    }
    const auto& nodes = table.albedo_nodes();
    for (uint32_t i = 0; i < nodes.size(); ++i) {
        double m = nodes[i].max_component();
        if (table.geometry().channels == 1) m = nodes[i].r;
        if (m > 1.0 + albedo_tolerance) ++r.albedo_nodes_over_one;
        if (m > r.max_albedo) {
            r.max_albedo = m;
            r.max_albedo_theta_deg = table.albedo_node_deg(i);
        }
    }
    return r;
}

}  // namespace shading
