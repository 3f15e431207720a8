// Building tables: grids, the no-data policy, folding, reciprocity, tabulating a model,
// resampling another table, the simulated measurement and the checks (table.h "building
// tables", "checks").
#include "shading/tables/table.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "shading/core/format.h"
#include "shading/core/random.h"

namespace shading {

namespace {

// Human-readable node label for error messages.
std::string cell_label(const TableGeometry& g, const uint32_t idx[4], int channel) {
    std::ostringstream s;
    for (int a = 0; a < g.axes(); ++a) s << (a ? " " : "") << g.axis_name(a) << "=" << detail::fmt(g.axis_deg(a, idx[a]), 9);
    s << " deg, channel " << channel;
    return s.str();
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
        if (valid_table_value(v[k])) fmax = std::max(fmax, double(v[k]));
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
            if (!valid_table_value(a) || !valid_table_value(b)) continue;
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
                                  detail::fmt_float(x));
            }
            if (!valid_table_value(x)) bad = true;
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
                if (!valid_table_value(v[cell * C + c])) first_bad = cell * C + c;
    }
    if (bad_cells + outside_bad == 0) return 0;
    if (policy == NoDataPolicy::Reject && bad_cells > 0) {
        g.unravel(first_bad / C, idx);
        throw_table_error(name, first_bad * 4,
                          "a value >= 0 at " + cell_label(g, idx, int(first_bad % C)) + " (no-data policy: reject)",
                          detail::fmt_float(v[first_bad]));
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
            ok[k] = valid_table_value(v[k]);
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
        if (!valid_table_value(v[k])) {
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
