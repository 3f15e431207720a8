// Sampling an object's surface for a subsurface finish: what the renderer provides (a
// SurfaceSampler per render thread) and how the samples are placed and refined
// (sample_surface, subsurface_sampling.cpp; shading/DIPOLE.md 6).
#pragma once

#include <cstddef>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "shading/core/depth_window.h"
#include "shading/core/vec.h"
#include "shading/subsurface/point_cloud.h"

namespace shading {

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
        // Light reaching p is tested from p + lift: zero, except on a flat facet with vertex
        // normals, where it reaches the curved surface they describe (smooth_facet_point in
        // core/smooth_facet.h): tested from the facet, light near the terminator falls in
        // facet-sized jags, which refinement would chase as shadow edges (DIPOLE.md 8).
        Vec3 lift;
        Vec3 lit() const { return p + lift; }
    };
    // The object's bounding box; false when it has none (unbounded: no subsurface light).
    virtual bool bounds(Vec3* lo, Vec3* hi) = 0;
    // Every crossing of the object's surface by the ray origin + t e_axis, t > 0 (origin is
    // outside the bounding box), in any order.
    virtual void line_hits(int axis, const Vec3& origin, std::vector<Hit>* hits) = 0;
    // The crossings of line_hits's line with t0 <= t <= t1, each as line_hits gives it (t from
    // origin, the same outward normal), in any order. The default filters line_hits; a
    // renderer may cast the segment alone (an edge sample's sub-lines need only the crossings
    // about their own sheet: DIPOLE.md 6, 2a).
    virtual void segment_hits(int axis, const Vec3& origin, double t0, double t1, std::vector<Hit>* hits) {
        const std::size_t first = hits->size();
        line_hits(axis, origin, hits);
        keep_depths_within(hits, first, t0, t1);
    }
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
    // The lights that reach the object, for a direction-aware profile (SamplingPlan::incidence):
    // how many; the unit direction from p toward light i (false: none); light i's colour
    // arriving at p (outward normal n) from to_light, after shadows. Default: none known.
    virtual int light_count() { return 0; }
    virtual bool light_direction(int i, const Vec3& p, Vec3* to_light) {
        (void)i;
        (void)p;
        (void)to_light;
        return false;
    }
    virtual Rgb light_colour(int i, const Vec3& p, const Vec3& n, const Vec3& to_light) {
        (void)i;
        (void)p;
        (void)n;
        (void)to_light;
        return Rgb(0.0);
    }
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
    std::size_t edge_means = 0;  // samples at an edge of the light that took their cell's mean E_t
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
    // A direction-aware profile (RadialProfile::entry_shift): for light arriving at outside
    // cosine cos_i, the entry factor and the exit shift per channel (scene units). Set: each lit
    // sample gets SurfacePoint::shift from the lights that reach it; empty: no shifts.
    std::function<void(double cos_i, Rgb* entry, Rgb* shift)> incidence;
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

}  // namespace shading
