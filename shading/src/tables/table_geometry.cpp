// TableGeometry: the layouts' axes, node angles, sizes and their checks (table.h).
#include "shading/tables/table.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "shading/core/format.h"

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

}  // namespace

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

}  // namespace shading
