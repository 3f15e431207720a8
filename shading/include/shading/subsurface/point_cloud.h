// Surface samples of an object and the octree over them that integrates a radial profile
// (rd_profile.h) against their transmitted irradiance: the far field of a lookup, in the
// spirit of Jensen & Buhler 2002 (shading/DIPOLE.md 6).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "shading/core/vec.h"
#include "shading/subsurface/rd_profile.h"

namespace shading {

class SurfaceSampler;  // subsurface_sampling.h
// Runs task(i, sampler) for i in [0, n), possibly from several threads, each with its own
// sampler; returns when all are done (rethrowing the first exception).
using ParallelFor =
    std::function<void(std::size_t n, const std::function<void(std::size_t, SurfaceSampler&)>& task)>;

// One surface sample: position and outward unit normal (scene units), the area it stands for,
// the irradiance transmitted into the medium there (POV units: subsurface.h), and the spacing
// of the sample lines that found it (its refinement level).
struct SurfacePoint {
    Vec3 p, n;
    double area = 0;
    Rgb irradiance;
    double spacing = 0;  // 0: the cloud's spacing (PointCloud(points, spacing, near))
    // Distance along -n to the object's next surface crossing (SurfaceSampler::thickness;
    // infinity: none, or not asked for).
    double thickness = std::numeric_limits<double>::infinity();
    // Direction-aware profiles: per channel, the mean offset (scene units) of the light that
    // enters here from where it leaves the surface again: the flux-weighted mean over the lights
    // of the profile's entry shift along each refracted beam's tangential direction (zero: the
    // profile is radially symmetric about p, as under light straight on).
    Vec3 shift[3] = {};
};

struct CloudStats {
    std::size_t points = 0, nodes = 0, levels = 1;
    double total_area = 0, finest_spacing = 0;
};

// An octree over surface points with per-node aggregates (area, transmitted flux A E_t, and
// the flux-weighted centre and covariance) for the hierarchical sum, and the near/far split
// that lookups at a point use.
class PointCloud {
public:
    // Near reflectance of a spacing h (RdProfile::near_reflectance).
    using NearFn = std::function<Rgb(double h)>;
    // Points of possibly different spacings (SurfacePoint::spacing > 0). Each point gets a
    // lookup spacing H >= its own (its leaf's lit points', or its leaf's finest where none is
    // lit): the smallest H such that no lit point (E_t > 0) within 3H of its leaf's box has a
    // spacing above H (then the window's ramp [H, 3H] is sampled at least as finely as H where
    // there is light to sample); found in parallel through `parallel` if given.
    PointCloud(std::vector<SurfacePoint> points, const NearFn& near, const ParallelFor* parallel = nullptr);
    // Every point at one spacing h (SurfacePoint::spacing ignored), near = near_reflectance(h).
    PointCloud(std::vector<SurfacePoint> points, double spacing, const Rgb& near = Rgb(0.0));

    // Coarsest spacing (the base sampling).
    double spacing() const { return levels_.empty() ? spacing_ : levels_.front().h; }
    // The base spacing where the image is (the sampler's h0, before it coarsens the samples
    // no visible point can see and before it refines any; spacing() until set): the window
    // of a fit that must not step where the levels do (Subsurface::curved).
    double view_spacing() const { return view_spacing_ > 0 ? view_spacing_ : spacing(); }
    void set_view_spacing(double h) { view_spacing_ = h; }
    // The split a lookup at x uses: the lookup spacing of the point nearest to x.
    int lookup_level(const Vec3& x) const;
    // Whether a point with light (E_t > 0 in some channel) lies within `radius` of x: where x
    // is lit and none does, the light at x fell between the samples (Subsurface::radiance).
    bool lit_within(const Vec3& x, double radius) const;
    // Whether a point within `radius` of y whose normal faces `facing` (n . facing > 0) has
    // E_t[c] scale[c] > bound[c] in some channel (a face's light that could matter through a
    // slab: Subsurface::transmits).
    bool brighter_within(const Vec3& y, double radius, const Vec3& facing, const Rgb& scale, const Rgb& bound) const;
    // The largest E_t of any point in any channel (0: nothing lit).
    double max_irradiance() const { return max_irradiance_; }
    double level_spacing(int level) const { return levels_[level].h; }
    const Rgb& level_near(int level) const { return levels_[level].near; }
    // Near reflectance of the base spacing (one-level clouds).
    const Rgb& near_reflectance() const { return levels_.front().near; }
    // The smallest SurfacePoint::thickness (infinity: none known).
    double thinnest() const { return thinnest_; }

    // The far part of M(x): sum over points of w(r) Rd(r) A E_t per channel (window of
    // radius r0 = 2h, ramp [r0 - h, r0 + h]), with a node's aggregate used in place of its
    // points when the node lies wholly beyond the ramp and its size seen from x is below
    // `max_angle` (node diagonal / distance to its centre), and nodes farther than `cutoff`
    // (scene units) from x skipped. An aggregate is the node's flux times Rd at its centre
    // plus the second-order term of Rd's Taylor expansion about the centre, (1/2) tr(H Sigma)
    // with Sigma the node's covariance: the error falls from O(angle^2) to O(angle^4).
    // `visited` (optional) counts nodes opened. `weight` (optional): Rd(r) times weight(r) per
    // channel (RadialProfile::exit_weight).
    Rgb far_exitance(const RdProfile& rd, const Vec3& x, double r0, double h, double max_angle, double cutoff,
                     std::size_t* visited = nullptr, const RadialWeight* weight = nullptr) const;
    // The same sum over every point with the profile's exact callable, no aggregation and no
    // cutoff: the reference.
    Rgb far_exitance_exact(const RdProfile& rd, const Vec3& x, double r0, double h,
                           const RadialWeight* weight = nullptr) const;
    // Thin geometry (shading/DIPOLE.md section 6a): M(x) at a point of unit normal nx and
    // thickness d, less the same face's near field: the points whose normal faces the same way
    // as nx (dot > 0) integrated with `same` (of the 3-D distance) and the window, as
    // far_exitance does; the points of the opposite face (dot <= 0) with `transmit`, T of the
    // lateral distance rho = sqrt(s^2 - min(|v.nx|, d)^2) (v = x - p, s = |v|: on a flat slab's
    // far face sqrt(s^2 - d^2)), with the window in rho, their part inside it as near_opposite
    // (the integral of (1 - w) T) times the (1 - w)-weighted mean of their E_t. Nodes are
    // aggregated per side: by their normal cone (or, for a one-sheeted node crossing the
    // plane of nx, its axis); a node holding both faces of a sheet is opened. `opposite`
    // (optional): the opposite face's part of the result. `weight` (optional): on `same` only.
    // `second` (optional): a second pair of profiles (the other thickness node around d) summed
    // in the same traversal, into *second->result and *second->opposite; the traversal's
    // cutoffs are the larger of the two profiles', its aggregation the stricter.
    struct SecondProfiles {
        const RdProfile* same;
        const RdProfile* transmit;
        Rgb near_opposite;
        Rgb* result;
        Rgb* opposite;
    };
    Rgb far_exitance_sided(const RdProfile& same, const RdProfile& transmit, const Vec3& x, const Vec3& nx, double d,
                           double r0, double h, double max_angle, const Rgb& near_opposite,
                           std::size_t* visited = nullptr, Rgb* opposite = nullptr,
                           const RadialWeight* weight = nullptr, const SecondProfiles* second = nullptr) const;
    // The same without aggregation or cutoff, with the profiles' exact callables: the reference.
    Rgb far_exitance_sided_exact(const RdProfile& same, const RdProfile& transmit, const Vec3& x, const Vec3& nx,
                                 double d, double r0, double h, const Rgb& near_opposite) const;

    // Direction-aware profiles (SurfacePoint::shift; shading/DIPOLE.md 6b). Whether any point
    // carries a shift (then the lookups below replace far_exitance and x's own irradiance).
    bool directional() const { return !node_shift_.empty(); }
    // The shift the lookups use for points()[i] in `channel`: its SurfacePoint::shift faded
    // where the surface bends within the shift's reach (a crease, a small bump), by the largest
    // angle between its normal and those within 2.3 shifts, 1 - (angle / 60 deg)^2, none from
    // 60 degrees (build_shifts). A cloud that is not directional: 0.
    Vec3 faded_shift(std::size_t i, int channel) const {
        return leaf_shift_.empty() ? Vec3(0, 0, 0) : leaf_shift_[i].s[channel];
    }
    // The exitance of light that entered at a slant: each point's light leaves about its own
    // shifted entry, spread along the shift with the shift as its mean: offsets a + (1 - a) t,
    // t exponential with mean 1, a = kSmearLead (three Gauss-Laguerre nodes: images at
    // p + kSmearT[k] shift, weights w_k; shading/DIPOLE.md 6b), per channel. The window is
    // taken about each image, so `near_irradiance` returns, per channel, the sum over k of w_k times the (1 - w)-weighted mean E_t of the points whose
    // k-th image lies inside it: the irradiance upstream of x, for the near field
    // (level_near x near_irradiance). Aggregates place each channel's flux at the node's centre
    // plus its flux-weighted mean shift. Otherwise as far_exitance.
    Rgb far_exitance_shifted(const RdProfile& rd, const Vec3& x, const Vec3& nx, double r0, double h, double max_angle,
                             double cutoff, Rgb* near_irradiance, std::size_t* visited = nullptr,
                             const RadialWeight* weight = nullptr) const;
    // The same without aggregation or cutoff, with the profile's exact callable: the reference.
    Rgb far_exitance_shifted_exact(const RdProfile& rd, const Vec3& x, const Vec3& nx, double r0, double h,
                                   Rgb* near_irradiance, const RadialWeight* weight = nullptr) const;
    // The lookup level for far_exitance_shifted: the coarsest of x's own and of the points
    // upstream of x (x less the first two images' offsets of its nearest point's shifts).
    int lookup_level_shifted(const Vec3& x) const;
    // The transmitted irradiance about a point y near the surface: the (1 - w)-weighted mean E_t
    // of the points inside the window of spacing h about y; where none is (y off the surface by
    // more than the window: a line along a curved face's tangent plane), the nearest point's E_t
    // (0 for an empty cloud).
    Rgb irradiance_about(const Vec3& y, double h) const;
    // The mean curvature H of the surface at x (unit normal nx), from the points within the
    // lookup window of spacing h about x (weights: area times 1 - w): the weighted
    // least-squares fit of (nx - n_i).(x - p_i) = H |x - p_i|^2, each pair's normal curvature
    // along its chord to first order. Exact on a sphere (1/R; -1/R seen from inside), 0 on a
    // plane; points whose normal faces away from nx (n_i.nx <= 0: a sheet's other face) are
    // left out; 0 where no other point is.
    double mean_curvature_about(const Vec3& x, const Vec3& nx, double h) const;
    // Whether every point within `radius` of x has a normal within the angle whose cosine is
    // cos_min of nx (a flat face there; a sheet's other face, a crease or a bump is not); the
    // search prunes nodes by their normal cones and stops at the first point that is not.
    bool flat_within(const Vec3& x, const Vec3& nx, double radius, double cos_min) const;
    // Directional clouds: per channel the divergence of the lit points' shift field about x
    // (across x's tangent plane, the window of spacing h, each point by its area: a weighted
    // least-squares linear fit s = s0 + J d, div = tr J). The shifts as the light gave them
    // (not faded at creases); points without one (unlit, or an edge cell whose centre the
    // light misses) and points whose normal is over 30 degrees from nx stay out; 0 where fewer
    // than 6 points are left or they lie along a line.
    Rgb shift_divergence_about(const Vec3& x, const Vec3& nx, double h) const;
    static constexpr int kSmearNodes = 3;
    // The part of the mean shift that every image takes (a): the images' offsets along the
    // shift are a + (1 - a) t, t exponential with mean 1, so their mean is the shift and their
    // variance (1 - a)^2 |shift|^2 (kSmearVariance). a = 0 (the plain exponential) spread a
    // slanted shadow's edge too wide both ways (shading/DIPOLE.md 6b, "The images' lead").
    static constexpr double kSmearLead = 0.25;
    static constexpr double kSmearVariance = (1.0 - kSmearLead) * (1.0 - kSmearLead);
    static const double kSmearT[kSmearNodes];  // a + (1 - a) t_k, t_k the Gauss-Laguerre nodes
    static const double kSmearW[kSmearNodes];

    // The near/far window (rd_profile.h far_window).
    static double window(double r, double r0, double h) { return far_window(r, r0, h); }

    const std::vector<SurfacePoint>& points() const { return points_; }
    CloudStats stats() const;

private:
    // The traversal reads only Node (48 bytes: bounds rounded outwards to float, squared
    // diagonal, links); an aggregate's data (Agg) and a leaf's points (Leaf: position and flux
    // A E_t) are read only when used.
    struct Node {
        float lo[3], hi[3];
        float diag2;               // squared diagonal of the bounds
        std::int32_t child = -1;   // first of `children` consecutive nodes; -1: a leaf
        std::int32_t first = 0, count = 0;  // points [first, first + count) (in point order)
        std::int16_t children = 0;
        std::int8_t uniform = 0;   // lookup level shared by all its points, -1: mixed
        std::uint8_t lit = 0;      // any flux at all
        std::uint8_t octant = 0;   // which octant of its parent's split it holds (bit 0: x, 1: y, 2: z above)
    };
    struct Agg {
        Vec3 centre;         // flux-weighted (area-weighted if no flux) centre
        double cov[6];       // the flux-weighted covariance: xx yy zz xy xz yz
        Rgb flux;            // sum of A E_t
    };
    struct Aux {             // for lookup levels
        Vec3 split;          // centre of the node's bounds (its octants' common corner)
        double max_spacing;
    };
    struct Cone {            // the node's normals: all within `angle` (radians) of `axis`
        float axis[3];
        float angle;
        double axis_cos(const Vec3& v) const {  // axis . v, unclamped
            return double(axis[0]) * v.x + double(axis[1]) * v.y + double(axis[2]) * v.z;
        }
    };
    struct Merge {           // while building: the weights of the centres (flux over channels, area)
        double wsum, area;
        Vec3 area_centre;
        Vec3 nsum;           // area-weighted normal sum
    };
    struct Leaf {
        Vec3 p;
        Rgb flux;            // A E_t
    };
    struct Level {
        double h;
        Rgb near;
    };
    struct Tree;
    void build_tree(const ParallelFor* parallel);
    void build(Tree& t, int index, int first, int count, int depth);
    int split(Tree& t, int index, int first, int count, int depth, int ranges[8][3]);
    void aggregate(Tree& t, int index, int first, int count, int n);
    void finish(const ParallelFor* parallel);
    // Deepest octree level: a traversal's stack holds at most 8 nodes per level.
    static constexpr int kMaxDepth = 48;
    // Squared distance from x to a box (0 inside).
    static double box_distance2(const Vec3& x, const float* lo, const float* hi) {
        const double dx = x.x < lo[0] ? lo[0] - x.x : (x.x > hi[0] ? x.x - hi[0] : 0.0);
        const double dy = x.y < lo[1] ? lo[1] - x.y : (x.y > hi[1] ? x.y - hi[1] : 0.0);
        const double dz = x.z < lo[2] ? lo[2] - x.z : (x.z > hi[2] ? x.z - hi[2] : 0.0);
        return dx * dx + dy * dy + dz * dz;
    }
    double max_spacing_within(int start, const float* lo, const float* hi, double radius, double above) const;
    int nearest(const Vec3& x) const;
    // visit(i, y - p_i, |y - p_i|^2, 1 - w) for every point i inside the window of spacing h
    // about y (irradiance_about, mean_curvature_about).
    template <class Visit>
    void for_each_in_window(const Vec3& y, double h, Visit&& visit) const;
    // The same window about x, where a node under `small` times h across whose normals all lie
    // within acos(min_cos) of nx is visited whole: whole(k, c - x, 1 - w at its centre c
    // (CurveSums)); the other points within the window: point(i, x - p_i, |x - p_i|^2, 1 - w)
    // (mean_curvature_about, shift_divergence_about).
    template <class Whole, class Point>
    void window_sum(const Vec3& x, const Vec3& nx, double h, double small, double min_cos, Whole&& whole,
                    Point&& point) const;
    // far_exitance (kSided false: every point on x's side, `transmit` unused) and
    // far_exitance_sided (true) in one traversal; cut_same2: the squared cutoff of `same`.
    template <bool kSided>
    Rgb far_sum(const RdProfile& same, const RdProfile* transmit, const Vec3& x, const Vec3& nx, double d, double r0,
                double h, double max_angle, double cut_same2, const Rgb& near_opposite, std::size_t* visited,
                Rgb* opposite, const RadialWeight* weight, const SecondProfiles* second = nullptr) const;
    // far_exitance_exact and far_exitance_sided_exact.
    template <bool kSided>
    Rgb exact_sum(const RdProfile& same, const RdProfile* transmit, const Vec3& x, const Vec3& nx, double d, double r0,
                  double h, const Rgb& near_opposite, const RadialWeight* weight) const;
    double spacing_ = 0;
    double view_spacing_ = 0;
    double max_irradiance_ = 0;
    std::vector<SurfacePoint> points_;
    std::vector<Leaf> leaves_;            // points_ in the same order, as the far sum reads them
    std::vector<std::uint8_t> level_of_;  // per point: index into levels_ (empty: all 0)
    std::vector<Level> levels_;           // coarsest first
    std::vector<Node> nodes_;
    std::vector<Agg> aggs_;
    std::vector<Aux> aux_;
    std::vector<Cone> cones_;             // read by far_exitance_sided, window_sum and the crease fade's search
    // Per node, the sums mean_curvature_about needs of its points, about their area centroid c:
    // A = sum A_i, n = sum A_i n_i, q = sum A_i n_i.(p_i - c), v = sum A_i |p_i - c|^2.
    struct CurveSums {
        Vec3 centre, nsum;
        double area = 0, q = 0, var = 0;
        double cone_cos = -1;  // cos of the node's normal cone's half-angle (cones_)
    };
    std::vector<CurveSums> curve_;
    void build_curve_sums();
    // Directional clouds only (else empty): per node and channel, the sums shift_divergence_about
    // needs of its points that are lit in the channel and carry a shift, about the node's
    // CurveSums centre c: a = sum A_i, m = sum A_i (p_i - c), M = sum A_i (p_i - c)(p_i - c)^T
    // (xx yy zz xy xz yz), s = sum A_i s_i, N = sum A_i s_i (p_i - c)^T (row-major), and how
    // many points.
    struct DivSums {
        double a = 0, m[3] = {0, 0, 0}, M[6] = {0, 0, 0, 0, 0, 0}, s[3] = {0, 0, 0}, N[9] = {};
        int count = 0;
        // += w times D's sums moved from D's centre to the point d before it (d = D's centre
        // - this one's): sum a (q + d) = m + a d, sum a (q + d)(q + d)^T = M + m d^T + d m^T +
        // a d d^T, sum a s (q + d)^T = N + s d^T.
        void add_moved(const DivSums& D, const double d[3], double w) {
            static constexpr int kI[6] = {0, 1, 2, 0, 0, 1}, kJ[6] = {0, 1, 2, 1, 2, 2};
            a += w * D.a;
            for (int i = 0; i < 3; ++i) {
                m[i] += w * (D.m[i] + D.a * d[i]);
                s[i] += w * D.s[i];
            }
            for (int e = 0; e < 6; ++e) {
                const int i = kI[e], j = kJ[e];
                M[e] += w * (D.M[e] + D.m[i] * d[j] + d[i] * D.m[j] + D.a * d[i] * d[j]);
            }
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j) N[3 * i + j] += w * (D.N[3 * i + j] + D.s[i] * d[j]);
            count += D.count;
        }
    };
    std::vector<std::array<DivSums, 3>> div_;
    void build_div_sums();
    // Directional clouds only (else empty): per point its shifts; per node the flux-weighted
    // mean shift per channel and the largest image offset of its points (t_max |shift|).
    struct NodeShift {
        Vec3 mean[3];
        double reach = 0;   // t_max x the largest |shift|: every image within it of the box
        double spread = 0;  // the largest |shift|: the images' spread about the shifted points
        double dev[3] = {0, 0, 0};  // per channel, the largest |shift - mean| of its lit points
    };
    struct LeafShift {
        Vec3 s[3];
    };
    std::vector<LeafShift> leaf_shift_;
    std::vector<NodeShift> node_shift_;
    void build_shifts(const ParallelFor* parallel);
    // Whether pred(i) holds for a point i of a lit node within `radius` of y (the first found).
    template <class Pred>
    bool any_lit_within(const Vec3& y, double radius, Pred pred) const;
    template <bool kExact>
    Rgb shifted_sum(const RdProfile& rd, const Vec3& x, const Vec3& nx, double r0, double h, double max_angle,
                    double cut2, Rgb* near_irradiance, std::size_t* visited, const RadialWeight* weight) const;
    double thinnest_ = std::numeric_limits<double>::infinity();
};

}  // namespace shading
