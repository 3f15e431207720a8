// brdftool: build, convert, inspect, check and fit tabulated BRDFs (.brdf files); polar plots
// are drawn by the harness (python -m harness.tools.brdfplot, console script brdf-plot).
// The logic lives in the shading library (table.h, merl.h); this file is argument
// handling and printing. Exit status: 0 ok, 1 failure (bad data, failed check), 2 usage.
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include "cli_options.h"
#include "eta.h"
#include "shading/brdf/model_spec.h"
#include "shading/finish/finish.h"
#include "shading/fit/fit.h"
#include "shading/tables/merl.h"
#include "shading/tables/table.h"

using namespace shading;

namespace {

using shading_tools::UsageError;

constexpr uint64_t kMaxTableBytes = uint64_t(2) << 30;  // same limit as the loader's default

struct Command {
    const char* name;
    const char* synopsis;
    const char* help;
    std::set<std::string> value_opts;  // options taking a value
    std::set<std::string> flag_opts;   // options without one
    int min_pos, max_pos;              // positional argument count (-1: unbounded)
    std::function<int(struct Args&)> run;
};

struct Args : shading_tools::Options {
    const Command* cmd = nullptr;
    std::set<std::string> flags;

    bool has(const std::string& k) const { return opt.count(k) || flags.count(k); }
    std::string output() const {
        std::string o = str("-o");
        if (o.empty()) throw UsageError("missing -o OUTPUT");
        return o;
    }
};

std::string mb(uint64_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.2f MB", double(bytes) / 1e6);
    return buf;
}

std::string rgb_text(const Rgb& v, int channels) {
    char buf[96];
    if (channels == 1)
        std::snprintf(buf, sizeof buf, "%.4f", v.r);
    else
        std::snprintf(buf, sizeof buf, "%.4f %.4f %.4f", v.r, v.g, v.b);
    return buf;
}

int channels_opt(const Args& a, int def = 3) {
    double c = a.number("--channels", def);
    if (c != 1 && c != 3) throw UsageError("--channels: 1 or 3");
    return int(c);
}

void guard_size(const TableGeometry& g) {
    uint64_t bytes = g.values() * 4;
    if (bytes > kMaxTableBytes)
        throw UsageError("a " + g.describe() + " table would take " + mb(bytes) +
                         " (limit 2 GiB); choose a coarser --step/--phi-step (--nodes for halfdiff)");
}

// The half/difference layout's node counts: --nodes NH,ND,NP (theta_h, theta_d, phi_d).
// The default, 256 x 128 x 32 (12.6 MB in RGB), keeps Beckmann lobes down to m = 0.02 within
// 0.1 % rel-RMSE on the harness's sphere (brdf_data/README.md, "Half/difference layout").
const std::vector<double> kDefaultHalfDiffNodes = {256, 128, 32};

TableGeometry halfdiff_geometry(const Args& a, int channels) {
    if (a.has("--step") || a.has("--phi-step"))
        throw UsageError("--step/--phi-step apply to the iso and aniso layouts; --layout halfdiff takes --nodes NH,ND,NP");
    const std::vector<double> v = a.list("--nodes", kDefaultHalfDiffNodes);
    if (v.size() != 3) throw UsageError("--nodes: three counts NH,ND,NP (theta_h, theta_d, phi_d), e.g. 90,90,180");
    for (double x : v)
        if (!(x >= 2) || x != std::floor(x) || x > kMaxHalfDiffPhi)
            throw UsageError("--nodes: counts are integers >= 2 (theta_h, theta_d <= " + std::to_string(kMaxHalfDiffTheta) +
                             ", phi_d <= " + std::to_string(kMaxHalfDiffPhi) + ")");
    return TableGeometry::halfdiff(uint32_t(v[0]), uint32_t(v[1]), uint32_t(v[2]), channels);
}

TableGeometry geometry_opts(const Args& a, bool anisotropic, double def_step) {
    int ch = channels_opt(a);
    double step = a.number("--step", def_step);
    if (!anisotropic) {
        if (a.has("--phi-step")) throw UsageError("--phi-step applies to --layout aniso only");
        return TableGeometry::isotropic(step, ch);
    }
    return TableGeometry::anisotropic(step, a.number("--phi-step", step), ch);
}

std::string joined_spec(const Args& a) {
    std::string spec;
    for (const auto& p : a.pos) spec += (spec.empty() ? "" : " ") + p;
    return spec;
}

BuildOptions build_opts(const Args& a, const std::string& name, const std::string& description) {
    BuildOptions bo;
    bo.nodata = parse_nodata_policy(a.str("--nodata", "fill"));
    bo.fold = a.has("--fold");
    bo.name = name;
    bo.description = description;
    return bo;
}

void report_written(const BrdfTable& t, const std::string& path) {
    std::cout << path << ": " << t.geometry().describe() << ", " << mb(t.values().size() * 4) << " payload";
    if (t.info().nodata_filled) std::cout << ", " << t.info().nodata_filled << " no-data cells filled";
    std::cout << "\n";
}

// ---------------------------------------------------------------- commands

int cmd_tabulate(Args& a) {
    std::string spec = joined_spec(a);
    BrdfPtr brdf = make_brdf(spec);
    std::string layout = a.str("--layout", brdf->anisotropic() ? "aniso" : "iso");
    if (layout != "iso" && layout != "aniso" && layout != "halfdiff") throw UsageError("--layout: iso, aniso or halfdiff");
    if (layout != "aniso" && brdf->anisotropic())
        throw UsageError("'" + spec + "' is anisotropic: an isotropic table would lose its azimuth (use --layout aniso)");
    if (layout != "halfdiff" && a.has("--nodes")) throw UsageError("--nodes applies to --layout halfdiff only");
    if (layout == "halfdiff" && a.has("--fold"))
        throw UsageError("--fold: a half/difference table is reciprocal by construction");
    TableGeometry g = layout == "halfdiff" ? halfdiff_geometry(a, channels_opt(a))
                                           : geometry_opts(a, layout == "aniso", layout == "aniso" ? 5.0 : 1.0);
    guard_size(g);
    const std::string out = a.output();
    auto table = build_table(tabulate(*brdf, g), build_opts(a, out, "tabulate: " + brdf->describe()));
    save_table_file(*table, out);
    report_written(*table, out);
    return 0;
}

int cmd_measured_like(Args& a) {
    std::string spec = joined_spec(a);
    BrdfPtr brdf = make_brdf(spec);
    if (brdf->anisotropic()) throw UsageError("measured-like: isotropic models only");
    TableGeometry g = geometry_opts(a, false, 1.0);
    guard_size(g);
    MeasurementSim sim;
    sim.noise = a.number("--noise", sim.noise);
    sim.missing = a.number("--missing", sim.missing);
    double seed = a.number("--seed", 1);
    if (seed < 0 || seed != std::floor(seed) || seed > 9007199254740992.0)
        throw UsageError("--seed: a non-negative integer");
    sim.seed = uint64_t(seed);
    const std::string out = a.output();
    TableGrid grid = tabulate(*brdf, g);
    uint64_t missing = simulate_measurement(grid, sim);
    char desc[256];
    std::snprintf(desc, sizeof desc, "measured-like: %s, noise %g, missing %g (%llu cells), seed %llu",
                  brdf->describe().c_str(), sim.noise, sim.missing, static_cast<unsigned long long>(missing),
                  static_cast<unsigned long long>(sim.seed));
    auto table = build_table(std::move(grid), build_opts(a, out, desc));
    save_table_file(*table, out);
    report_written(*table, out);
    return 0;
}

int cmd_convert(Args& a) {
    const std::string layout = a.str("--layout", "iso");
    if (layout != "iso" && layout != "halfdiff") throw UsageError("--layout: iso or halfdiff");
    if (layout == "halfdiff" && (a.has("--step") || a.has("--fold")))
        throw UsageError("--layout halfdiff stores MERL's own bins: no --step, and no --fold (reciprocal by construction)");
    auto merl = MerlBrdf::load_file(a.pos[0]);
    MerlConvertOptions o;
    o.step_deg = a.number("--step", 1.0);
    o.channels = channels_opt(a);
    o.nodata = parse_nodata_policy(a.str("--nodata", "fill"));
    o.fold = a.has("--fold");
    if (layout == "iso") guard_size(TableGeometry::isotropic(o.step_deg, o.channels));
    const std::string out = a.output();
    auto table = layout == "halfdiff" ? merl_to_halfdiff(*merl, o) : merl_to_table(*merl, o);
    save_table_file(*table, out);
    std::cout << merl->describe() << "\n";
    report_written(*table, out);
    return 0;
}

int cmd_fill(Args& a) {
    // The loader's fill policy (brdf_data/README.md, "No data and validation"), then write.
    LoadOptions lo;
    lo.nodata = NoDataPolicy::Fill;
    auto t = load_table_file(a.pos[0], lo);
    const std::string out = a.output();
    TableGrid grid = unfold(*t);
    BuildOptions bo;
    bo.fold = a.has("--fold") || t->geometry().folded;
    bo.name = out;
    bo.description = t->info().description;
    bo.prior_nodata_filled = t->info().nodata_filled;
    auto table = build_table(std::move(grid), bo);
    save_table_file(*table, out);
    report_written(*table, out);
    return 0;
}

int cmd_resample(Args& a) {
    auto src = load_table_file(a.pos[0]);
    const TableGeometry& sg = src->geometry();
    if (a.has("--fold") && a.has("--unfold")) throw UsageError("--fold and --unfold exclude each other");
    TableGeometry g;
    int ch = a.has("--channels") ? channels_opt(a) : sg.channels;
    const std::string src_layout = sg.layout == TableLayout::Isotropic ? "iso"
                                   : sg.layout == TableLayout::Anisotropic ? "aniso" : "halfdiff";
    const std::string layout = a.str("--layout", src_layout);
    if (layout != "iso" && layout != "aniso" && layout != "halfdiff") throw UsageError("--layout: iso, aniso or halfdiff");
    if ((layout == "aniso") != (src_layout == "aniso"))
        throw UsageError("--layout: an anisotropic table resamples to the aniso layout only, and only it does");
    if (layout == "halfdiff") {
        if (a.has("--fold")) throw UsageError("--fold: a half/difference table is reciprocal by construction");
        if (!a.has("--nodes")) throw UsageError("missing --nodes NH,ND,NP (--layout halfdiff)");
        g = halfdiff_geometry(a, ch);
    } else {
        if (a.has("--nodes")) throw UsageError("--nodes applies to --layout halfdiff only");
        if (!a.has("--step")) throw UsageError("missing --step S");
        double step = a.number("--step", 1.0);
        if (layout == "iso") {
            if (a.has("--phi-step")) throw UsageError("--phi-step applies to anisotropic tables only");
            g = TableGeometry::isotropic(step, ch);
        } else {
            g = TableGeometry::anisotropic(step, a.number("--phi-step", step), ch);
        }
    }
    guard_size(g);
    Interp interp = parse_interp(a.str("--interp", "linear"));
    const std::string out = a.output();
    BuildOptions bo;
    bo.fold = layout == "iso" && (a.has("--fold") || (sg.folded && !a.has("--unfold")));
    bo.name = out;
    bo.description = src->info().description + "; resampled (" + to_string(interp) + ") from " + sg.describe();
    bo.prior_nodata_filled = src->info().nodata_filled;
    auto table = build_table(resample(*src, g, interp), bo);
    save_table_file(*table, out);
    report_written(*table, out);
    return 0;
}

void print_albedo(const BrdfTable& t, const std::vector<double>& thetas) {
    std::cout << "directional albedo (integral of f cos over the hemisphere: the fraction of light reflected"
              << (t.geometry().channels == 3 ? "; R G B" : "") << "):\n";
    for (double th : thetas) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "  theta_i=%5.1f: ", th);
        std::cout << buf << rgb_text(t.directional_albedo(th * kPi / 180), t.geometry().channels) << "\n";
    }
}

const std::vector<double> kAlbedoThetas = {0, 15, 30, 45, 60, 75, 85, 89};

// What `info` says about reciprocity (Helmholtz: f must not change when light and view
// swap), with the numbers in words. Folded tables carry the error found when they were
// folded in their description ("reciprocity error max X 1/sr, rel R", build_table's text).
std::string reciprocity_words(const BrdfTable& t) {
    // Measured on measured-like tables with 2 % noise (1 deg): rel 0.13 for a Lambert table,
    // 0.017 for a glossy plastic (the largest value is its peak).
    const std::string normal =
        "             Measured data is never exactly reciprocal, and the largest difference is that of\n"
        "             one pair of cells: noise alone makes it several times the noise of one sample\n"
        "             (2 % noise: rel about 0.02 on a glossy table, 0.13 on a matte one). Much more, or\n"
        "             a large rms, points to misaligned angles or a conversion error (see brdf-plot).\n";
    char buf[512];
    if (t.geometry().folded) {
        const std::string& d = t.info().description;
        double mx = 0, rel = 0;
        auto at = d.find("reciprocity error max ");
        if (at != std::string::npos &&
            std::sscanf(d.c_str() + at, "reciprocity error max %lf 1/sr, rel %lf", &mx, &rel) == 2) {
            std::snprintf(buf, sizeof buf,
                          "reciprocity: exact as stored (folded: one value per pair (theta_i, theta_r), theta_i <= theta_r).\n"
                          "             Before folding, f(theta_i, theta_r, phi) and f(theta_r, theta_i, phi) differed\n"
                          "             by up to %.4g 1/sr, %.3g %% of the table's largest value (the description's\n"
                          "             \"rel %.3g\"); the two were averaged.\n",
                          mx, 100 * rel, rel);
            return buf + normal;
        }
        return "reciprocity: exact as stored (folded: one value per pair (theta_i, theta_r), theta_i <= theta_r).\n";
    }
    ReciprocityStats r = reciprocity(t);
    if (!r.applicable) return "reciprocity: not compared (the theta_i and theta_r grids differ)\n";
    std::snprintf(buf, sizeof buf,
                  "reciprocity: f(theta_i, theta_r, phi) and f(theta_r, theta_i, phi) differ by up to %.4g 1/sr,\n"
                  "             %.3g %% of the table's largest value (rel %.3g); rms %.4g 1/sr.\n",
                  r.max_abs, 100 * r.max_rel, r.max_rel, r.rms_abs);
    return buf + normal;
}

int cmd_info(Args& a) {
    const std::string path = a.pos[0];
    std::vector<uint8_t> bytes = read_file_bytes(path);
    TableHeader h = parse_table_header(bytes.data(), bytes.size(), path);
    ValueScan scan = scan_table_values(bytes.data(), h);
    std::cout << "file:        " << path << "\n"
              << "format:      PVBRDF version " << h.version << ", " << mb(bytes.size()) << ", payload at offset "
              << h.payload_offset << "\n"
              << "geometry:    " << h.geom.describe() << "\n"
              << "units:       1/sr, cos(theta_i) excluded\n";
    char sum[32];
    std::snprintf(sum, sizeof sum, "0x%016llx", static_cast<unsigned long long>(h.checksum));
    std::cout << "checksum:    FNV-1a-64 " << sum << " (verified)\n"
              << "no-data:     " << h.nodata_filled << " cells filled at conversion; payload holds " << scan.nan
              << " NaN, " << scan.inf << " Inf, " << scan.negative << " negative values\n"
              << "description: " << (h.description.empty() ? "(none)" : h.description) << "\n";
    if (scan.inf) return 1;
    LoadOptions lo;
    lo.nodata = NoDataPolicy::Fill;
    auto t = load_table(bytes.data(), bytes.size(), path, lo);
    std::cout << "memory:      " << mb(t->bytes_used()) << " when loaded\n" << reciprocity_words(*t);
    print_albedo(*t, kAlbedoThetas);
    return 0;
}

int cmd_albedo(Args& a) {
    const std::string spec = joined_spec(a);
    std::shared_ptr<FinishModel> m = make_finish_model(make_brdf(spec));
    const bool glossy = a.has("--glossy");
    std::cout << "# " << m->brdf->describe() << "\n# theta_o_deg  albedo r g b" << (glossy ? " (glossy part)" : "")
              << "\n";
    for (double th : a.list("--theta", {0, 15, 30, 45, 60, 75, 85, 89})) {
        if (!(th >= 0 && th <= 90)) throw UsageError("--theta: angles in [0, 90] degrees");
        Rgb v = finish_model_albedo(*m, std::cos(th * kPi / 180));
        if (glossy) v = v - m->base;
        char buf[128];
        std::snprintf(buf, sizeof buf, "%g %.9g %.9g %.9g\n", th, v.r, v.g, v.b);
        std::cout << buf;
    }
    return 0;
}

int cmd_check(Args& a) {
    const std::string path = a.pos[0];
    std::vector<std::string> failures, warnings;
    std::vector<uint8_t> bytes = read_file_bytes(path);
    TableHeader h;
    try {
        h = parse_table_header(bytes.data(), bytes.size(), path);
    } catch (const TableError& e) {
        std::cout << "FAIL " << e.what() << "\n";
        return 1;
    }
    std::cout << path << ": " << h.geom.describe() << "\n";
    ValueScan scan = scan_table_values(bytes.data(), h);
    std::cout << "values: " << scan.nan << " NaN, " << scan.inf << " Inf, " << scan.negative
              << " negative; no-data cells filled at conversion: " << h.nodata_filled << "\n";
    if (scan.inf) {
        std::cout << "FAIL " << scan.inf << " infinite values (first at offset " << scan.first_bad_offset << ")\n";
        return 1;
    }
    if (scan.nan || scan.negative)
        failures.push_back(std::to_string(scan.nan + scan.negative) + " no-data values (NaN or negative) in the payload, first at offset " +
                           std::to_string(scan.first_bad_offset) + " (statistics below use the fill policy)");
    LoadOptions lo;
    lo.nodata = NoDataPolicy::Fill;
    auto t = load_table(bytes.data(), bytes.size(), path, lo);
    const double tol = a.number("--albedo-tol", 1e-3);
    CheckReport r = check_table(*t, a.list("--theta-i", kAlbedoThetas), tol);
    const TableGeometry& g = t->geometry();
    if (g.folded) {
        std::cout << "reciprocity: exact (reciprocity-folded storage)\n";
    } else if (g.layout == TableLayout::HalfDiff) {
        std::cout << "reciprocity: exact (half/difference layout: swapping wi and wo adds 180 deg to phi_d, its period)\n";
    } else if (!r.recip.applicable) {
        std::cout << "reciprocity: not checked (theta_i and theta_r grids differ)\n";
    } else {
        char buf[256];
        std::snprintf(buf, sizeof buf, "reciprocity: |f(i,r) - f(r,i)| max %.4g 1/sr (%.3g%% of max f), rms %.4g 1/sr",
                      r.recip.max_abs, 100 * r.recip.max_rel, r.recip.rms_abs);
        std::cout << buf << "\n";
        if (a.has("--max-recip") && r.recip.max_rel > a.number("--max-recip", 0))
            failures.push_back("reciprocity error " + std::to_string(r.recip.max_rel) + " above --max-recip");
    }
    std::cout << "directional albedo" << (g.channels == 3 ? " (R G B)" : "") << ":\n";
    for (size_t k = 0; k < r.albedo.size(); ++k) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "  theta_i=%5.1f: ", r.theta_i_deg[k]);
        std::cout << buf << rgb_text(r.albedo[k], g.channels) << "\n";
    }
    char buf[160];
    std::snprintf(buf, sizeof buf, "max albedo %.4f at theta_i=%g; theta_i nodes with albedo > 1 + %g: %u of %zu",
                  r.max_albedo, r.max_albedo_theta_deg, tol, r.albedo_nodes_over_one, t->albedo_nodes().size());
    std::cout << buf << "\n";
    if (r.albedo_nodes_over_one) {
        std::string m = std::to_string(r.albedo_nodes_over_one) + " theta_i nodes reflect more energy than they receive";
        (a.has("--allow-energy-gain") ? warnings : failures).push_back(m);
    }
    for (const auto& w : warnings) std::cout << "WARN " << w << "\n";
    for (const auto& f : failures) std::cout << "FAIL " << f << "\n";
    std::cout << (failures.empty() ? "OK\n" : "FAILED\n");
    return failures.empty() ? 0 : 1;
}

// ---------------------------------------------------------------- fit and recommend

struct FamilyFit {
    FitResult fit;
    ErrorStats error;  // of fit.spec over every node with data
    std::string failure;
};

// Progress of a long job on stderr: "brdftool fit: 12/38 families, 23 s elapsed, about
// 41 s left", at least once a second while it runs (families take seconds to a minute
// each, so progress cannot wait for the next one to finish) and once at the end;
// rewritten in place on a terminal, one line each otherwise (logs, pipes). The time left is
// learnt from the families done (eta.h): their measured time per unit of prior cost, applied
// to the costs of the families left, on the threads that run them.
class Progress {
public:
    Progress(std::string what, std::vector<double> prior, int threads, bool enabled)
        : what_(std::move(what)), total_(prior.size()), prior_(std::move(prior)),
          state_(total_, shading_tools::ItemState::Queued), seconds_(total_, 0.0), start_(total_),
          threads_(threads), enabled_(enabled), tty_(isatty(2) != 0), t0_(std::chrono::steady_clock::now()) {}
    void started(size_t k) {
        std::lock_guard<std::mutex> lock(m_);
        state_[k] = shading_tools::ItemState::Running;
        start_[k] = std::chrono::steady_clock::now();
    }
    void done(size_t k) {
        {
            std::lock_guard<std::mutex> lock(m_);
            state_[k] = shading_tools::ItemState::Done;
            seconds_[k] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_[k]).count();
            ++done_;
        }
        cv_.notify_all();
    }
    // Prints until every item is done; the caller's workers call started(k) and done(k).
    void run() {
        std::unique_lock<std::mutex> lock(m_);
        while (done_ < total_) {
            cv_.wait_for(lock, std::chrono::seconds(1), [&] { return done_ >= total_; });
            if (done_ < total_) print(false);
        }
        print(true);
    }

private:
    void print(bool last) {  // with m_ held
        if (!enabled_) return;
        const auto now = std::chrono::steady_clock::now();
        double el = std::chrono::duration<double>(now - t0_).count();
        char buf[256];
        if (last) {
            std::snprintf(buf, sizeof buf, "%s: %zu/%zu families in %.1f s", what_.c_str(), done_, total_, el);
        } else {
            std::vector<double> sec = seconds_;
            for (size_t k = 0; k < total_; ++k)
                if (state_[k] == shading_tools::ItemState::Running)
                    sec[k] = std::chrono::duration<double>(now - start_[k]).count();
            const double left = shading_tools::seconds_left(prior_, state_, sec, threads_);
            if (std::isnan(left))
                std::snprintf(buf, sizeof buf, "%s: %zu/%zu families, %.0f s elapsed, time left: after the first family",
                              what_.c_str(), done_, total_, el);
            else
                std::snprintf(buf, sizeof buf, "%s: %zu/%zu families, %.0f s elapsed, about %.0f s left", what_.c_str(),
                              done_, total_, el, std::ceil(left));
        }
        if (tty_)
            std::fprintf(stderr, "\r%-78s%s", buf, last ? "\n" : "");
        else
            std::fprintf(stderr, "%s\n", buf);
        std::fflush(stderr);
    }
    std::string what_;
    size_t total_, done_ = 0;
    std::vector<double> prior_;
    std::vector<shading_tools::ItemState> state_;
    std::vector<double> seconds_;
    std::vector<std::chrono::steady_clock::time_point> start_;
    int threads_;
    bool enabled_, tty_;
    std::chrono::steady_clock::time_point t0_;
    std::mutex m_;
    std::condition_variable cv_;
};

// What fitting a family costs relative to the others: the prior of the time left (eta.h; the
// seconds per unit are learnt on the run, so only the ratios matter). Measured once: each
// family's own time in one `fit --model all` of the tutorial's 1 deg MERL-like table on two
// threads (2026-12, two cores, 291 s in all): lambert 0.3 s, oren_nayar 0.7, ward 0.9-1.1,
// lafortune k=1 5.4, k=2 19.7; microfacet f=none 2-7, schlick 3-6, dielectric 6-12 and
// conductor 27-50 s, about twice that with the Gaussian D; Smith G 0.7-0.9 of V-cavity.
// Replayed on that run's schedule, the time left stays within 0.75-1.06 of the truth from the
// first family on; elapsed / done x left said 0.15 of it at 5 s and 0.37 at 30 s.
double family_prior_cost(const std::string& family) {
    auto has = [&](const char* w) { return family.find(w) != std::string::npos; };
    if (family.rfind("lambert", 0) == 0) return 0.3;
    if (family.rfind("oren_nayar", 0) == 0) return 0.7;
    if (family.rfind("ward", 0) == 0) return 1.0;
    if (family.rfind("lafortune", 0) == 0) return has("k=1") ? 5.5 : 20;
    if (family.rfind("microfacet", 0) == 0) {
        double c = has("f=conductor") ? 40 : has("f=dielectric") ? 8 : has("f=schlick") ? 5 : 4.5;
        if (has("d=gaussian")) c *= 2;
        if (has("g=smith")) c *= 0.8;
        return c;
    }
    return 5;  // a family added later: about a simple microfacet's
}

// Fits every family (in parallel) and measures each result on the whole grid, with
// progress on stderr unless --quiet.
std::vector<FamilyFit> fit_all(const TableGrid& grid, const std::vector<std::string>& families, const Args& a) {
    FitSampling sp;
    sp.coarse_step_deg = a.number("--coarse", sp.coarse_step_deg);
    sp.peak_cone_deg = a.number("--cone", sp.peak_cone_deg);
    if (!(sp.coarse_step_deg > 0) || !(sp.peak_cone_deg >= 0)) throw UsageError("--coarse > 0 and --cone >= 0 degrees");
    FitOptions fo;
    fo.irls_rounds = int(a.number("--irls", fo.irls_rounds));
    fo.restarts = int(a.number("--restarts", fo.restarts));
    if (fo.irls_rounds < 1 || fo.restarts < 1) throw UsageError("--irls and --restarts: at least 1");
    unsigned hw = std::max(1u, std::thread::hardware_concurrency());
    int nthreads = int(a.number("--threads", double(hw)));
    if (nthreads < 1) throw UsageError("--threads: at least 1");
    const std::string what = std::string("brdftool ") + a.cmd->name;
    const bool talk = !a.has("--quiet");
    const FitData data = fit_samples(grid, sp);
    if (talk)
        std::cerr << what << ": " << data.samples.size() << " fit samples (" << data.nodata_cells
                  << " no-data nodes skipped), " << families.size() << " famil" << (families.size() == 1 ? "y" : "ies")
                  << " on " << std::min<int>(nthreads, int(families.size())) << " thread(s)\n";
    std::vector<FamilyFit> out(families.size());
    std::vector<double> prior;
    for (const auto& f : families) prior.push_back(family_prior_cost(f));
    const int workers = std::min<int>(nthreads, int(families.size()));
    Progress progress(what, prior, workers, talk);
    std::atomic<size_t> next{0};
    auto work = [&]() {
        for (size_t k; (k = next.fetch_add(1)) < families.size();) {
            progress.started(k);
            try {
                out[k].fit = fit_model(data, families[k], fo);
                out[k].error = table_error(*make_brdf(out[k].fit.spec), grid);
            } catch (const std::exception& e) {
                out[k].fit.family = families[k];
                out[k].failure = e.what();
            }
            progress.done(k);
        }
    };
    std::vector<std::thread> pool;
    for (int t = 0; t < workers; ++t) pool.emplace_back(work);
    progress.run();
    for (auto& t : pool) t.join();
    return out;
}

std::string fixed(double v, int prec) {
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", prec, v);
    return b;
}

// "  m                  0.149855 +- 1.1e-05" (one standard error, where estimated)
std::string param_line(const FitParam& p) {
    char buf[128];
    int n = std::snprintf(buf, sizeof buf, "  %-18s %.6g", p.name.c_str(), p.value);
    if (p.stderr_ > 0 && n > 0 && size_t(n) < sizeof buf) std::snprintf(buf + n, sizeof buf - size_t(n), " +- %.2g", p.stderr_);
    return buf;
}

void print_fit(const FamilyFit& f, const TableGrid& grid) {
    std::cout << "family: " << f.fit.family << "\n";
    if (!f.failure.empty()) {
        std::cout << "  FAILED: " << f.failure << "\n";
        return;
    }
    const FitResult& r = f.fit;
    char buf[256];
    std::snprintf(buf, sizeof buf, "  error: %.5f rel-RMSE (cos theta_i weighted) over %llu nodes with data (%llu no-data excluded); %.5f on the fit samples",
                  f.error.rel_rmse, static_cast<unsigned long long>(f.error.cells),
                  static_cast<unsigned long long>(f.error.nodata_cells), r.sample_error);
    std::cout << buf << "\n";
    std::cout << "  diffuse estimate (off-specular median x pi): " << rgb_text(r.kd_estimate, grid.geom.channels) << "\n";
    for (const FitParam& p : r.params) std::cout << param_line(p) << "\n";
    if (r.energy_clamped) std::cout << "  note: kd + rho_s exceeded 1 and was scaled to 1 (energy conservation)\n";
    std::snprintf(buf, sizeof buf, "  fit: %d model passes, %.2f s", r.evaluations, r.seconds);
    std::cout << buf << "\n";
    std::cout << "  spec: " << r.spec << "\n";
    std::cout << "  pov:  " << pov_finish_snippet(r.spec) << "\n";
}

std::vector<size_t> by_error(const std::vector<FamilyFit>& fits) {
    std::vector<size_t> order(fits.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = k;
    auto key = [&](size_t k) { return fits[k].failure.empty() ? fits[k].error.rel_rmse : 1e300; };
    std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) { return key(x) < key(y); });
    return order;
}

std::string percent(double rel) {
    char b[32];
    std::snprintf(b, sizeof b, rel < 0.1 ? "%.1f %%" : "%.0f %%", 100 * rel);
    return b;
}

constexpr size_t kShortList = 10;  // families listed without --details

int cmd_fit(Args& a) {
    const std::string path = a.pos[0];
    TableGrid grid = load_table_grid(path);
    std::vector<std::string> families = expand_families(a.str("--model", "all"));
    std::vector<FamilyFit> fits = fit_all(grid, families, a);
    if (a.has("--tsv")) {
        std::cout << "family\terror\tsample_error\tseconds\tspec\n";
        for (size_t k : by_error(fits))
            std::cout << fits[k].fit.family << "\t" << (fits[k].failure.empty() ? fixed(fits[k].error.rel_rmse, 6) : "nan")
                      << "\t" << fixed(fits[k].fit.sample_error, 6) << "\t" << fixed(fits[k].fit.seconds, 2) << "\t"
                      << fits[k].fit.spec << "\n";
        return 0;
    }
    bool any = false;
    for (const FamilyFit& f : fits) any = any || f.failure.empty();
    // One family: its whole block (parameters, error, spec), the finish line last.
    if (fits.size() == 1) {
        print_fit(fits[0], grid);
        return any ? 0 : 1;
    }
    // Several: the ranking, then the best one's parameters, its finish line last. Every
    // family's block only with --details.
    const bool details = a.has("--details");
    if (details)
        for (const FamilyFit& f : fits) print_fit(f, grid);
    std::cout << (details ? "\n" : "") << "table: " << path << " (" << grid.geom.describe() << ")\n"
              << "families, best first (error: rel-RMSE of f, cos theta_i weighted; 0.02 = 2 %):\n";
    std::vector<size_t> order = by_error(fits);
    size_t shown = 0;
    for (size_t k : order) {
        if (!details && shown == kShortList) break;
        char buf[160];
        std::snprintf(buf, sizeof buf, "  %-42s %s", fits[k].fit.family.c_str(),
                      fits[k].failure.empty()
                          ? (fixed(fits[k].error.rel_rmse, 5) + "  (" + percent(fits[k].error.rel_rmse) + ")").c_str()
                          : ("failed: " + fits[k].failure).c_str());
        std::cout << buf << "\n";
        ++shown;
    }
    if (shown < order.size())
        std::cout << "  ... " << order.size() - shown << " more (--details lists every family with its parameters)\n";
    if (!any) {
        std::cout << "no family could be fitted\n";
        return 1;
    }
    const FamilyFit& best = fits[order[0]];
    std::cout << "\nbest: " << best.fit.family << ", error " << fixed(best.error.rel_rmse, 5) << " ("
              << percent(best.error.rel_rmse) << ")\n";
    for (const FitParam& p : best.fit.params) std::cout << param_line(p) << "\n";
    std::cout << pov_finish_snippet(best.fit.spec) << "\n";
    return 0;
}

// Default cost table: $BRDF_COSTS, else costs.txt in the parent of brdftool's directory
// (build/costs.txt for build/shading/brdftool, where harness/tools/cost.py writes it).
std::string default_costs_path() {
    if (const char* e = std::getenv("BRDF_COSTS")) return e;
    char buf[4096];
    ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
    if (n <= 0) return "";
    std::string exe(buf, size_t(n));
    auto slash = exe.rfind('/');
    if (slash == std::string::npos) return "";
    std::string dir = exe.substr(0, slash);
    slash = dir.rfind('/');
    return (slash == std::string::npos ? std::string(".") : dir.substr(0, slash)) + "/costs.txt";
}

int cmd_recommend(Args& a) {
    const std::string path = a.pos[0];
    const double tol = a.number("--tol", 0.05);
    if (!(tol > 0)) throw UsageError("--tol: a relative error > 0");
    CostTable costs = builtin_costs();
    std::string cpath = a.has("--costs") ? a.str("--costs") : default_costs_path();
    if (a.has("--costs") || (!cpath.empty() && std::ifstream(cpath).good())) {
        CostTable loaded = load_costs(cpath);  // an explicit --costs that is missing is an error
        for (auto& e : loaded.entries) costs.entries.push_back(e);  // later (measured) entries win ties
        costs.source = cpath + " (measured), the built-in rough order for families it lacks";
    } else {
        costs.source = "the built-in rough order (no measured costs: `brdf-cost` writes build/costs.txt)";
    }
    TableGrid grid = load_table_grid(path);
    std::vector<std::string> families = expand_families(a.str("--model", "all"));
    std::vector<FamilyFit> fits = fit_all(grid, families, a);
    const double table_cost = costs.cost_of("table");
    // Cheapest within tolerance; ties by error.
    long choice = -1;
    for (size_t k = 0; k < fits.size(); ++k) {
        if (!fits[k].failure.empty() || !(fits[k].error.rel_rmse <= tol)) continue;
        if (choice < 0) {
            choice = long(k);
            continue;
        }
        double ck = costs.cost_of(fits[k].fit.family), cc = costs.cost_of(fits[size_t(choice)].fit.family);
        if (ck < cc || (ck == cc && fits[k].error.rel_rmse < fits[size_t(choice)].error.rel_rmse)) choice = long(k);
    }
    if (a.has("--tsv")) {
        std::cout << "family\terror\tcost\twithin_tol\tspec\n";
        for (size_t k : by_error(fits)) {
            bool ok = fits[k].failure.empty() && fits[k].error.rel_rmse <= tol;
            std::cout << fits[k].fit.family << "\t" << (fits[k].failure.empty() ? fixed(fits[k].error.rel_rmse, 6) : "nan")
                      << "\t" << fixed(costs.cost_of(fits[k].fit.family), 3) << "\t" << (ok ? "yes" : "no") << "\t"
                      << fits[k].fit.spec << "\n";
        }
        std::cout << "table\t0\t" << fixed(table_cost, 3) << "\tyes\t\n";
        std::cout << "choice\t" << (choice < 0 ? "table" : fits[size_t(choice)].fit.family) << "\t\t\t"
                  << (choice < 0 ? "" : fits[size_t(choice)].fit.spec) << "\n";
        return 0;
    }
    std::cout << "table: " << path << " (" << grid.geom.describe() << ")\n"
              << "cost: trace time relative to stock POV-Ray's phong highlight on the same scene (1.00 = as fast),\n"
              << "      from " << costs.source << "\n"
              << "tolerance: error (rel-RMSE of f, cos theta_i weighted) <= " << tol << " (" << percent(tol) << ")\n\n";
    char buf[256];
    std::snprintf(buf, sizeof buf, "  %-42s %10s %10s  %s", "model", "error", "cost (x)", "within tol");
    std::cout << buf << "\n";
    // Without --details: every family within the tolerance, then the best others up to the
    // short list's length.
    const bool details = a.has("--details");
    std::vector<size_t> order = by_error(fits);
    size_t shown = 0, within = 0;
    for (size_t k : order) within += fits[k].failure.empty() && fits[k].error.rel_rmse <= tol;
    for (size_t k : order) {
        const FamilyFit& f = fits[k];
        bool ok = f.failure.empty() && f.error.rel_rmse <= tol;
        if (!details && !ok && shown >= std::max(kShortList, within)) continue;
        std::snprintf(buf, sizeof buf, "  %-42s %10s %10.2f  %s", f.fit.family.c_str(),
                      f.failure.empty() ? fixed(f.error.rel_rmse, 5).c_str() : "failed", costs.cost_of(f.fit.family),
                      ok ? "yes" : "");
        std::cout << buf << "\n";
        ++shown;
    }
    if (shown < order.size())
        std::cout << "  ... " << order.size() - shown << " more, none within the tolerance (--details lists them)\n";
    std::snprintf(buf, sizeof buf, "  %-42s %10s %10.2f  %s", "(keep the table)", "0", table_cost, "yes");
    std::cout << buf << "\n\n";
    if (choice < 0) {
        std::cout << "choice: keep the table (no model within " << tol << "; the best, " << fits[order[0]].fit.family
                  << ", has error " << (fits[order[0]].failure.empty() ? fixed(fits[order[0]].error.rel_rmse, 5) : "-")
                  << ")\n";
        return 0;
    }
    const FamilyFit& c = fits[size_t(choice)];
    std::snprintf(buf, sizeof buf, "choice: %s (error %.5f = %s, cost %.2f x stock phong; the table costs %.2f x)",
                  c.fit.family.c_str(), c.error.rel_rmse, percent(c.error.rel_rmse).c_str(), costs.cost_of(c.fit.family),
                  table_cost);
    std::cout << buf << "\n  spec: " << c.fit.spec << "\n" << pov_finish_snippet(c.fit.spec) << "\n";
    return 0;
}

std::string models_text() {
    std::string s = "models (from make_brdf):\n";
    try {
        for (const ModelHelp& m : model_help()) {
            s += "  " + m.name + ": " + m.summary + "\n";
            std::stringstream keys(m.keys);
            std::string line;
            while (std::getline(keys, line)) s += "      " + line + "\n";
        }
    } catch (const std::exception& e) {
        s += "  (unavailable: " + std::string(e.what()) + ")\n";
    }
    return s;
}

const std::vector<Command>& commands() {
    static const std::vector<Command> cmds = {
        {"tabulate", "tabulate SPEC... -o OUT.brdf [--step 1] [--fold] [--channels 3] [--layout iso|aniso|halfdiff] [--phi-step S] [--nodes NH,ND,NP]",
         "Sample an analytic model (a make_brdf spec, e.g. 'lambert rho=0.5') at every node.\n"
         "  --step S       node spacing in degrees (divides 90; default 1, anisotropic 5)\n"
         "  --fold         store theta_i <= theta_r only (reciprocity), averaging f(i,r) and f(r,i)\n"
         "  --channels N   1 (mean of R,G,B) or 3\n"
         "  --layout L     iso (default for isotropic models), aniso (4-D, absolute azimuths) or\n"
         "                 halfdiff (theta_h, theta_d, phi_d; nodes dense near the half vector:\n"
         "                 narrow lobes, see brdf_data/README.md)\n"
         "  --phi-step S   azimuth spacing of the anisotropic layout (divides 360; default --step)\n"
         "  --nodes N,N,N  theta_h, theta_d, phi_d node counts of the halfdiff layout\n"
         "                 (default 256,128,32: 12.6 MB in RGB; MERL's grid is 90,90,180)\n",
         {"-o", "--step", "--channels", "--layout", "--phi-step", "--nodata", "--nodes"}, {"--fold"}, 1, -1, cmd_tabulate},
        {"measured-like", "measured-like SPEC... -o OUT.brdf [--noise 0.02] [--missing 0.001] [--seed 1] [--step 1] [--nodata fill|reject] [--fold]",
         "Simulate a gonioreflectometer: the model sampled at every node, each value times\n"
         "max(0, 1 + noise*N(0,1)), each cell missing (no data) with probability --missing,\n"
         "then the no-data policy (fill: from the nearest valid nodes along phi, then theta).\n"
         "Deterministic for a --seed. Measured data is not reciprocal: --fold symmetrises it.\n",
         {"-o", "--step", "--channels", "--noise", "--missing", "--seed", "--nodata"}, {"--fold"}, 1, -1, cmd_measured_like},
        {"convert", "convert IN.binary -o OUT.brdf [--layout iso|halfdiff] [--step 1] [--nodata fill|reject] [--fold] [--channels 3]",
         "Convert a MERL .binary (90x90x180 half/difference bins, scaled 1/1500, 1.15/1500,\n"
         "1.66/1500) to a table.\n"
         "  --layout iso      an isotropic table: the reference bin lookup at every node (default)\n"
         "  --layout halfdiff MERL's own bins stored as the nodes of a half/difference table, no\n"
         "                    resampling (no --step, no --fold); below-horizon bins are filled\n"
         "  --nodata fill    fill nodes whose bin has no data (default)\n"
         "  --nodata reject  fail on the first such node, naming the MERL sample's byte offset\n"
         "  --fold           store theta_i <= theta_r only (lossless: MERL is reciprocal)\n",
         {"-o", "--step", "--channels", "--nodata", "--layout"}, {"--fold"}, 1, 1, cmd_convert},
        {"fill", "fill IN.brdf -o OUT.brdf [--fold]",
         "Fill the no-data cells (NaN or negative values) of a table with the format's rule\n"
         "(linear between the nearest valid nodes along phi, then theta_r, then theta_i; see\n"
         "brdf_data/README.md) and write it; the header counts the cells filled.\n",
         {"-o"}, {"--fold"}, 1, 1, cmd_fill},
        {"resample", "resample IN.brdf -o OUT.brdf (--step S [--phi-step S] | --layout halfdiff --nodes NH,ND,NP) [--layout iso] [--interp linear|nearest] [--fold|--unfold] [--channels N]",
         "Evaluate a table at the nodes of a new grid (the same layout unless --layout: iso and\n"
         "halfdiff convert into each other; aniso stays aniso). Folding is kept unless --unfold;\n"
         "--fold folds an unfolded isotropic table.\n",
         {"-o", "--step", "--phi-step", "--interp", "--channels", "--layout", "--nodes"}, {"--fold", "--unfold"}, 1, 1, cmd_resample},
        {"info", "info FILE.brdf",
         "Print the header (geometry, checksum, description, no-data count), the memory a\n"
         "loaded table takes, and its directional albedo at a few theta_i.\n",
         {}, {}, 1, 1, cmd_info},
        {"albedo", "albedo SPEC... [--theta 0,15,...] [--glossy]",
         "Directional albedo a(theta_o) = integral of f cos over the hemisphere of an analytic\n"
         "model, as finishes use it (46-node quadrature, linear between nodes; phi_o = 0).\n"
         "  --glossy   minus the Lambertian base: what a finish's `samples` rays reflect\n",
         {"--theta"}, {"--glossy"}, 1, -1, cmd_albedo},
        {"check", "check FILE.brdf [--theta-i 0,15,...] [--albedo-tol 1e-3] [--allow-energy-gain] [--max-recip REL]",
         "Validate a table: header and checksum, NaN/Inf/negative values (fail), reciprocity\n"
         "error max/rms (fail above --max-recip, relative to max f), directional albedo at\n"
         "--theta-i, theta_i nodes whose albedo exceeds 1 + tol (fail unless --allow-energy-gain).\n"
         "Exit status 1 on any failure.\n",
         {"--theta-i", "--albedo-tol", "--max-recip"}, {"--allow-energy-gain"}, 1, 1, cmd_check},
        {"fit", "fit TABLE.brdf [--model all|FAMILY] [--details] [--coarse 5] [--cone 15] [--irls 3] [--restarts 2] [--threads N] [--tsv] [--quiet]",
         "Fit analytic models to a table (no-data cells, NaN or negative, are excluded). One family:\n"
         "its parameters, error, spec and a ready POV finish. Several: the best ten by error, the best\n"
         "one's parameters, and its ready `finish { brdf_model { ... } }` as the last line.\n"
         "Progress (families done, time elapsed and left) goes to stderr at least once a second.\n"
         "docs/fitting.md explains the method.\n"
         "  --model M     all (default), lambert, oren_nayar, ward, ward_aniso, lafortune [k=N],\n"
         "                microfacet [d=blinn|gaussian|tr|beckmann] [g=vcavity|smith]\n"
         "                [f=none|dielectric|conductor|schlick] (omitted keys: every choice)\n"
         "  --coarse S    fit-sample sub-grid spacing in degrees (default 5)\n"
         "  --cone A      full-resolution cone around the mirror direction, degrees (default 15)\n"
         "  --irls N      robust reweighting rounds (1 = plain least squares; default 3)\n"
         "  --restarts N  best scan starts refined by Levenberg-Marquardt (default 2)\n"
         "  --threads N   families fitted in parallel (default: the CPU count)\n"
         "  --details     every family's parameters, error and finish, and the whole ranking\n"
         "  --tsv         one line per family: family, error, sample error, seconds, spec\n"
         "  --quiet       no progress on stderr\n"
         "Error: sqrt(sum w (model - table)^2 / sum w table^2), w = cos(theta_i), over every node with\n"
         "data and every channel, the model sampled at the nodes as `tabulate` samples them: a relative\n"
         "error of f (0.02 = 2 %; a table with 2 % noise scores about 0.02 against its own model).\n",
         {"--model", "--coarse", "--cone", "--irls", "--restarts", "--threads"}, {"--tsv", "--quiet", "--details"}, 1, 1, cmd_fit},
        {"recommend", "recommend TABLE.brdf [--tol 0.05] [--costs FILE] [--model all|FAMILY] [--details] [--tsv] [fit options]",
         "Fit the models (as `fit`), rank them by error and render cost, and name the cheapest\n"
         "model whose error is within --tol, or 'keep the table'; the chosen model's ready finish\n"
         "is the last line. Cost unit: trace time relative to stock POV-Ray's `phong` highlight on\n"
         "the same scene (1.00 = as fast, 1.25 = a quarter slower).\n"
         "  --tol E       largest acceptable error (rel-RMSE of f, cos-weighted, as `fit` reports;\n"
         "                default 0.05 = 5 %)\n"
         "  --costs FILE  trace-time ratios vs stock phong, lines 'FAMILY RATIO' (brdf-cost, i.e.\n"
         "                harness/tools/cost.py, writes them). Default: $BRDF_COSTS, else costs.txt in\n"
         "                the parent directory of brdftool's (build/costs.txt); without a file, a\n"
         "                built-in rough order.\n"
         "  --details     every family (default: those within --tol and the best ten)\n"
         "  --tsv         one line per family: family, error, cost, within_tol, spec; then 'table'\n"
         "                and 'choice' lines\n"
         "  --quiet       no progress on stderr\n",
         {"--model", "--coarse", "--cone", "--irls", "--restarts", "--threads", "--tol", "--costs"}, {"--tsv", "--quiet", "--details"}, 1, 1, cmd_recommend},
    };
    return cmds;
}

void print_usage(std::ostream& os) {
    os << "usage: brdftool COMMAND [ARGS]   (brdftool help COMMAND, or brdftool COMMAND --help, for details;\n"
          "                                  brdftool --version; man brdftool)\n\ncommands:\n";
    for (const Command& c : commands()) os << "  " << c.synopsis << "\n";
}

void print_help(const Command& c) {
    std::cout << "usage: brdftool " << c.synopsis << "\n\n" << c.help;
    if (std::string(c.name) == "tabulate" || std::string(c.name) == "measured-like") std::cout << "\n" << models_text();
}

Args parse_args(const Command& c, int argc, char** argv) {
    Args a;
    a.cmd = &c;
    for (int k = 2; k < argc; ++k) {
        std::string s = argv[k];
        if (s.size() > 1 && s[0] == '-' && !(s.size() > 1 && (std::isdigit(static_cast<unsigned char>(s[1])) || s[1] == '.'))) {
            std::string key = s, value;
            bool inline_value = false;
            if (auto eq = s.find('='); eq != std::string::npos && s.rfind("--", 0) == 0) {
                key = s.substr(0, eq);
                value = s.substr(eq + 1);
                inline_value = true;
            }
            if (key == "--output") key = "-o";
            if (c.flag_opts.count(key)) {
                if (inline_value) throw UsageError(key + " takes no value");
                a.flags.insert(key);
            } else if (c.value_opts.count(key)) {
                if (!inline_value) {
                    if (k + 1 >= argc) throw UsageError(key + " needs a value");
                    value = argv[++k];
                }
                a.opt[key] = value;
            } else {
                throw UsageError("unknown option " + key);
            }
        } else {
            a.pos.push_back(s);
        }
    }
    if (int(a.pos.size()) < c.min_pos) throw UsageError("missing argument");
    if (c.max_pos >= 0 && int(a.pos.size()) > c.max_pos) throw UsageError("unexpected argument '" + a.pos.back() + "'");
    return a;
}

const Command* find_command(const std::string& name) {
    for (const Command& c : commands())
        if (name == c.name) return &c;
    return nullptr;
}

}  // namespace

#ifndef POVRAY_BRDF_VERSION
#define POVRAY_BRDF_VERSION "unknown"
#endif

int main(int argc, char** argv) {
    if (argc < 2) {
        print_usage(std::cerr);
        return 2;
    }
    const std::string name = argv[1];
    if (name == "--version" || name == "-V" || name == "version") {
        std::cout << "brdftool (povray-brdf) " << POVRAY_BRDF_VERSION << "\n"
                  << ".brdf format version " << kTableVersion << " (brdf_data/README.md); shading library of the "
                  << "POV-Ray 3.7.0.10 fork povray-brdf\n";
        return 0;
    }
    if (name == "--help" || name == "-h" || name == "help") {
        // `brdftool help CMD` = `brdftool CMD --help`
        if (argc > 2) {
            const Command* c = find_command(argv[2]);
            if (!c) {
                std::cerr << "brdftool help: unknown command '" << argv[2] << "'\n";
                print_usage(std::cerr);
                return 2;
            }
            print_help(*c);
            return 0;
        }
        print_usage(std::cout);
        return 0;
    }
    const Command* cmd = find_command(name);
    if (!cmd) {
        std::cerr << "brdftool: unknown command '" << name << "'\n";
        print_usage(std::cerr);
        return 2;
    }
    for (int k = 2; k < argc; ++k)
        if (std::string(argv[k]) == "--help" || std::string(argv[k]) == "-h") {
            print_help(*cmd);
            return 0;
        }
    try {
        Args a = parse_args(*cmd, argc, argv);
        return cmd->run(a);
    } catch (const UsageError& e) {
        std::cerr << "brdftool " << name << ": " << e.what() << "\nusage: brdftool " << cmd->synopsis << "\n";
        return 2;
    } catch (const std::invalid_argument& e) {  // bad spec, step, policy...
        std::cerr << "brdftool " << name << ": " << e.what() << "\n";
        return 2;
    } catch (const std::exception& e) {  // TableError and other runtime failures
        std::cerr << "brdftool " << name << ": " << e.what() << "\n";
        return 1;
    }
}
