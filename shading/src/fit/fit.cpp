// Fitting analytic models to tables (fit.h): the grid, the error metric, samples, and the
// variable projection with Levenberg-Marquardt and robust reweighting. The families are in
// fit_families.cpp, the cost table in costs.cpp.
#include "shading/fit/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "shading/brdf/model_spec.h"
#include "shading/core/bytes.h"
#include "shading/core/optimize.h"
#include "shading/fit/fit_families.h"

namespace shading {

using fit_detail::Family;
using fit_detail::ScaleMode;
using fit_detail::ShapeParam;
using fit_detail::SpecOut;
using fit_detail::make_family;

namespace {

bool cell_valid(const TableGrid& grid, uint64_t cell) {
    const int C = grid.geom.channels;
    for (int c = 0; c < C; ++c)
        if (!(grid.values[cell * C + c] >= 0)) return false;
    return true;
}

// Model value compared with channel k of a C-channel table.
inline double channel_of(const Rgb& v, int k, int C) { return C == 1 ? v.average() : v[k]; }

double median_of(std::vector<double> v) {
    if (v.empty()) return 0;
    size_t h = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + h, v.end());
    return v[h];
}

double angle_to_mirror(const Vec3& wo, const Vec3& wi) {
    return safe_acos(dot(wo, Vec3{-wi.x, -wi.y, wi.z}));
}

}  // namespace

// ---------------------------------------------------------------- grids

TableGrid load_table_grid(const std::string& path, std::string* description) {
    std::vector<uint8_t> bytes = read_file_bytes(path);
    TableHeader h = parse_table_header(bytes.data(), bytes.size(), path);
    const TableGeometry& g = h.geom;
    const uint8_t* p = bytes.data() + h.payload_offset;
    const uint64_t nv = h.payload_bytes / 4;
    std::vector<float> v(nv);
    for (uint64_t k = 0; k < nv; ++k) {
        float x = bytes::rd_f32(p + 4 * k);
        if (std::isinf(x))
            throw_table_error(path, h.payload_offset + 4 * k, "a finite value", x > 0 ? "inf" : "-inf");
        v[k] = x >= 0 ? x : std::numeric_limits<float>::quiet_NaN();
    }
    TableGrid grid = unfold_payload(g, std::move(v));
    if (description) *description = h.description;
    return grid;
}

TableGrid table_grid(const BrdfTable& table) { return unfold(table); }

void node_directions(const TableGeometry& g, const uint32_t idx[4], Vec3& wo, Vec3& wi) {
    if (g.layout == TableLayout::Isotropic) {
        wi = spherical_direction(g.sample_deg(0, idx[0]) * kDegree, 0.0);
        wo = spherical_direction(g.sample_deg(1, idx[1]) * kDegree, g.axis_deg(2, idx[2]) * kDegree);
    } else {
        wi = spherical_direction(g.sample_deg(0, idx[0]) * kDegree, g.axis_deg(1, idx[1]) * kDegree);
        wo = spherical_direction(g.sample_deg(2, idx[2]) * kDegree, g.axis_deg(3, idx[3]) * kDegree);
    }
}

ErrorStats table_error(const Brdf& model, const TableGrid& grid) {
    const TableGeometry& g = grid.geom;
    const int C = g.channels;
    ErrorStats s;
    double num = 0, den = 0;
    uint32_t idx[4];
    for (uint64_t cell = 0, cells = g.cells(); cell < cells; ++cell) {
        if (!cell_valid(grid, cell)) {
            ++s.nodata_cells;
            continue;
        }
        g.unravel(cell, idx);
        ++s.cells;
        // The weight: cos of the node's own theta_i (0 at the 90 deg node).
        double w = std::cos(g.axis_deg(0, idx[0]) * kDegree);
        if (idx[0] + 1 == g.n[0]) w = 0;
        if (w <= 0) continue;
        Vec3 wo, wi;
        node_directions(g, idx, wo, wi);
        Rgb m = model.f(wo, wi);
        for (int c = 0; c < C; ++c) {
            double t = grid.values[cell * C + c];
            double e = channel_of(m, c, C) - t;
            num += w * e * e;
            den += w * t * t;
        }
    }
    s.rel_rmse = den > 0 ? std::sqrt(num / den) : (num > 0 ? std::numeric_limits<double>::infinity() : 0.0);
    return s;
}

// ---------------------------------------------------------------- samples

FitData fit_samples(const TableGrid& grid, const FitSampling& sp) {
    const TableGeometry& g = grid.geom;
    if (g.layout == TableLayout::HalfDiff)
        throw std::invalid_argument("fit: half/difference tables are not fitted directly; resample first "
                                    "(brdftool resample IN.brdf -o OUT.brdf --layout iso --step 1)");
    FitData d;
    d.channels = g.channels;
    const int C = g.channels;
    auto stride = [&](int axis) {
        return std::max<uint32_t>(1, uint32_t(std::lround(sp.coarse_step_deg / g.step_deg(axis))));
    };
    auto add = [&](uint64_t cell, const uint32_t idx[4], double nodes) {
        if (idx[0] + 1 == g.n[0]) return;  // theta_i = 90: weight 0
        if (!cell_valid(grid, cell)) {
            ++d.nodata_cells;
            return;
        }
        FitSample s;
        node_directions(g, idx, s.wo, s.wi);
        s.weight = std::cos(g.axis_deg(0, idx[0]) * kDegree) * nodes;
        for (int c = 0; c < C; ++c) s.target[c] = grid.values[cell * C + c];
        d.samples.push_back(s);
    };
    if (g.layout == TableLayout::Isotropic) {
        const uint32_t si = stride(0), sr = stride(1), sp2 = stride(2);
        const double cone = sp.peak_cone_deg * kDegree;
        // Theta nodes at or beyond grazing_deg are all kept (each stands for itself): models
        // that diverge at the grazing mirror pair differ most there.
        auto graze = [&](int axis, uint32_t i) { return g.axis_deg(axis, i) >= sp.grazing_deg - 1e-9; };
        for (uint32_t i = 0; i < g.n[0]; ++i) {
            const bool gi = graze(0, i);
            if (!gi && i % si != 0) continue;
            const double wi_nodes = gi ? 1.0 : double(si);
            for (uint32_t r = 0; r < g.n[1]; ++r) {
                const bool gr = graze(1, r);
                for (uint32_t p = 0; p < g.n[2]; ++p) {
                    uint32_t idx[4] = {i, r, p, 0};
                    Vec3 wo, wi;
                    node_directions(g, idx, wo, wi);
                    bool dense = angle_to_mirror(wo, wi) <= cone;
                    bool coarse = (gr || r % sr == 0) && p % sp2 == 0;
                    if (dense)
                        add(grid.cell(i, r, p), idx, wi_nodes);
                    else if (coarse)
                        add(grid.cell(i, r, p), idx, wi_nodes * (gr ? 1.0 : double(sr)) * sp2);
                }
            }
        }
    } else {
        const uint32_t s0 = stride(0), s1 = stride(1), s2 = stride(2), s3 = stride(3);
        for (uint32_t i = 0; i < g.n[0]; i += s0)
            for (uint32_t q = 0; q < g.n[1]; q += s1)
                for (uint32_t r = 0; r < g.n[2]; r += s2)
                    for (uint32_t p = 0; p < g.n[3]; p += s3) {
                        uint32_t idx[4] = {i, q, r, p};
                        add(grid.cell(i, q, r, p), idx, double(s0) * s1 * s2 * s3);
                    }
    }
    return d;
}

Rgb estimate_diffuse(const FitData& d) {
    std::vector<double> v[3];
    for (const FitSample& s : d.samples) {
        if (s.wi.z < std::cos(60 * kDegree) || s.wo.z < std::cos(60 * kDegree)) continue;
        if (angle_to_mirror(s.wo, s.wi) < 60 * kDegree) continue;
        for (int c = 0; c < d.channels; ++c) v[c].push_back(s.target[c]);
    }
    Rgb kd;
    for (int c = 0; c < d.channels; ++c) {
        if (v[c].size() < 10) {  // no off-specular region sampled: a low quantile of everything
            std::vector<double> all;
            for (const FitSample& s : d.samples) all.push_back(s.target[c]);
            if (all.empty()) continue;
            size_t q = all.size() / 10;
            std::nth_element(all.begin(), all.begin() + q, all.end());
            kd[c] = kPi * all[q];
        } else {
            kd[c] = kPi * median_of(v[c]);
        }
    }
    if (d.channels == 1) kd = Rgb(kd.r);
    for (int c = 0; c < 3; ++c) kd[c] = std::clamp(kd[c], 0.0, 1.0);
    return kd;
}

std::string pov_finish_snippet(const std::string& spec) { return "finish { brdf_model { \"" + spec + "\" } }"; }

// The problem the optimiser solves for one family (fit_families.h).
namespace {

// ------------------------------------------------------------ the variable-projection problem

struct Problem {
    const FitData& data;
    const Family& fam;
    std::vector<double> h;  // robust weight per sample x channel
    double norm = 1;        // sqrt(sum w t^2): residuals are relative
    int evaluations = 0;

    Problem(const FitData& d, const Family& f) : data(d), fam(f) {
        h.assign(d.samples.size() * size_t(d.channels), 1.0);
        double den = 0;
        for (const FitSample& s : d.samples)
            for (int c = 0; c < d.channels; ++c) den += s.weight * s.target[c] * s.target[c];
        norm = den > 0 ? std::sqrt(den) : 1.0;
    }
    int C() const { return data.channels; }

    // Bases at every sample (RGB), basis-major.
    std::vector<Rgb> eval_bases(const std::vector<BrdfPtr>& b) {
        ++evaluations;
        const size_t n = data.samples.size();
        std::vector<Rgb> out(b.size() * n);
        for (size_t j = 0; j < b.size(); ++j)
            for (size_t i = 0; i < n; ++i) out[j * n + i] = b[j]->f(data.samples[i].wo, data.samples[i].wi);
        return out;
    }

    // Linear parameters per channel given the bases; kd_fixed (if given) pins kd.
    void solve_linear(const std::vector<Rgb>& S, const Rgb* kd_fixed, Rgb& kd, std::vector<Rgb>& coef) const {
        const size_t n = data.samples.size();
        const int nb = fam.nbases;
        const bool kd_free = fam.has_kd && !kd_fixed;
        const bool scale_free = fam.scale == ScaleMode::Free;
        kd = kd_fixed ? *kd_fixed : Rgb(0.0);
        coef.assign(nb, Rgb(fam.scale == ScaleMode::Free ? 0.0 : 1.0));
        for (int c = 0; c < C(); ++c) {
            const size_t K = (kd_free ? 1 : 0) + (scale_free ? nb : 0);
            if (K == 0) continue;
            Vector ata(K * K, 0.0), atb(K, 0.0), col(K);
            for (size_t i = 0; i < n; ++i) {
                const FitSample& s = data.samples[i];
                double w = s.weight * h[i * C() + c];
                if (w <= 0) continue;
                double y = s.target[c];
                double sumS = 0;
                for (int j = 0; j < nb; ++j) sumS += channel_of(S[j * n + i], c, C());
                size_t k = 0;
                if (fam.scale == ScaleMode::One) y -= sumS;
                if (fam.scale == ScaleMode::OneMinusKd) {
                    y -= sumS;
                    if (kd_free) col[k++] = kInvPi - sumS;
                    else y -= kd[c] * (kInvPi - sumS);
                } else {
                    if (kd_free) col[k++] = kInvPi;
                    else if (fam.has_kd) y -= kd[c] * kInvPi;
                }
                if (scale_free)
                    for (int j = 0; j < nb; ++j) col[k++] = channel_of(S[j * n + i], c, C());
                for (size_t a = 0; a < K; ++a) {
                    atb[a] += w * col[a] * y;
                    for (size_t b = 0; b < K; ++b) ata[a * K + b] += w * col[a] * col[b];
                }
            }
            Vector x = nnls_small(ata, atb, K);
            size_t k = 0;
            if (kd_free) kd[c] = std::min(x[k++], 1.0);
            if (scale_free)
                for (int j = 0; j < nb; ++j) coef[j][c] = x[k++];
        }
        if (C() == 1) {
            kd = Rgb(kd.r);
            for (Rgb& v : coef) v = Rgb(v.r);
        }
        if (fam.scale == ScaleMode::OneMinusKd)
            for (Rgb& v : coef) v = Rgb(1.0) - kd;
    }

    // Model values per sample x channel.
    double model_value(const std::vector<Rgb>& S, size_t i, int c, const Rgb& kd, const std::vector<Rgb>& coef) const {
        const size_t n = data.samples.size();
        double m = fam.has_kd ? kd[c] * kInvPi : 0.0;
        for (int j = 0; j < fam.nbases; ++j) m += coef[j][c] * channel_of(S[j * n + i], c, C());
        return m;
    }

    void residuals(const std::vector<Rgb>& S, const Rgb& kd, const std::vector<Rgb>& coef, Vector& r) const {
        const size_t n = data.samples.size();
        r.resize(n * C());
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < C(); ++c) {
                double w = data.samples[i].weight * h[i * C() + c];
                r[i * C() + c] = std::sqrt(w) * (model_value(S, i, c, kd, coef) - data.samples[i].target[c]) / norm;
            }
    }

    void reweight(const std::vector<Rgb>& S, const Rgb& kd, const std::vector<Rgb>& coef) {
        const size_t n = data.samples.size();
        std::vector<double> at;
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < C(); ++c) at.push_back(std::abs(data.samples[i].target[c]));
        const double tau = 0.05 * median_of(at) + 1e-30;
        std::vector<double> z(n * C());
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < C(); ++c) {
                double t = data.samples[i].target[c];
                z[i * C() + c] = std::abs(model_value(S, i, c, kd, coef) - t) / (std::abs(t) + tau);
            }
        const double scale = 1.4826 * median_of(z);
        // Cauchy weights (redescending: a gross outlier's pull goes to zero).
        for (size_t k = 0; k < z.size(); ++k) h[k] = scale > 0 ? 1.0 / (1.0 + sqr(z[k] / (2.385 * scale))) : 1.0;
    }
};

Vector to_internal(const Family& f, const Vector& x) {
    Vector u(x.size());
    for (size_t j = 0; j < x.size(); ++j) u[j] = f.shape[j].log ? std::log(x[j]) : x[j];
    return u;
}
Vector to_natural(const Family& f, const Vector& u) {
    Vector x(u.size());
    for (size_t j = 0; j < u.size(); ++j)
        x[j] = std::clamp(f.shape[j].log ? std::exp(u[j]) : u[j], f.shape[j].lo, f.shape[j].hi);
    return x;
}

// Weighted E over the samples for a spec (plain weights, no robust factor).
double sample_error(const FitData& d, const Brdf& model) {
    double num = 0, den = 0;
    for (const FitSample& s : d.samples) {
        Rgb m = model.f(s.wo, s.wi);
        for (int c = 0; c < d.channels; ++c) {
            double e = channel_of(m, c, d.channels) - s.target[c];
            num += s.weight * e * e;
            den += s.weight * s.target[c] * s.target[c];
        }
    }
    return den > 0 ? std::sqrt(num / den) : 0.0;
}

// E over the samples without the `trim` fraction of sample x channels with the largest
// relative residual: how a candidate fits the bulk of the data, blind to gross outliers.
double trimmed_sample_error(const FitData& d, const Brdf& model, double trim) {
    struct Term { double z, num, den; };
    std::vector<Term> terms;
    for (const FitSample& s : d.samples) {
        Rgb m = model.f(s.wo, s.wi);
        for (int c = 0; c < d.channels; ++c) {
            double t = s.target[c], e = channel_of(m, c, d.channels) - t;
            terms.push_back({std::abs(e) / (std::abs(t) + 1e-30), s.weight * e * e, s.weight * t * t});
        }
    }
    size_t keep = terms.size() - size_t(trim * double(terms.size()));
    std::nth_element(terms.begin(), terms.begin() + std::min(keep, terms.size() - 1), terms.end(),
                     [](const Term& a, const Term& b) { return a.z < b.z; });
    double num = 0, den = 0;
    for (size_t k = 0; k < keep; ++k) {
        num += terms[k].num;
        den += terms[k].den;
    }
    return den > 0 ? std::sqrt(num / den) : 0.0;
}

}  // namespace

FitResult fit_model(const FitData& data, const std::string& family, const FitOptions& opt) {
    auto t0 = std::chrono::steady_clock::now();
    const Family fam = make_family(family);
    if (data.samples.empty()) throw std::invalid_argument("fit: the table has no sample with data");
    FitResult res;
    res.family = fam.name;
    res.kd_estimate = estimate_diffuse(data);
    Problem pb(data, fam);
    const size_t ns = fam.shape.size();

    // Step 3: scan the starts with kd fixed at the diffuse estimate.
    std::vector<Vector> starts(1, Vector());
    for (const ShapeParam& p : fam.shape) {
        std::vector<Vector> next;
        for (const Vector& s : starts)
            for (double v : p.starts) {
                Vector t = s;
                t.push_back(v);
                next.push_back(t);
            }
        starts.swap(next);
    }
    if (fam.valid_start) starts.erase(std::remove_if(starts.begin(), starts.end(), [&](const Vector& x) { return !fam.valid_start(x); }), starts.end());
    std::vector<std::pair<double, Vector>> scored;
    for (const Vector& x : starts) {
        try {
            std::vector<Rgb> S = pb.eval_bases(fam.bases(x)), coef;
            Rgb kd;
            pb.solve_linear(S, fam.has_kd ? &res.kd_estimate : nullptr, kd, coef);
            Vector r;
            pb.residuals(S, kd, coef, r);
            double cost = 0;
            for (double v : r) cost += v * v;
            scored.push_back({cost, x});
        } catch (const std::invalid_argument&) {
        }
    }
    if (scored.empty()) throw std::runtime_error("fit: no valid start for " + fam.name);
    std::sort(scored.begin(), scored.end(), [](const auto& a, const auto& b) { return a.first < b.first; });

    // Step 4-5 from the best starts.
    double best_err = std::numeric_limits<double>::infinity();
    for (int k = 0; k < std::min<int>(opt.restarts, int(scored.size())); ++k) {
        Vector u = to_internal(fam, scored[k].second);
        Vector lo(ns), hi(ns);
        for (size_t j = 0; j < ns; ++j) {
            lo[j] = fam.shape[j].log ? std::log(fam.shape[j].lo) : fam.shape[j].lo;
            hi[j] = fam.shape[j].log ? std::log(fam.shape[j].hi) : fam.shape[j].hi;
        }
        std::fill(pb.h.begin(), pb.h.end(), 1.0);
        if (opt.irls_rounds > 1) {  // first weights from the scan's solution (kd at its robust estimate)
            std::vector<Rgb> S = pb.eval_bases(fam.bases(scored[k].second)), coef;
            Rgb kd;
            pb.solve_linear(S, fam.has_kd ? &res.kd_estimate : nullptr, kd, coef);
            pb.reweight(S, kd, coef);
        }
        auto rfn = [&](const Vector& uu, Vector& r) {
            Vector x = to_natural(fam, uu);
            std::vector<Rgb> S = pb.eval_bases(fam.bases(x)), coef;
            Rgb kd;
            pb.solve_linear(S, nullptr, kd, coef);
            pb.residuals(S, kd, coef, r);
        };
        LmResult lm;
        lm.x = u;
        LmOptions lo_opt;
        lo_opt.max_iterations = opt.max_iterations;
        lo_opt.ftol = 1e-8;
        lo_opt.xtol = 1e-8;
        lo_opt.fd_step = 1e-5;
        for (int round = 0; round < std::max(1, opt.irls_rounds); ++round) {
            // Later rounds start from the previous solution: fewer iterations suffice.
            lo_opt.max_iterations = round == 0 ? opt.max_iterations : std::max(1, opt.max_iterations / 3);
            if (ns > 0) lm = levenberg_marquardt(rfn, lm.x, lo, hi, lo_opt);
            Vector x = to_natural(fam, lm.x);
            std::vector<Rgb> S = pb.eval_bases(fam.bases(x)), coef;
            Rgb kd;
            pb.solve_linear(S, nullptr, kd, coef);
            if (round + 1 < opt.irls_rounds) pb.reweight(S, kd, coef);
        }
        // The robust solution, and plain least squares from it: Cauchy weights also mute the
        // large residuals of a family that cannot follow the data (misfit, not outliers), so
        // the candidate that fits the bulk better (trimmed error: the 1 % worst residuals
        // left out) is kept.
        std::vector<std::pair<LmResult, SpecOut>> cands;
        auto spec_of = [&](const LmResult& l) {
            Vector x = to_natural(fam, l.x);
            std::vector<Rgb> S = pb.eval_bases(fam.bases(x)), coef;
            Rgb kd;
            pb.solve_linear(S, nullptr, kd, coef);
            return fam.spec(x, kd, coef);
        };
        cands.push_back({lm, spec_of(lm)});
        if (opt.irls_rounds > 1) {
            std::fill(pb.h.begin(), pb.h.end(), 1.0);
            LmResult plain = lm;
            lo_opt.max_iterations = opt.max_iterations;
            if (ns > 0) plain = levenberg_marquardt(rfn, u, lo, hi, lo_opt);  // from the scan's start
            cands.push_back({plain, spec_of(plain)});
        }
        // Plain least squares unless the robust fit follows the bulk of the data clearly
        // better (trimmed error below half of plain's): outliers were present.
        size_t pick = 0;
        if (cands.size() == 2) {
            double tr_robust = trimmed_sample_error(data, *make_brdf(cands[0].second.spec), 0.01);
            double tr_plain = trimmed_sample_error(data, *make_brdf(cands[1].second.spec), 0.01);
            pick = tr_robust < 0.5 * tr_plain ? 0 : 1;
        }
        lm = cands[pick].first;
        const Vector x = to_natural(fam, lm.x);
        SpecOut so = cands[pick].second;
        BrdfPtr model = make_brdf(so.spec);
        // Restarts compete on the plain error when plain fits were kept, on the trimmed one
        // when the robust fit was (outliers would dominate the plain error).
        double err = pick == 0 && cands.size() == 2 ? trimmed_sample_error(data, *model, 0.01) : sample_error(data, *model);
        if (err < best_err) {
            best_err = err;
            res.spec = so.spec;
            res.energy_clamped = so.clamped;
            res.sample_error = sample_error(data, *model);
            res.params.clear();
            // Standard errors of the shape parameters: Gauss-Newton covariance x residual variance.
            const double dof = double(data.samples.size() * data.channels) - double(ns) -
                               double(fam.nbases * 3 + (fam.has_kd ? 3 : 0));
            const double var = dof > 0 ? 2.0 * lm.cost / dof : 0.0;
            for (size_t j = 0; j < ns; ++j) {
                double su = lm.jtj_inverse.empty() ? -1 : std::sqrt(std::max(0.0, lm.jtj_inverse[j * ns + j] * var));
                if (su > 0 && fam.shape[j].log) su *= x[j];
                res.params.push_back({fam.shape[j].name, x[j], ns ? su : -1});
            }
            for (const FitParam& p : so.linear) res.params.push_back(p);
        }
    }
    res.evaluations = pb.evaluations;
    res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return res;
}

}  // namespace shading
