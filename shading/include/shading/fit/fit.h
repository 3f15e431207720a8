// Fitting analytic models to BRDF tables (measured or tabulated), and choosing the cheapest
// model a table needs. docs/fitting.md is the tutorial; the definitions are here.
//
// Error metric (the one every fit reports, "rel-RMSE, cos-weighted"):
//     E = sqrt( sum_{c,k} w_c (m_ck - t_ck)^2 ) / sqrt( sum_{c,k} w_c t_ck^2 ),  w_c = cos(theta_i)
// over every table node c that has data (no-data cells, NaN or negative, are excluded) and
// every stored channel k (a 1-channel table compares with the model's RGB mean), where t is
// the stored value and m the model at the node's directions, sampled exactly as
// `brdftool tabulate` samples them (a theta node at 90 deg is taken half a step inside).
// Nodes at theta_i = 90 deg have weight 0. Folded tables are unfolded first (both halves count).
//
// How a fit works (fit_model):
//  1. Samples: a 5-degree sub-grid of the table's nodes, plus every node within 15 deg of the
//     mirror direction of wi (at the sub-grid's theta_i), plus every theta_i and theta_r node
//     from 80 deg on (where models that diverge at the grazing mirror pair differ most),
//     weighted by cos(theta_i) times the number of table nodes each sample stands for, so the
//     fitted loss estimates the full-grid metric's numerator. Tables coarser than 5 degrees
//     use every node.
//  2. Diffuse first: kd is estimated as pi x the median value (per channel) over samples at
//     least 60 deg from the mirror direction with theta_i, theta_r <= 60 deg.
//  3. Lobe scan: for each start on a grid of the shape parameters (roughness, exponents),
//     the lobe's linear scale is solved with kd fixed to that estimate; the two best starts
//     go on to step 4 (restarts).
//  4. Joint refinement: Levenberg-Marquardt over the shape parameters (log scale where they
//     are scales), with the linear ones (kd and the lobe scales, per channel) solved by
//     non-negative least squares at every evaluation (variable projection).
//  5. Robustness: three rounds of iteratively reweighted least squares. Before each LM run
//     (the first from step 3's solution) every sample x channel gets the Cauchy weight
//     1 / (1 + (z / (2.385 s))^2) of its relative residual z = (m - t)/(|t| + tau),
//     tau = 0.05 x median |t|, s = 1.4826 x median |z| (a robust scale of multiplicative
//     noise), so gross outliers lose their pull. Cauchy weights also mute the large
//     residuals of a family that cannot follow the data (misfit, not outliers), so plain
//     least squares is run from the same start as well. The robust fit is kept only if its
//     trimmed error (E without the 1 % sample x channels of largest relative residual) is
//     below 0.5 x the plain fit's (clear evidence of outliers), else the plain one. Of the
//     restarts, the smaller E wins (the trimmed E where the robust fit was kept).
// The result's spec is printed with 6 significant digits; errors are those of that spec.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"
#include "shading/tables/table.h"

namespace shading {

// A table file as an unfolded grid with its no-data cells kept as NaN (no fill, no pole
// averaging). Validates like the loader (TableError), except that no-data values are allowed.
TableGrid load_table_grid(const std::string& path, std::string* description = nullptr);
// The same from a loaded table (no no-data cells by construction).
TableGrid table_grid(const BrdfTable& table);

// Directions of a grid node, as `tabulate` samples them (grazing nodes half a step inside).
void node_directions(const TableGeometry& g, const uint32_t idx[4], Vec3& wo, Vec3& wi);

struct ErrorStats {
    double rel_rmse = 0;        // E above
    uint64_t cells = 0;         // nodes with data that were compared
    uint64_t nodata_cells = 0;  // nodes excluded
};
// The documented metric of `model` against every valid node of `grid`.
ErrorStats table_error(const Brdf& model, const TableGrid& grid);

struct FitSample {
    Vec3 wo, wi;
    double weight = 0;   // cos(theta_i) x nodes represented
    Rgb target;          // channels beyond the grid's count are unused
};

struct FitSampling {
    double coarse_step_deg = 5;     // sub-grid spacing (rounded to a multiple of the table's step)
    double peak_cone_deg = 15;      // full-resolution cone around the mirror direction
    double grazing_deg = 80;        // theta_i and theta_r nodes from here to 90 deg: all kept
};

struct FitData {
    std::vector<FitSample> samples;
    int channels = 3;
    uint64_t nodata_cells = 0;   // no-data nodes seen while sampling (excluded)
};
FitData fit_samples(const TableGrid& grid, const FitSampling& sampling = {});

struct FitParam {
    std::string name;
    double value = 0;
    double stderr_ = -1;  // one standard error from the Gauss-Newton covariance; < 0: not estimated
};

struct FitOptions {
    int irls_rounds = 3;      // 1 = plain least squares
    int restarts = 2;         // best starts of the lobe scan refined by LM
    int max_iterations = 60;  // per LM run
};

struct FitResult {
    std::string family;          // canonical family name ("microfacet d=tr g=smith f=dielectric")
    std::string spec;            // make_brdf spec of the fit (6 significant digits)
    std::vector<FitParam> params;
    Rgb kd_estimate;             // step 2's diffuse estimate
    double sample_error = 0;     // E over the fit samples (sample weights), of `spec`
    bool energy_clamped = false; // kd + rho_s exceeded 1 and was scaled down to 1
    int evaluations = 0;         // model passes over the samples
    double seconds = 0;
};

// Every family `--model all` fits, canonical names.
std::vector<std::string> fit_families();
// A pattern to families: "all", a canonical name, "microfacet" (every d, g, f), or a partial
// microfacet ("microfacet d=tr", "microfacet f=schlick"), "lafortune" (= lafortune k=1),
// "lafortune k=N". Throws std::invalid_argument for an unknown pattern.
std::vector<std::string> expand_families(const std::string& pattern);

FitResult fit_model(const FitData& data, const std::string& family, const FitOptions& opt = {});

// pi x median over the off-specular samples (step 2 above), per channel.
Rgb estimate_diffuse(const FitData& data);

// `finish { brdf_model { "SPEC" } }`
std::string pov_finish_snippet(const std::string& spec);

// ---------------------------------------------------------------- recommend

// Relative render cost of a model family against POV's stock `phong` (trace-time ratio).
// Keys are family prefixes: "lambert", "oren_nayar", "ward", "lafortune", "microfacet d=X",
// "table" (brdf_table lookups). harness/tools/cost.py measures them; without a file the built-in
// rough order is used: each model's own entries (ModelEntry::costs, model_spec.h) and "table".
struct CostTable {
    std::vector<std::pair<std::string, double>> entries;
    std::string source = "built-in rough order";
    double cost_of(const std::string& family) const;  // longest matching prefix; 1.0 if none
};
CostTable builtin_costs();
// Text file: lines "KEY<whitespace>RATIO", '#' comments. Keys as above (may contain spaces:
// the ratio is the last word; the key's words are joined by one space and must be printable
// ASCII). RATIO is a decimal number ([+]d[.d][e[+-]d]) in [kMinCostRatio, kMaxCostRatio].
// Lines end at '\n'; spaces are ' ', '\t', '\r', '\v', '\f'. harness/tools/cost.py reads the
// same grammar. parse_costs reads the bytes of a file named `name`; both throw TableError
// "NAME: line L, offset B: expected X, found Y. ..." (B: byte offset in the file).
constexpr double kMinCostRatio = 1e-6;
constexpr double kMaxCostRatio = 1e6;
CostTable parse_costs(const std::string& text, const std::string& name);
CostTable load_costs(const std::string& path);

}  // namespace shading
