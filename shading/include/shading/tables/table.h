// Tabulated BRDFs: an immutable float32 grid that implements Brdf (lookups: table.cpp,
// table_halfdiff.cpp; sampling: table_sampler.h), the tools that build one (from a model, a
// simulated measurement, another table: table_build.cpp) and the `.brdf` file (table_io.cpp).
// brdf_data/README.md specifies the grids, their nodes, folding, the poles and the
// interpolation; in short:
//  * theta axes have n nodes on [0, 90] deg, the last exactly at grazing; lookups clamp theta.
//  * Isotropic: (theta_i, theta_r, phi = phi_r - phi_i), phi on [0, 180] (an isotropic BRDF
//    is even in phi: any phi is folded into that range; 180 is the mirror side).
//  * Anisotropic: (theta_i, phi_i, theta_r, phi_r), azimuths from the tangent, periodic.
//  * Half/difference (narrow lobes, MERL's own grid): (theta_h, theta_d, phi_d) at the centres
//    of MERL's bins, trilinear in (sqrt(theta_h), theta_d, phi_d) with virtual pole nodes
//    (the row means) below the first theta_h and theta_d nodes; reciprocal by construction
//    (phi_d has period 180 deg), never folded. Nearest reads MERL's own bin, so a converted
//    MERL file gives MerlBrdf::f exactly.
//  * Storage: row-major over the axes, channel fastest; a folded isotropic table stores the
//    pairs theta_i <= theta_r only (a lookup of i > r reads (r, i)).
//  * The pole: BrdfTable's constructor replaces each theta = 0 row by its mean over the
//    undefined azimuth, so a lookup there never depends on the caller's frame.
//
// f(wo, wi) excludes cos(theta_i) like every Brdf (see vec.h). Tables are immutable after
// construction: lookups are const, lock-free and safe from any number of threads.
#pragma once

#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace shading {

class TableSampler;  // table_sampler.h

#if defined(__SSE2__)
namespace detail {
// Two consecutive floats (a node's channels 0 and 1) as a pair of doubles, by movq + cvtps2pd:
// _mm_loadl_epi64 reads through an unaligned, may-alias type (table floats are only 4-byte
// aligned). The renderer's table reads (read_iso, read_halfdiff) take channels 0 and 1 so.
inline __m128d load_float_pair(const float* p) {
    return _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p))));
}
}  // namespace detail
#endif

namespace detail {
// The renderer's table read, both layouts: four rows r[k] of a table, each linear between
// two nodes of its periodic/last axis (a[k] and second(k), t_phi), then bilinear as
// lerp(lerp(r0, r1, t_in), lerp(r2, r3, t_in), t_out), each lerp a + t (b - a): about half
// the arithmetic of eight weighted corners, and a short dependency chain. t = 0 returns a
// node exactly; t = 1 returns it to within the rounding of b - a (exact unless the two values
// differ by 2^29 or more). C channels (1 or 3); nearest: the node at a[0] alone.
template <class Second>
inline Rgb read_four_rows(const float* const a[4], Second second, double t_phi, double t_in, double t_out, int C,
                          bool nearest) {
    if (nearest) return C == 1 ? Rgb(a[0][0]) : Rgb(a[0][0], a[0][1], a[0][2]);
    auto lerp = [](double x, double y, double t) { return x + t * (y - x); };
    auto channel = [&](int c) {
        double r[4];
        for (int k = 0; k < 4; ++k) r[k] = lerp(double(a[k][c]), double(second(k)[c]), t_phi);
        return lerp(lerp(r[0], r[1], t_in), lerp(r[2], r[3], t_in), t_out);
    };
    if (C == 1) return Rgb(channel(0));
#if defined(__SSE2__)
    // Channels 0 and 1 as a pair of doubles: the same operations in the same order, so the
    // same bits.
    auto lerp2 = [](__m128d x, __m128d y, __m128d t) { return _mm_add_pd(x, _mm_mul_pd(t, _mm_sub_pd(y, x))); };
    const __m128d tp = _mm_set1_pd(t_phi), ti = _mm_set1_pd(t_in), to = _mm_set1_pd(t_out);
    __m128d r[4];
    for (int k = 0; k < 4; ++k) r[k] = lerp2(load_float_pair(a[k]), load_float_pair(second(k)), tp);
    const __m128d rg = lerp2(lerp2(r[0], r[1], ti), lerp2(r[2], r[3], ti), to);
    return Rgb(_mm_cvtsd_f64(rg), _mm_cvtsd_f64(_mm_unpackhi_pd(rg, rg)), channel(2));
#else
    return Rgb(channel(0), channel(1), channel(2));
#endif
}
}  // namespace detail

// Every loader/validation failure. Messages read "NAME: offset N: expected X, found Y",
// N being the byte offset in the file (or buffer) where the problem was found.
class TableError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};
[[noreturn]] void throw_table_error(const std::string& name, uint64_t offset, const std::string& expected,
                                    const std::string& found);

// A value a table may hold: finite and >= 0 (NaN and negative cells of a grid are "no data").
inline bool valid_table_value(float v) { return std::isfinite(v) && v >= 0.0f; }

enum class TableLayout : uint32_t { Isotropic = 1, Anisotropic = 2, HalfDiff = 3 };
// Linear = trilinear (isotropic) / quadrilinear (anisotropic) in the angles, phi periodic
// where the axis is periodic. Nearest = the nearest node (ties to the larger index).
enum class Interp { Nearest, Linear };
// What to do with "no data" cells (NaN or negative values in measured data).
//   Reject: error naming the first such cell.
//   Fill:   per channel, along phi (phi_r for anisotropic) first: linear interpolation
//           between the nearest valid nodes on each side of the same row (or a copy of
//           the one valid side); rows with no valid node are then filled the same way
//           along theta_r, then (anisotropic) phi_i, then theta_i. Each pass only reads
//           values valid before it started, so the result does not depend on cell order.
enum class NoDataPolicy { Reject, Fill };

const char* to_string(Interp);
const char* to_string(NoDataPolicy);
Interp parse_interp(const std::string&);              // "nearest" | "linear" (or "trilinear")
NoDataPolicy parse_nodata_policy(const std::string&);  // "reject" | "fill"

struct TableGeometry {
    TableLayout layout = TableLayout::Isotropic;
    int channels = 3;                   // 1 (grey) or 3 (linear RGB)
    uint32_t n[4] = {91, 91, 181, 1};   // nodes per axis; isotropic: n[3] == 1
    bool folded = false;                // isotropic only; needs n[0] == n[1]

    // step_deg must divide 90 (theta) and 180 (iso phi) / 360 (aniso phi) evenly;
    // throws std::invalid_argument otherwise.
    static TableGeometry isotropic(double step_deg = 1.0, int channels = 3, bool folded = false);
    static TableGeometry anisotropic(double theta_step_deg = 5.0, double phi_step_deg = 5.0, int channels = 3);
    // Half/difference layout with n_h, n_d, n_p nodes (throws std::invalid_argument outside
    // [2, kMaxHalfDiffTheta] / [2, kMaxHalfDiffPhi]). MERL's grid is (90, 90, 180).
    static TableGeometry halfdiff(uint32_t n_h = 256, uint32_t n_d = 128, uint32_t n_p = 32, int channels = 3);

    int axes() const { return layout == TableLayout::Anisotropic ? 4 : 3; }
    bool is_phi_axis(int axis) const;    // iso: axis 2; aniso: axes 1 and 3; halfdiff: axis 2
    bool is_periodic(int axis) const;    // aniso phi axes, halfdiff phi_d
    // Node spacing, degrees. Halfdiff: theta_h axis 90/n0 in sqrt(90 deg * theta_h) (the
    // axis is uniform in sqrt(theta_h)), theta_d 90/n1, phi_d 180/n2.
    double step_deg(int axis) const;
    double axis_deg(int axis, uint32_t index) const;  // angle of a node, degrees
    uint32_t max_nodes(int axis) const;  // the format's limit for the axis
    // Halfdiff only: the node pair (phi_h = 0; wi, wo as merl.h's from_half_diff gives them)
    // and whether both directions are above the horizon (false: an "outside" cell).
    bool halfdiff_node_pair(const uint32_t idx[4], Vec3& wi, Vec3& wo) const;
    // The angle at which a model is sampled for a node (tabulate, and fit's comparison):
    // the node's angle, except the theta node at 90 deg, sampled half a step inside (a
    // model's f can diverge at grazing while f cos stays finite; see table.cpp).
    double sample_deg(int axis, uint32_t index) const;
    // Per-axis node indices of cell `cell` of an unfolded grid (idx[3] = 0 when isotropic).
    void unravel(uint64_t cell, uint32_t idx[4]) const;
    // Angle tuples stored (folded: pairs theta_i <= theta_r only) and float values.
    // Overflow-checked: throws std::overflow_error if the product does not fit 64 bits.
    uint64_t cells() const;
    uint64_t values() const;
    // Throws std::invalid_argument if the geometry is not one the table supports.
    void validate() const;
    std::string describe() const;  // "isotropic 91x91x181 (1 deg), 3 channels, reciprocity-folded"
    const char* axis_name(int axis) const;  // "theta_i", "phi", "theta_h", ...
};

constexpr uint32_t kMaxHalfDiffTheta = 9000;  // theta_h, theta_d nodes (0.01 deg)
constexpr uint32_t kMaxHalfDiffPhi = 18000;   // phi_d nodes

struct TableInfo {
    std::string description;     // free text: where the data came from (shown by `brdftool info`)
    uint64_t nodata_filled = 0;  // cells that had no data at conversion and were filled
};

class BrdfTable final : public Brdf {
public:
    // `values` follows `geometry` (see top of file); every value must be finite and >= 0
    // (std::invalid_argument otherwise: apply a NoDataPolicy before). Averages the pole rows
    // and computes the directional albedo.
    BrdfTable(const TableGeometry& geometry, std::vector<float> values, TableInfo info = {},
              Interp interp = Interp::Linear);
    ~BrdfTable() override;
    // A copy has the same data and builds its own sampler when asked.
    BrdfTable(const BrdfTable& other);
    BrdfTable& operator=(const BrdfTable&) = delete;

    Rgb f(const Vec3& wo, const Vec3& wi) const override { return f(wo, wi, interp_); }
    Rgb f(const Vec3& wo, const Vec3& wi, Interp interp) const;
    bool anisotropic() const override { return geom_.layout == TableLayout::Anisotropic; }
    std::string describe() const override;

    // Importance sampling from the table's own data (TableSampler, every layout: built on the
    // first call and shared by everything that holds the table; sample_glossy/pdf_glossy are
    // the same, a table having no Lambertian base).
    Vec3 sample(const Vec3& wo, double u1, double u2) const override;
    double pdf(const Vec3& wo, const Vec3& wi) const override;
    const TableSampler* sampler() const;
    size_t sampler_bytes() const;          // 0 until the sampler is built

    // Lookups by angle, radians. Isotropic tables: phi = phi_r - phi_i, any real value.
    // Anisotropic tables given (theta_i, theta_r, phi) use phi_i = 0, phi_r = phi.
    Rgb eval_iso(double theta_i, double theta_r, double phi) const { return eval_iso(theta_i, theta_r, phi, interp_); }
    Rgb eval_iso(double theta_i, double theta_r, double phi, Interp interp) const;
    // Any layout; isotropic tables use phi_r - phi_i.
    Rgb eval_aniso(double theta_i, double phi_i, double theta_r, double phi_r, Interp interp) const;
    // Half/difference tables (layout 3; other layouts: std::logic_error). By angle, radians:
    // theta_h, theta_d clamped to [0, pi/2], phi_d any real (period pi).
    Rgb eval_halfdiff(double theta_h, double theta_d, double phi_d, Interp interp) const;
    // From unit vectors in any frame: n the normal, wi towards the light, wo towards the
    // viewer, both above the surface (n.wi > 0, n.wo > 0; the caller tests). Four square
    // roots, three atan2_upper (vec.h), no frame: the renderer's per-light path (finish.cpp).
    Rgb eval_halfdiff_dirs(const Vec3& n, const Vec3& wi, const Vec3& wo, Interp interp) const;
    // The same in two steps, as prepare_iso_cos/read_iso: prepare_halfdiff_dirs locates the
    // pair, finds the four (theta_h, theta_d) rows the read needs and prefetches them (their
    // memory latency then overlaps the renderer's shadow test); read_halfdiff interpolates.
    // Same bits as eval_halfdiff_dirs.
    struct HdRead {
        const float* a[4] = {nullptr, nullptr, nullptr, nullptr};  // rows (h0,d0) (h0,d1) (h1,d0) (h1,d1) at phi_d node i0
        const float* b[4] = {nullptr, nullptr, nullptr, nullptr};  // the same rows at phi_d node i1
        double t_h = 0, t_d = 0, t_phi = 0;  // weights of the second node on each axis
        int channels = 3;
        bool nearest = false;  // a[0] alone
    };
    void prepare_halfdiff_dirs(const Vec3& n, const Vec3& wi, const Vec3& wo, Interp interp, HdRead* rd) const {
        prepare_halfdiff_dirs(n, wi, wo, dot(n, wi), dot(n, wo), interp, rd);
    }
    // The same with cos_i = dot(n, wi) and cos_o = dot(n, wo) as the caller computed them.
    void prepare_halfdiff_dirs(const Vec3& n, const Vec3& wi, const Vec3& wo, double cos_i, double cos_o, Interp interp,
                               HdRead* rd) const;
    // Rows (h0,d0) (h0,d1) (h1,d0) (h1,d1): theta_d inner, theta_h outer (inline, as read_iso).
    static Rgb read_halfdiff(const HdRead& rd) {
        return detail::read_four_rows(
            rd.a, [&](int k) { return rd.b[k]; }, rd.t_phi, rd.t_d, rd.t_h, rd.channels, rd.nearest);
    }
    bool halfdiff() const { return geom_.layout == TableLayout::HalfDiff; }
    // The renderer's per-light lookup (isotropic tables; others fall back to eval_iso): from
    // cos(theta_i), cos(theta_r) and cos(phi), the angles through acos_approx (vec.h, within
    // 8e-11 rad: 5e-9 of a 1 deg cell) instead of libm's acos/atan2. Inputs are clamped to
    // [0, 1] / [-1, 1]; NaN reads as 90 deg.
    Rgb eval_iso_cos(double cos_i, double cos_r, double cos_phi, Interp interp) const;
    // The same in two steps, for many lights seen from one viewer: the viewer's place on the
    // theta_r axis once (isotropic tables only), then each light.
    struct AxisPos {
        uint32_t i0 = 0, i1 = 0;
        double t = 0;  // weight of i1
    };
    AxisPos locate_theta_r_cos(double cos_r, Interp interp) const;
    Rgb eval_iso_cos(double cos_i, const AxisPos& theta_r, double cos_phi, Interp interp) const;
    // The same in two steps: prepare_iso_cos locates the light, finds the four rows the
    // read needs and prefetches them (so their memory latency can overlap other work, such
    // as the renderer's shadow test); read_iso interpolates. Same bits as eval_iso_cos.
    struct IsoRead {
        const float* row[4] = {nullptr, nullptr, nullptr, nullptr};  // (i0,r0) (i1,r0) (i0,r1) (i1,r1) at phi i0
        uint32_t dphi = 0;        // floats from a row's first phi node to its second
        double t_i = 0, t_r = 0, t_phi = 0;
        int channels = 3;
        bool nearest = false;     // row[0] alone
    };
    void prepare_iso_cos(double cos_i, const AxisPos& theta_r, double cos_phi, Interp interp, IsoRead* read) const;
    // Trilinear by detail::read_four_rows: phi inside each of the four (theta_i, theta_r)
    // rows, then theta_i, then theta_r (inline, so the renderer's call site holds it). The
    // two phi nodes of a row are neighbours in memory.
    static Rgb read_iso(const IsoRead& rd) {
        return detail::read_four_rows(
            rd.row, [&](int k) { return rd.row[k] + rd.dphi; }, rd.t_phi, rd.t_i, rd.t_r, rd.channels, rd.nearest);
    }

    // Stored value at a node, unfolded indices per axis (folded tables swap theta indices).
    float node(uint32_t a0, uint32_t a1, uint32_t a2, uint32_t a3, int channel) const;

    const TableGeometry& geometry() const { return geom_; }
    const TableInfo& info() const { return info_; }
    Interp interpolation() const { return interp_; }
    const std::vector<float>& values() const { return values_; }

    // Directional albedo a(theta_i) = integral over the hemisphere of f cos(theta_r) dw_r,
    // computed at construction on a ~1 deg midpoint grid of the (interpolated) table with
    // exact cos*sin weights per theta_r band (so a constant table integrates exactly), summed
    // as per-node weights times the stored values (the same integral, a node's work instead of
    // a cell's).
    // One entry per theta_i node; anisotropic tables: mean over the phi_i nodes. Half/
    // difference tables have no theta_i axis: entries every 2 deg (albedo_node_deg), each
    // integrated over the half vector (dw_o = 4 cos(theta_d) dw_h) on the table's own
    // sqrt(theta_h) spacing, so a narrow lobe is resolved (table_halfdiff.cpp).
    const std::vector<Rgb>& albedo_nodes() const { return albedo_; }
    double albedo_node_deg(size_t k) const;  // theta_i of albedo_nodes()[k], degrees
    Rgb directional_albedo(double theta_i) const;  // radians; linear between nodes
    size_t bytes_used() const;

private:
    friend class TableSampler;  // reads the stored rows (offset) of the nodes it samples
    AxisPos locate(int axis, double deg, Interp interp) const;
    // locate() of a non-periodic axis (theta, or iso phi) at deg already in its range.
    AxisPos locate_in_range(int axis, double deg, Interp interp) const;
    uint64_t offset(const uint32_t idx[4]) const;  // of channel 0, in floats
    Rgb gather(const AxisPos pos[4], Interp interp) const;
    // Isotropic lookup at positions on the three axes: trilinear by nested linear
    // interpolation (the same function as gather(), within rounding).
    Rgb gather_iso(const AxisPos& ti, const AxisPos& tr, const AxisPos& phi, Interp interp) const;
    void rows_iso(const AxisPos& ti, const AxisPos& tr, const AxisPos& phi, Interp interp, IsoRead* read) const;
    void average_poles();
    void compute_albedo();
    // Half/difference layout (table_halfdiff.cpp).
    struct HdPos {
        int32_t i0, i1;  // i0 == -1: the virtual pole node (theta = 0) of the axis
        double t;        // weight of i1
    };
    HdPos locate_hd(int axis, double x, Interp interp) const;  // x: fractional node index
    void rows_hd(const HdPos pos[3], Interp interp, HdRead* rd) const;
    void rows_hd_interior(const HdPos pos[3], HdRead* rd) const;                // Linear, no pole row
    [[gnu::noinline]] void rows_hd_edge(const HdPos pos[3], Interp interp, HdRead* rd) const;  // the rest
    [[gnu::noinline]] void prepare_hd_nearest(double theta_h, double theta_d, double phi_d, HdRead* rd) const;
    Rgb gather_hd(const HdPos pos[3], Interp interp) const;
    // theta_h, theta_d in [0, pi/2] (clamped), phi_d in [0, pi]: the three axis positions
    void locate_all_hd(double theta_h, double theta_d, double phi_d, Interp interp, HdPos pos[3]) const;
    Rgb hd_lookup(double theta_h, double theta_d, double phi_d, Interp interp) const;
    void init_halfdiff();
    void compute_albedo_halfdiff();

    TableGeometry geom_;
    std::vector<float> values_;
    TableInfo info_;
    Interp interp_;
    std::vector<Rgb> albedo_;
    uint64_t stride_[4] = {0, 0, 0, 0};  // unfolded strides in floats
    double inv_step_[4] = {0, 0, 0, 0};  // nodes per degree
    double last_node_[4] = {0, 0, 0, 0};  // n - 1 per axis, as a double
    // Half/difference layout: mean over phi_d of each theta_h = first-node row (per theta_d
    // node) and of each theta_d = first-node row (per theta_h node), channel fastest: the
    // virtual pole nodes; pole_hd_ both at once (the (0, 0) row's mean).
    std::vector<float> pole_h_, pole_d_;
    float pole_hd_[3] = {0, 0, 0};
    std::vector<uint64_t> fold_row_;  // folded tables: offset of pair (a, a) minus a rows, per a
    mutable std::once_flag sampler_once_;
    // The sampler is built and deleted by table_sampler.cpp: the lookups need nothing of it.
    struct SamplerDeleter {
        void operator()(const TableSampler* s) const;
    };
    mutable std::unique_ptr<const TableSampler, SamplerDeleter> sampler_;
    mutable std::atomic<const TableSampler*> sampler_ready_{nullptr};
};

// ---------------------------------------------------------------- building tables

// A table under construction: always unfolded, may hold no-data values (NaN or < 0).
struct TableGrid {
    TableGeometry geom;
    std::vector<float> values;
    TableGrid() = default;
    explicit TableGrid(const TableGeometry& g, float init = 0.0f);  // g.folded is cleared
    uint64_t cell(uint32_t a0, uint32_t a1, uint32_t a2, uint32_t a3 = 0) const;  // cell index
    float& at(uint32_t a0, uint32_t a1, uint32_t a2, uint32_t a3, int c) {
        return values[cell(a0, a1, a2, a3) * geom.channels + c];
    }
};

struct BuildOptions {
    NoDataPolicy nodata = NoDataPolicy::Fill;
    bool fold = false;  // isotropic only: symmetrise (mean of f(i,r), f(r,i)) and store half
    Interp interp = Interp::Linear;
    std::string name = "table";  // for error messages
    std::string description;
    uint64_t prior_nodata_filled = 0;  // added to the filled count (e.g. from a file header)
};

// Applies the no-data policy in place; returns the number of cells that had no data.
// Reject: TableError "NAME: offset N: ..." where N is the byte offset of the value in the
// unfolded float32 payload. +-Inf is never "no data": always an error.
// Half/difference grids: outside cells (a direction below the horizon) are filled under
// either policy and not counted: they are geometry, not missing measurements.
uint64_t apply_nodata_policy(TableGrid& grid, NoDataPolicy policy, const std::string& name);
// The full grid of a payload laid out as `g` says (a folded payload, theta_i <= theta_r only,
// is mirrored into both halves).
TableGrid unfold_payload(const TableGeometry& g, std::vector<float> values);

// Reciprocity of an unfolded grid over nodes: |f(i,r,...) - f(r,i,...)|.
struct ReciprocityStats {
    bool applicable = false;  // needs matching theta_i/theta_r (and phi_i/phi_r) node counts
    double max_abs = 0, rms_abs = 0;
    double max_rel = 0;  // max_abs / max |f| of the table
    uint32_t worst[4] = {0, 0, 0, 0};
};
ReciprocityStats reciprocity(const TableGrid& grid);
ReciprocityStats reciprocity(const BrdfTable& table);  // folded: exact zero

// Policy, then folding, then the immutable table. Consumes the grid.
std::unique_ptr<BrdfTable> build_table(TableGrid grid, const BuildOptions& opt);

// A folded or unfolded table back to a full grid (folded halves mirrored).
TableGrid unfold(const BrdfTable& table);

// Samples a model at every node: isotropic nodes use wi at azimuth 0 and wo at azimuth phi;
// anisotropic nodes use both absolute azimuths; half/difference nodes use the node pair
// (TableGeometry::halfdiff_node_pair), outside cells are left NaN for the no-data fill.
// One channel stores the RGB mean.
// Non-finite or negative model values throw std::runtime_error naming the node.
TableGrid tabulate(const Brdf& brdf, const TableGeometry& g);

// Evaluates `src` (with `interp`) at the nodes of `g`. Between the isotropic and the
// half/difference layouts in either direction (through the node's direction pair; outside
// half/difference cells are left NaN for the fill); an anisotropic source only to itself.
TableGrid resample(const BrdfTable& src, const TableGeometry& g, Interp interp = Interp::Linear);

// Gonioreflectometer simulation on a tabulated grid, deterministic for a seed:
// each value *= max(0, 1 + noise * N(0,1)) (independent per value), then each cell is
// missing (all channels NaN) with probability `missing`. Returns the missing-cell count.
struct MeasurementSim {
    double noise = 0.02;
    double missing = 0.001;
    uint64_t seed = 1;
};
uint64_t simulate_measurement(TableGrid& grid, const MeasurementSim& sim);

// ---------------------------------------------------------------- checks

struct CheckReport {
    ReciprocityStats recip;
    std::vector<double> theta_i_deg;  // where the albedo below was evaluated
    std::vector<Rgb> albedo;
    uint32_t albedo_nodes_over_one = 0;  // theta_i nodes with a channel albedo > 1 + tol
    double max_albedo = 0, max_albedo_theta_deg = 0;
};
CheckReport check_table(const BrdfTable& table, const std::vector<double>& theta_i_deg,
                        double albedo_tolerance = 1e-3);

// ---------------------------------------------------------------- the .brdf file

constexpr uint32_t kTableVersion = 1;
constexpr size_t kTableFixedHeader = 112;
constexpr uint32_t kFlagFolded = 1u << 0;
constexpr uint32_t kFlagNoDataFilled = 1u << 1;
constexpr uint32_t kUnitsPerSr = 1;
// Largest BRDF value a .brdf file may hold, 1/sr (brdf_data/README.md says why 1e10): far above
// any sharp lobe, a conductor's 1/(4 cos_i cos_o) near grazing included, and low enough that
// every product the renderer forms (pi f cos, the finish's scale <= 1e6, the light's colour,
// sums over lights and albedo integrals) stays far inside float range. Above it: a unit or
// scaling error, or damage.
constexpr double kMaxTableValue = 1e10;

struct TableHeader {
    uint32_t version = 0;
    uint32_t payload_offset = 0;
    uint32_t flags = 0;
    TableGeometry geom;
    uint64_t payload_bytes = 0;
    uint64_t checksum = 0;  // FNV-1a-64 of the payload bytes
    uint64_t nodata_filled = 0;
    std::string description;
};

struct LoadOptions {
    NoDataPolicy nodata = NoDataPolicy::Reject;  // for NaN/negative values in the payload
    Interp interp = Interp::Linear;
    uint64_t max_payload_bytes = uint64_t(2) << 30;  // 2 GiB
};

// Validates the header, the sizes and the checksum of a .brdf image; allocates nothing
// but the description string. Throws TableError.
TableHeader parse_table_header(const uint8_t* data, size_t size, const std::string& name,
                               uint64_t max_payload_bytes = uint64_t(2) << 30);
struct ValueScan {
    uint64_t nan = 0, inf = 0, negative = 0;
    uint64_t first_bad_offset = UINT64_MAX;  // byte offset in the file
};
ValueScan scan_table_values(const uint8_t* data, const TableHeader& header);

// Everything above, then the finiteness/sign rule, then the table. `name` is what error
// messages call the data (POV-Ray passes the file name it opened).
std::unique_ptr<BrdfTable> load_table(const uint8_t* data, size_t size, const std::string& name,
                                      const LoadOptions& opt = {});
std::unique_ptr<BrdfTable> load_table_file(const std::string& path, const LoadOptions& opt = {});
std::vector<uint8_t> encode_table(const BrdfTable& table);
void save_table_file(const BrdfTable& table, const std::string& path);

// Whole-file helpers (TableError naming the path on failure). read_file_bytes reads regular
// files only (a directory is "expected a regular file, found a directory"); write_file_bytes
// writes a temporary file of its own in the same folder, fsyncs it and renames it over `path`
// (every file the library and its tools write goes through it).
std::vector<uint8_t> read_file_bytes(const std::string& path);
// Throws TableError "NAME: offset 0: expected a regular file, found a directory (give the path
// of a file in it, not the folder)" (or what else `path` is) unless it is a regular file: for
// readers that open files by other means (POV-Ray's parser) before they size them.
void require_regular_file(const std::string& path, const std::string& name);
void write_file_bytes(const std::string& path, const std::vector<uint8_t>& bytes);

}  // namespace shading
