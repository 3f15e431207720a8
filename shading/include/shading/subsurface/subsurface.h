// The dipole subsurface finish: irradiance sampled over an object's surface once per render,
// integrated against a radial profile Rd with a hierarchical (octree) evaluation, in the
// spirit of Jensen & Buhler, "A Rapid Hierarchical Rendering Technique for Translucent
// Materials", SIGGRAPH 2002.
//
// What a renderer does with it (POV's adapter in patches/; nothing here knows POV types):
//  1. For each object whose finish has a Subsurface, once, on first use: Subsurface::cloud
//     samples the object's surface through a SurfaceSampler the renderer implements (lines
//     crossing the object, and the Fresnel-transmitted irradiance E_t at a point in POV's
//     units: sum over lights of Ft(eta, cos_l) cos_l x light colour x visibility, the light
//     loop of a surface whose BRDF is TransmittanceBrdf: Ft, or the profile's entry factor,
//     over pi). Every render thread that asks for a
//     cloud while it is being built takes part in building it (its own sampler), and the
//     result does not depend on which thread did what. Where the irradiance departs from a
//     linear function between neighbouring samples (shadow edges, terminators) the sampling
//     is refined, level by level, down to a spacing where the near field holds a small part
//     of Rd (sample_surface below); where no part of the image is within reach it is coarser.
//  2. At a shading point x seen from direction wo: pixel += Ft(eta, cos_o) M(x) (for another
//     profile than the dipole: its exit factor, RadialProfile::exit_factor), where M(x),
//     the radiant exitance, is Jensen 2001's integral of Rd(|x - p|) E_t(p) over the surface.
//     Since POV's pixel is pi x radiance, this is L_o = (1/pi) Ft(wo) M. M splits at a window
//     w(r) that rises smoothly (C2) from 0 at R0 - h to 1 at R0 + h (R0 = 2h, h the local
//     sample spacing at x, PointCloud::lookup_level):
//       near: E_t(x) * integral of (1 - w(r)) Rd(r) 2 pi r dr   (the surface taken as flat
//             within 3h and lit like x: E_t(x) comes from the light loop at x itself);
//       far:  sum_i w(r_i) Rd(r_i) A_i E_t,i over the samples (hierarchically, PointCloud).
//     The near integral holds Rd's sharp peak (finite at r = 0, but ~1/r^3 for zr << r << 1/
//     sigma_tr): integrated, not sampled, so nothing is regularised by hand and there is no
//     grid pattern for any spacing.
//  3. The single-scattering term is a BRDF (Dipole::single_scatter_brdf) lit by the ordinary
//     light loop: the finish model's brdf includes it.
// Lengths are scene units (Medium::mm_per_unit converts the published 1/mm coefficients).
#pragma once

#include <atomic>
#include <cstring>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "shading/brdf/brdf.h"
#include "shading/subsurface/dipole.h"
#include "shading/subsurface/radial_profile.h"
#include "shading/subsurface/slab.h"

namespace shading {

// ---------------------------------------------------------------------------------------------
// The radial profile: the seam between a profile (the dipole, or any tabulated Rd) and the
// machinery that integrates it over surfaces.

// Rd(r) per channel (exitance at distance r per unit flux entering the medium, per scene
// unit^2), tabulated once for the octree's inner loop with its first two derivatives:
// cubic Hermite in r between nodes (f from f and f', f'' from f'' and f'''). Nodes lie at r = scale (s - 1) for
// s = 2^e (1 + k/64): 64 per octave of 1 + r/scale, uniform within `scale` of the peak and
// logarithmic beyond (the same relative step along an exponential or power-law tail), found
// from the bits of s without a logarithm. 0 at and beyond r_max. Relative error below 1e-4
// wherever Rd > 1e-9 Rd(0) (SubsurfaceRdProfile tests).
class RdProfile {
public:
    using Fn = std::function<Rgb(double)>;
    // rd(r): the profile, finite and >= 0 for every r >= 0 (called only here, while building
    // and for the near field). disc(R) (may be empty): its integral over a disc of radius R,
    // dimensionless, disc(inf) the total diffuse reflectance; empty: integrated numerically
    // from rd (4-point Gauss-Legendre on each node interval, summed once). scale > 0: the length of the profile's
    // peak (the smallest mean free path 1/sigma_t'); r_max > 0: where rd may be taken as 0.
    // Throws std::invalid_argument for a bad range.
    RdProfile(Fn rd, Fn disc, double scale, double r_max);
    // The table of a radial profile (radial_profile.h: the dipole, the exact profile): its rd
    // and disc integral, scale = its smallest mean free path, r_max = its cutoff. The one way a
    // profile reaches the sampler (Subsurface builds it).
    static std::shared_ptr<const RdProfile> of(std::shared_ptr<const RadialProfile> model);
    // A tabulated profile: radii 0 = r[0] < r[1] < ... and rd per channel at each (>= 0),
    // interpolated monotonically (Fritsch-Carlson cubic in log rd; linear where rd is 0),
    // 0 beyond the last radius. Throws std::invalid_argument on unsorted or bad input.
    static std::shared_ptr<const RdProfile> tabulated(std::vector<double> r, std::vector<Rgb> rd, double scale);

    Rgb rd(double r) const;                           // the table (fast)
    void eval(double r, Rgb* f, Rgb* d1, Rgb* d2) const;  // Rd and d/dr, d2/dr2 (table)
    Rgb exact(double r) const { return rd_(r); }      // the callable itself
    Rgb disc(double R) const;                         // integral over a disc of radius R
    Rgb total() const { return total_; }              // disc(r_max)
    // Smallest radius holding `fraction` of the total in every channel (bisection on disc).
    double radius_containing(double fraction) const;
    // The part of the profile inside the near/far window of spacing h (R0 = 2h, ramp [h, 3h]):
    // integral of (1 - w(r)) Rd(r) 2 pi r dr per channel.
    Rgb near_reflectance(double h) const;
    double r_max() const { return r_max_; }
    double scale() const { return scale_; }
    // How much a node's squared size/distance ratio may grow at squared distance d2 beyond the
    // profile's peak of 2 pi r^2 Rd(r) (its share of the total per unit log r): by
    // sqrt(peak / share), the aggregation error (~ angle^4 x share) then stays that of the peak,
    // at most 4 (twice the angle). 1 within the peak. Per octave of 1 + d2/scale^2, the smallest
    // over that octave and beyond.
    double angle_gain2(double d2) const {
        const double s2 = 1.0 + d2 * inv_scale_ * inv_scale_;
        std::uint64_t bits;
        std::memcpy(&bits, &s2, sizeof bits);
        const std::size_t e = std::size_t(bits >> 52) - 1023;
        return e < gain2_.size() ? gain2_[e] : gain2_.back();
    }

private:
    struct Node {
        double f[3], d1[3], d2[3], d3[3];
    };
    Fn rd_, disc_;
    double scale_ = 1, inv_scale_ = 1, r_max_ = 1;
    Rgb total_;
    Rgb interval_integral(double a, double b) const;
    std::vector<Node> nodes_;
    std::vector<double> node_r_;
    std::vector<Rgb> cumulative_;  // without a disc callable: the integral up to each node
    std::vector<double> gain2_;
};

// ---------------------------------------------------------------------------------------------
// Surface samples and the octree.

class SurfaceSampler;
// Runs task(i, sampler) for i in [0, n), possibly from several threads, each with its own
// sampler; returns when all are done (rethrowing the first exception).
using ParallelFor =
    std::function<void(std::size_t n, const std::function<void(std::size_t, SurfaceSampler&)>& task)>;

// One surface sample: position and outward unit normal (scene units), the area it stands for,
// the irradiance transmitted into the medium there (POV units, see above), and the spacing
// of the sample lines that found it (its refinement level).
struct SurfacePoint {
    Vec3 p, n;
    double area = 0;
    Rgb irradiance;
    double spacing = 0;  // 0: the cloud's spacing (PointCloud(points, spacing, near))
    // Distance along -n to the object's next surface crossing (SurfaceSampler::thickness;
    // infinity: none, or not asked for).
    double thickness = std::numeric_limits<double>::infinity();
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
    // lookup spacing H >= its own: the smallest H such that no point within 3H of its leaf's
    // box has a spacing above H (then the window's ramp [H, 3H] is sampled at least as finely
    // as H); found in parallel through `parallel` if given.
    PointCloud(std::vector<SurfacePoint> points, const NearFn& near, const ParallelFor* parallel = nullptr);
    // Every point at one spacing h (SurfacePoint::spacing ignored), near = near_reflectance(h).
    PointCloud(std::vector<SurfacePoint> points, double spacing, const Rgb& near = Rgb(0.0));

    // Coarsest spacing (the base sampling).
    double spacing() const { return levels_.empty() ? spacing_ : levels_.front().h; }
    // The split a lookup at x uses: the lookup spacing of the point nearest to x.
    int lookup_level(const Vec3& x) const;
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
    // `visited` (optional) counts nodes opened.
    Rgb far_exitance(const RdProfile& rd, const Vec3& x, double r0, double h, double max_angle, double cutoff,
                     std::size_t* visited = nullptr) const;
    // The same sum over every point with the profile's exact callable, no aggregation and no
    // cutoff: the reference.
    Rgb far_exitance_exact(const RdProfile& rd, const Vec3& x, double r0, double h) const;
    // Thin geometry (shading/DIPOLE.md section 6a): M(x) at a point of unit normal nx and
    // thickness d, less the same face's near field: the points whose normal faces the same way
    // as nx (dot > 0) integrated with `same` (of the 3-D distance) and the window, as
    // far_exitance does; the points of the opposite face (dot <= 0) with `transmit`, T of the
    // lateral distance rho = sqrt(s^2 - min(|v.nx|, d)^2) (v = x - p, s = |v|: on a flat slab's
    // far face sqrt(s^2 - d^2)), with the window in rho, their part inside it as near_opposite
    // (the integral of (1 - w) T) times the (1 - w)-weighted mean of their E_t. Nodes are
    // aggregated per side: by their normal cone (or, for a one-sheeted node crossing the
    // plane of nx, its axis); a node holding both faces of a sheet is opened. `opposite`
    // (optional): the opposite face's part of the result.
    Rgb far_exitance_sided(const RdProfile& same, const RdProfile& transmit, const Vec3& x, const Vec3& nx, double d,
                           double r0, double h, double max_angle, const Rgb& near_opposite,
                           std::size_t* visited = nullptr, Rgb* opposite = nullptr) const;
    // The same without aggregation or cutoff, with the profiles' exact callables: the reference.
    Rgb far_exitance_sided_exact(const RdProfile& same, const RdProfile& transmit, const Vec3& x, const Vec3& nx,
                                 double d, double r0, double h, const Rgb& near_opposite) const;

    // The window: 0 below r0 - h, 1 above r0 + h, between them the C2 smootherstep
    // t^3 (6 t^2 - 15 t + 10) of t = (r - r0 + h) / 2h (on a grid of spacing h its
    // quadrature leaves a fainter pattern than smoothstep's).
    static double window(double r, double r0, double h);

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
    void finish();
    double max_spacing_within(int start, const float* lo, const float* hi, double radius, double above) const;
    int nearest(const Vec3& x) const;
    double spacing_ = 0;
    std::vector<SurfacePoint> points_;
    std::vector<Leaf> leaves_;            // points_ in the same order, as the far sum reads them
    std::vector<std::uint8_t> level_of_;  // per point: index into levels_ (empty: all 0)
    std::vector<Level> levels_;           // coarsest first
    std::vector<Node> nodes_;
    std::vector<Agg> aggs_;
    std::vector<Aux> aux_;
    std::vector<Cone> cones_;             // read only by far_exitance_sided
    double thinnest_ = std::numeric_limits<double>::infinity();
};

// ---------------------------------------------------------------------------------------------
// Sampling an object: what the renderer provides, and how samples are refined.

// Where the camera looks, in POV's terms: image rays are direction + x right + y up from
// location (Perspective), or along direction from location + x right + y up (Orthographic),
// for x, y in [-1/2, 1/2]; `lens` widens either by the focal-blur aperture. Everywhere: any
// other camera (or none known). Refinement goes only where the image can see within a reach.
struct ViewVolume {
    enum class Kind { Everywhere, Perspective, Orthographic };
    Kind kind = Kind::Everywhere;
    Vec3 location, direction, right, up;
    double lens = 0;
    // Whether a point of the volume lies within about `reach` of p (conservative: true when the
    // vectors are degenerate).
    bool near(const Vec3& p, double reach) const;
};

// One render thread's access to the object being sampled (Subsurface::cloud). Called only from
// the thread that owns it, while that thread is inside Subsurface::cloud.
class SurfaceSampler {
public:
    virtual ~SurfaceSampler() = default;
    struct Hit {
        double t;  // distance along the line from its origin
        Vec3 p, n; // point and outward unit normal
    };
    // The object's bounding box; false when it has none (unbounded: no subsurface light).
    virtual bool bounds(Vec3* lo, Vec3* hi) = 0;
    // Every crossing of the object's surface by the ray origin + t e_axis, t > 0 (origin is
    // outside the bounding box), in any order.
    virtual void line_hits(int axis, const Vec3& origin, std::vector<Hit>* hits) = 0;
    // Transmitted irradiance E_t at p (outward unit normal n), POV units.
    virtual Rgb irradiance(const Vec3& p, const Vec3& n) = 0;
    // What the object is, for messages ("sphere").
    virtual std::string describe() = 0;
    // Where the camera looks (default: everywhere).
    virtual ViewVolume view() { return ViewVolume(); }
    // Distance from p (on the surface, outward unit normal n) along -n to the object's next
    // surface crossing: the local thickness (infinity when the line leaves without crossing
    // it again, e.g. an open surface; default: infinity, thin geometry unknown).
    virtual double thickness(const Vec3& p, const Vec3& n) {
        (void)p;
        (void)n;
        return std::numeric_limits<double>::infinity();
    }
};

struct SubsurfaceSettings {
    double spacing = 0;        // base sample spacing in scene units; 0: automatic (sample_spacing())
    double max_angle = 0.7;    // hierarchical error threshold (PointCloud::far_exitance)
    bool single_scatter = true;
    int max_lines = 200;       // automatic spacing: at most this many sample lines per bbox axis
    // Refinement (sample_surface): levels below the base spacing, each halving it; -1:
    // automatic (down to the spacing whose near field holds at most edge_fraction of Rd in
    // every channel: a lookup right at a sharp shadow edge is then off by about half of that).
    int max_levels = -1;
    double edge_fraction = 0.05;
    double tolerance = 0.02;   // refine where E_t departs from linear by this part of its maximum
    std::size_t max_points = 4000000;  // per object; refinement stops before exceeding it
    // Thin geometry: each sample's thickness (SurfaceSampler::thickness) and, where an object
    // is thinner than slab_threshold(), slab profiles (slab.h) instead of the half-space's.
    bool thin = true;
};


// What building one cloud found (for the statistics).
struct CloudReport {
    bool unbounded = false;  // no finite bounding box: empty cloud
    bool thin = false;       // more than 10 % of the level-0 segments through it are shorter than mfp'
    double thinnest = std::numeric_limits<double>::infinity();  // smallest sample thickness (if asked for)
    double extent = 0;       // largest side of the bounding box (scene units)
    Vec3 centre;             // of the bounding box
    int levels = 0;          // refinement levels used
    std::size_t refined = 0; // samples added by refinement
    bool view_limited = false;  // refinement kept to the camera's view
    bool capped = false;     // refinement stopped by max_points
};

// How to sample one object (Subsurface::cloud fills it in).
struct SamplingPlan {
    Vec3 lo, hi;          // the object's bounding box
    double h0 = 1;        // spacing of the first lines
    int levels = 0;       // halvings in all
    int view_levels = 0;  // the first halvings go wherever the view is within reach (h0 is then
                          // the base spacing x 2^view_levels: coarse where nothing is seen)
    double tolerance = 0.02;
    std::size_t max_points = 4000000;
    double mean_free_path = 0;  // for the thin-geometry count
    bool thickness = false;     // ask the sampler for each sample's thickness
    ViewVolume view;
    double reach = 0;     // the profile's radius holding 99 % of Rd
};

// Samples an object for a subsurface finish (subsurface_sampling.cpp; shading/DIPOLE.md 6):
//  * lines along x, y and z at spacing h0 across the bounding box; each crossing is a sample
//    of family `axis`, standing for the area h^2 w_a(n) / |n_axis| (w_a: a partition of unity
//    over the three families that gives 0 to a family whose lines graze the surface, so every
//    family's samples lie at most ~3.5 h apart on the surface: no rings where lines graze,
//    e.g. around the point of a sphere that faces one axis);
//  * E_t at each sample;
//  * level by level (h_k = h0 / 2^k): the first view_levels split every sample within reach of
//    the view; then samples whose E_t departs from the linear interpolation of their grid
//    neighbours by more than tolerance x max E_t (and that lie within reach of the view) are
//    marked, the marks widened to every sample of the level within 4.5 h_k, and each marked
//    sample replaced by the crossings of the four sub-lines of its line cell (when they cross
//    the surface as often as the parent line did).
// Every stage runs through `parallel`. Returns the cloud's points.
std::vector<SurfacePoint> sample_surface(const ParallelFor& parallel, const SamplingPlan& plan, CloudReport* report);

// ---------------------------------------------------------------------------------------------
// Counters for POV's statistics (process-wide, all subsurface finishes).
struct SubsurfaceStats {
    std::size_t clouds = 0, points = 0, lookups = 0, nodes_visited = 0;
    double build_seconds = 0;
    std::size_t refined_points = 0;
    int max_levels = 0;
    double finest_spacing = 0;  // smallest spacing reached in any cloud (scene units), 0: none
    std::size_t unbounded = 0;  // objects that could not be sampled (no finite bounding box)
    std::size_t thin = 0;       // thin geometry off: objects thinner than the mean free path in > 10 % of places
    // Thin geometry on: objects thinner than their finish's slab threshold somewhere, the
    // thinnest sample found (scene units and transport mean free paths), lookups that used
    // slab profiles.
    std::size_t slab_objects = 0, slab_lookups = 0;
    double thinnest = 0, thinnest_mfp = 0;  // 0: none
    std::vector<std::string> notes;  // per-object warnings (small objects), sorted
};
SubsurfaceStats subsurface_stats();

// What one `dipole { }` finish holds: the medium, its settings, the radial profile (the model,
// radial_profile.h, and its table RdProfile::of(model) that the octree reads), and the
// per-object clouds.
class Subsurface {
public:
    // model: the radial profile to integrate, its exit and entry factors (null: the dipole of
    // this medium with `fdr`, DipoleRadialProfile; an ExactProfile for `profile exact`). The
    // dipole of the medium stays for the single-scattering BRDF either way.
    Subsurface(const Medium& medium, const SubsurfaceSettings& settings, FdrModel fdr = FdrModel::JensenFit,
               std::shared_ptr<const RadialProfile> model = nullptr);
    ~Subsurface();
    Subsurface(const Subsurface&) = delete;
    Subsurface& operator=(const Subsurface&) = delete;

    const Dipole& dipole() const { return dipole_; }
    const RdProfile& profile() const { return *profile_; }
    const RadialProfile& model() const { return *model_; }
    const std::shared_ptr<const RadialProfile>& model_ptr() const { return model_; }
    const SubsurfaceSettings& settings() const { return settings_; }

    // Base sample spacing for an object whose bounding box has the given largest extent: the
    // user's, or the larger of half the smallest channel's mean free path 1/sigma_t' and
    // extent / max_lines (bounds the point count); refinement goes finer where it matters.
    double sample_spacing(double extent) const;
    // Refinement levels below base spacing h0 (settings: max_levels, edge_fraction).
    int refinement_levels(double h0) const;
    // Rd is negligible (below 1e-6 of its integral) beyond this distance: the profile's r_max.
    double cutoff() const { return profile_->r_max(); }
    // Smallest mean free path 1/sigma_t' over the channels (scene units; the model's): geometry
    // thinner than this is outside the profile's assumptions (the statistics warn).
    double mean_free_path() const;
    // Largest diffusion length 1/sigma_tr over the channels (scene units; inf without absorption).
    double diffusion_length() const;

    // The cloud of the object `key`, sampled through `sampler` the first time. Lock-free once
    // built. While it is being built, every thread that asks takes part (with its own
    // sampler) and returns when it is done. An empty cloud is kept too (nothing to scatter).
    const PointCloud& cloud(const void* key, SurfaceSampler& sampler) const;

    // Thin geometry: the thickness from which objects are treated as semi-infinite (slab.h
    // slab_threshold at 0.5 %; scene units; 0 with thin geometry off), and whether a lookup on
    // this cloud needs its point's thickness (some sample of it is thinner).
    double slab_threshold() const { return slab_threshold_; }
    bool wants_thickness(const PointCloud& cloud) const { return cloud.thinnest() < slab_threshold_; }
    // The slab profiles used for a point of thickness d < slab_threshold() (d is rounded to one
    // of 32 nodes per octave from 0.01 mean free paths up; built on first use, lock-free after).
    const SlabProfiles& slab(double d) const;

    // The near/far split of this finish for a cloud of spacing h: R0 = 2h.
    static double near_radius(double h) { return 2.0 * h; }
    Rgb near_reflectance(double h) const { return profile_->near_reflectance(h); }

    // pixel += radiance(...): exit_factor(cos_o) M(x) (RGB; RadialProfile::exit_factor, the
    // dipole's is Ft(eta, cos_o)) at x (normal n) on an object whose
    // cloud is `cloud`, with E_t(x) the transmitted irradiance at x itself; 0 when the viewer
    // is below the surface.
    Rgb radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                 const Rgb& irradiance_here) const;
    // The same at a point of local thickness `thickness` (SurfaceSampler::thickness): below
    // slab_threshold() the slab's profiles (far_exitance_sided, the near field from R); at or
    // above it exactly the call above.
    Rgb radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                 const Rgb& irradiance_here, double thickness) const;

private:
    Dipole dipole_;
    SubsurfaceSettings settings_;
    std::shared_ptr<const RadialProfile> model_;
    std::shared_ptr<const RdProfile> profile_;
    double reach_ = 0;  // radius holding 99 % of Rd: how far from the view refinement matters
    // Thin geometry: threshold, the slab nodes (thickness d_k = slab_min_ 2^(k/32)), each built
    // once under slab_mutex_ and read through its atomic pointer.
    double slab_threshold_ = 0, slab_min_ = 0;
    Rgb slab_scale_{1.0, 1.0, 1.0};  // per channel: the model's half-space total / the dipole's
    struct SlabNode;
    std::size_t slab_count_ = 0;
    std::unique_ptr<std::atomic<const SlabNode*>[]> slab_nodes_;
    mutable std::mutex slab_mutex_;
    const SlabNode& slab_node(double d) const;
    struct Entry;
    struct Index;
    std::shared_ptr<const PointCloud> build(Entry& e, SurfaceSampler& sampler) const;
    mutable std::mutex mutex_;
    mutable std::vector<std::unique_ptr<Entry>> entries_;
    mutable std::vector<std::unique_ptr<const Index>> indexes_;  // every index published (readers may hold any)
    mutable std::atomic<const Index*> index_{nullptr};
};

// RadialProfile::entry_factor(cos_i) / pi as a Brdf (wo ignored above the surface; the
// dipole's: Ft(eta, cos_i) / pi): lit by the renderer's light loop it yields the transmitted
// irradiance E_t at a point (the adapter's finish model for it: FinishModel::transmittance,
// finish.h).
class TransmittanceBrdf final : public Brdf {
public:
    explicit TransmittanceBrdf(std::shared_ptr<const RadialProfile> model);
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    std::string describe() const override;

private:
    std::shared_ptr<const RadialProfile> model_;
};

// The single-scattering term of a medium as a Brdf (Dipole::single_scatter_brdf), optionally
// plus another Brdf on top (a specular coat from brdf_model): the surface part of a dipole finish.
class DipoleSurfaceBrdf final : public Brdf {
public:
    DipoleSurfaceBrdf(std::shared_ptr<const Subsurface> s, BrdfPtr coat);
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    bool anisotropic() const override { return coat_ && coat_->anisotropic(); }
    std::string describe() const override;
    Rgb lambert_base() const override { return coat_ ? coat_->lambert_base() : Rgb(0.0); }
    const BrdfPtr& coat() const { return coat_; }

private:
    std::shared_ptr<const Subsurface> s_;
    BrdfPtr coat_;
};

}  // namespace shading
