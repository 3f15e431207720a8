// The renderer's side of a `dipole { }` finish: the block's keywords as plain values in, a
// registered-ready finish model out, and the subsurface light at a shaded point. The patches
// parse the block and implement DipoleObject with the renderer's own geometry; nothing else of
// the subsurface layer reaches them.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "shading/core/depth_window.h"
#include "shading/core/smooth_facet.h"
#include "shading/finish/finish.h"

namespace shading {

// A `dipole { }` block as the scene wrote it. What is not given keeps the preset's value or
// the library's default (SubsurfaceSettings).
struct DipoleParams {
    std::string preset;                                   // a published medium; empty: none
    std::optional<Rgb> sigma_s, sigma_s_prime, sigma_a;  // 1/mm
    std::optional<Rgb> anisotropy;                        // Henyey-Greenstein g per channel
    std::optional<double> ior;                            // n_medium / n_outside
    std::optional<double> mm_per_unit;                    // mm per scene unit
    double scene_mm_per_unit = 10.0;                      // global_settings mm_per_unit: the default
    std::optional<double> sample_spacing, error_bound;    // scene units (0: automatic); octree threshold
    std::optional<int> refine_levels;
    std::optional<bool> single_scatter;                   // default: on with the exact profile
    std::optional<bool> thin_geometry;
    std::optional<bool> directional;                      // the exact profile's entry shifts (default on)
    std::optional<bool> curvature;                        // the curvature correction (default: on with the exact profile)
    bool exact_profile = true;                            // `profile exact` (default) or `profile dipole`
    // `method profile` (the default), `method random_walk` or `method auto` (per object:
    // the walk for objects under 10 diffusion lengths across, the profile elsewhere)
    enum class Method { Profile, RandomWalk, Auto };
    Method method = Method::Profile;
    std::optional<int> samples;                           // walks per shaded point (random_walk)
    // depths per channel for single scattering traced in the object's own shape (0, the
    // default: the half-space's formula); SubsurfaceSettings::single_scatter_points
    std::optional<int> single_scatter_samples;
    std::string file;                                     // where the block is written, for its notes
    int line = 0;
};

// Whether `name` is a preset; throws std::invalid_argument naming the presets otherwise (the
// parser asks at the name, so the error points there).
void dipole_preset_check(const std::string& name);

// The finish of a dipole block with `coat` (may be null) above it: finish_model_with_subsurface
// of the medium, its profile (the exact one reads subsurface_profiles.ssp and, where `find`
// locates it, subsurface_slabs.ssp) and settings. What the renderer should tell the user about
// the medium (e.g. a g outside the exact profile's tables) goes into the model's notes, naming
// the medium, at the block's file and line: finish_model_notes() gives them for the finishes a
// scene uses. Throws
// std::invalid_argument with a complete message ("dipole: ...") for a block that cannot make a
// finish.
std::shared_ptr<FinishModel> make_dipole_finish(const DipoleParams& params, const FinishModel* coat,
                                                const FindFile& find);

// What the library asks of the renderer about one object with a dipole finish while it samples
// the object's surface (once per object, from the render threads that reach it first). The
// facade's twin of subsurface's SurfaceSampler, on purpose: the patches see only this layer.
class DipoleObject {
public:
    virtual ~DipoleObject() = default;
    struct Hit {
        double t;   // distance along the line from its origin
        Vec3 p, n;  // point and outward unit normal
        // line_hits: light reaching p is tested from p + lift; zero except on a flat facet with
        // vertex normals (a smooth triangle), where smooth_facet_point(...) - p.
        Vec3 lift;
    };
    // The camera, for refinement within reach of what is seen.
    struct CameraView {
        enum class Kind { Everywhere, Perspective, Orthographic };
        Kind kind = Kind::Everywhere;
        Vec3 location, direction, right, up;
        double lens = 0;
    };
    // The object's bounding box; false when it has none (unbounded: no subsurface light).
    virtual bool bounds(Vec3* lo, Vec3* hi) = 0;
    // Every crossing of the object's surface by origin + t e_axis, t > 0, in any order.
    virtual void line_hits(int axis, const Vec3& origin, std::vector<Hit>* hits) = 0;
    // Those crossings with t0 <= t <= t1, as line_hits gives them (t from origin, the same
    // outward normal). The default filters line_hits; a renderer that can cast the segment
    // alone saves the rest of the line.
    virtual void segment_hits(int axis, const Vec3& origin, double t0, double t1, std::vector<Hit>* hits) {
        const std::size_t first = hits->size();
        line_hits(axis, origin, hits);
        keep_depths_within(hits, first, t0, t1);
    }
    // Transmitted irradiance E_t at p (outward unit normal n), POV units.
    virtual Rgb irradiance(const Vec3& p, const Vec3& n) = 0;
    // What the object is, for messages ("sphere").
    virtual std::string describe() = 0;
    virtual CameraView camera() { return CameraView(); }
    // Distance from p along -n to the object's next surface crossing (infinity: none).
    virtual double thickness(const Vec3& p, const Vec3& n) = 0;

    // `method random_walk` (shading/subsurface/random_walk.h, WalkScene): where the ray
    // origin + t d (origin inside the object) first leaves it, t > 0, crossings into another part
    // of the object skipped (false: never); the scene's lights seen from a point of the surface.
    virtual bool leave(const Vec3& origin, const Vec3& d, Hit* hit) { (void)origin; (void)d; (void)hit; return false; }
    virtual int light_count() { return 0; }
    // Unit direction from p toward light i; false: none.
    virtual bool light_direction(int i, const Vec3& p, Vec3* to_light) { (void)i; (void)p; (void)to_light; return false; }
    // Light i's colour arriving at surface point p (outward normal n) from to_light, after shadows.
    virtual Rgb light_colour(int i, const Vec3& p, const Vec3& n, const Vec3& to_light) {
        (void)i; (void)p; (void)n; (void)to_light;
        return Rgb(0.0);
    }
};

// Thin geometry (Subsurface::slab_single_at_lookup): what single scattering of the flat slab of
// thickness d at x adds to the half-space's that the light loop's BRDF (or the lookup) gives
// there, over `object`'s lights: for each light on x's face the slab's less the half-space's
// (less where the far face cuts the depth short, more where it reflects much back: thin, ior >
// 1, grazing), for each light on the far side the light entering the far face at x - n d (lit
// as that face) scattered once toward the eye where the slab's T leaves it out
// (SlabProfiles::t_single_apart). Terms below 1e-6 of a lit face's single scattering are
// skipped with their shadow rays. Dipole::single_scatter_slab; shading/DIPOLE.md 5a.
// `upstream` (directional lookups; null: 1): per light index, the ratio that lit the lookup's
// half-space single scattering from upstream (Subsurface::single_scatter_upstream); the face's
// correction takes it too, so that the two sum to the slab's own single scattering lit from
// upstream (without it, the correction could exceed the dimmed half-space term: negative pixels).
Rgb slab_single_scatter(const Subsurface& s, DipoleObject& object, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                        double d, const Rgb* upstream = nullptr);

// pixel += finish_subsurface_radiance(...): the light that entered `model`'s medium on the object
// `key` (the object's identity) and leaves at x (unit normal n) toward to_eye. The object's
// point cloud is sampled through `object` on first use; `here()` is E_t at x itself, asked for
// after the cloud exists. Throws std::invalid_argument when the cloud cannot be built (a
// spacing far too small for the object), with what to change.
Rgb finish_subsurface_radiance(const FinishModel& model, const void* key, DipoleObject& object, const Vec3& x,
                               const Vec3& n, const Vec3& to_eye, const std::function<Rgb()>& here);

}  // namespace shading
