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
//     over pi). Every render thread that asks for a cloud while it is being built takes part
//     in building it (its own sampler), and the result does not depend on which thread did
//     what. Where the irradiance departs from a linear function between neighbouring samples
//     (shadow edges, terminators) the sampling is refined, level by level, down to a spacing
//     where the near field holds a small part of Rd (sample_surface); where no part of the
//     image is within reach it is coarser.
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
//
// The parts, lowest first: dipole.h and exact_profile.h (ss_profile.h's tables) behind
// radial_profile.h; rd_profile.h (a profile's table for the octree); slab.h (thin slabs);
// point_cloud.h (the samples and the octree); subsurface_sampling.h (sampling an object);
// cloud_cache.h, slab_cache.h (built once, read lock-free); subsurface_stats.h. This header
// includes them all: the finish adapter and the patches see the whole finish through it.
#pragma once

#include <limits>

#include <memory>
#include <vector>
#include <mutex>
#include <unordered_set>
#include <string>

#include "shading/brdf/brdf.h"
#include "shading/core/vec.h"
#include "shading/subsurface/cloud_cache.h"
#include "shading/subsurface/curvature.h"
#include "shading/subsurface/dipole.h"
#include "shading/subsurface/exact_profile.h"
#include "shading/subsurface/point_cloud.h"
#include "shading/subsurface/radial_profile.h"
#include "shading/subsurface/random_walk.h"
#include "shading/subsurface/rd_profile.h"
#include "shading/subsurface/slab.h"
#include "shading/subsurface/slab_cache.h"
#include "shading/subsurface/ss_profile.h"
#include "shading/subsurface/subsurface_sampling.h"
#include "shading/subsurface/subsurface_stats.h"

namespace shading {

// The most depths per channel `single_scatter_samples` takes (each costs a light path per light).
constexpr int kMaxSingleScatterPoints = 256;

// The directions toward the lights at a point (unit vectors), what the lookups' incidence terms
// are taken for: POV's lights as the finish found them, without shadow rays.
struct LightDirections {
    const Vec3* to_light = nullptr;
    std::size_t count = 0;
};

struct SubsurfaceSettings {
    double spacing = 0;        // base sample spacing in scene units; 0: automatic (sample_spacing())
    double max_angle = 0.7;    // hierarchical error threshold (PointCloud::far_exitance)
    bool single_scatter = true;
    int max_lines = 200;       // automatic spacing: at most this many sample lines per bbox axis
    // Refinement (sample_surface): levels below the base spacing, each halving it; -1:
    // automatic (down to the spacing whose near field holds at most edge_fraction of what
    // every channel reflects, Rd plus the single scattering the finish adds: a lookup right at
    // a sharp shadow edge is then off by about half of that).
    int max_levels = -1;
    double edge_fraction = 0.05;
    double tolerance = 0.02;   // refine where E_t departs from linear by this part of its maximum
    std::size_t max_points = 4000000;  // per object; refinement stops before exceeding it
    // Thin geometry: each sample's thickness (SurfaceSampler::thickness) and, where an object
    // is thinner than slab_threshold(), slab profiles (slab.h) instead of the half-space's.
    bool thin = true;
    // Direction-aware profiles (RadialProfile::entry_shift; the exact profile's): light entering
    // at a slant leaves about an entry shifted along its refracted beam, and single scattering
    // is lit from upstream (shading/DIPOLE.md 6b): the constructor then moves single_scatter to
    // auto_single_scatter (at each lookup, not in the BRDF), as the finish does for `auto`.
    // Off in the library (its unit checks are of the radially symmetric profile); the dipole
    // finish turns it on unless the scene says `directional off` (dipole_finish.cpp).
    bool directional = false;
    // The exact profile's exit distribution for light entering at a slant (RadialProfile::
    // exit_factor_oblique; shading/DIPOLE.md 6e): the half-space lookup's exit factor taken for
    // the incidence of the lights at the point (incidence_exit_ratio). Nothing changes for a
    // profile without oblique exits (the dipole) or under light straight on.
    bool oblique_exits = true;
    // The exact profile's first-order correction for the surface's mean curvature
    // (curvature.h; shading/DIPOLE.md 6d): off here, on by default in the finish with the
    // exact profile.
    bool curvature = false;
    // `method profile` (the above) or `method random_walk`: exact transport inside the
    // object's own surface (random_walk.h), no cloud, no profile, no single-scattering BRDF.
    // `method auto`: per object, the walk where its smallest bounding-box extent is below
    // auto_lengths diffusion lengths (small objects, sheets: where the profile's assumptions
    // fail), the profile elsewhere; single scattering then comes with the profile's lookups
    // (auto_single_scatter), not from the BRDF, so walked objects do not count it twice.
    // Single scattering traced in the object's own shape (`single_scatter_samples N`,
    // RandomWalk::single_scatter: N depths per channel along each view ray) instead of the
    // half-space's BRDF: right on curved and thin objects and for light from behind a sheet.
    // 0 (the default): the BRDF. With N > 0 and method profile the constructor moves
    // single_scatter to auto_single_scatter (at each lookup), as for `directional`.
    int single_scatter_points = 0;
    enum class Method { Profile, RandomWalk, Auto };
    Method method = Method::Profile;
    WalkSettings walk;
    double auto_lengths = 10.0;
    bool auto_single_scatter = true;
};

// What one `dipole { }` finish holds: the medium, its settings, the radial profile (the model,
// radial_profile.h, and its table make_rd_profile(model) that the octree reads), the
// per-object clouds and the slabs of thin geometry.
// One light's colour arriving at points of a face, after shadows (Subsurface::
// single_scatter_upstream; the finish's DipoleObject::light_colour), and `here`, at the shaded
// point itself, which the caller has already.
struct LightAlongLine {
    Rgb here;
    virtual Rgb at(const Vec3& y) const = 0;

protected:
    ~LightAlongLine() = default;
};

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
    // The walk of `method random_walk` and `method auto`, and of single scattering traced in
    // the object (single_scatter_points > 0); null otherwise.
    const RandomWalk* walk() const { return walk_.get(); }
    // Whether single scattering is traced in the object's shape at each lookup.
    bool traced_single_scatter() const { return settings_.single_scatter_points > 0 && settings_.auto_single_scatter; }
    // Thin geometry: whether a point thinner than slab_threshold() gets the flat slab's own
    // single scattering at its lookup (Dipole::single_scatter_slab, dipole_finish.cpp): single
    // scattering on (from the BRDF or at each lookup), not traced. The half-space term the BRDF
    // (or a direction-aware lookup, lit from upstream) adds is then corrected for the far face,
    // and light entering the far face is scattered once toward the eye (the slab's T leaves it
    // out, t_single_apart).
    bool slab_single_at_lookup() const { return slab_single_; }
    // Whether lookups use the profile's entry shifts (settings.directional and a profile with
    // them: shading/DIPOLE.md 6b).
    bool directional() const { return directional_; }
    bool oblique_exits() const { return oblique_exits_; }
    // The exit distribution's change with the light's incidence at x (normal n), per channel:
    // sum over the lights facing x (unit directions to_lights[i]; shadows not tested) of the
    // light's weight entry_factor(cos_i) cos_i times exit_factor_oblique over exit_factor, over
    // the weights' sum. Faded to 1 as the lights' largest cosine falls from kObliqueFade to 0
    // (at a terminator and beyond it the light at x entered elsewhere). 1 without oblique exits.
    Rgb incidence_exit_ratio(const Vec3& n, const Vec3& to_eye, const Vec3* to_lights, std::size_t count) const;
    static constexpr double kObliqueFade = 0.1;
    // Per channel c(eta, alpha') times the anisotropy weight times mfp', in scene units
    // (curvature.h): the exitance's relative change per unit of mean curvature; 0 with the
    // correction off.
    const Rgb& curvature_length() const { return curvature_length_; }
    // Single scattering next to a change of light (a shadow edge): the light that scatters once
    // under x toward to_eye entered upstream, at x + t z D (D the tangential offset per unit
    // depth of the refracted view and light rays, z the mean single-scattering depth per
    // channel, t exponential): the cloud's transmitted irradiance there over its irradiance
    // about x, per channel, at most 1 (1 where the cloud has none about x). Multiplies the
    // half-space's single-scattering BRDF.
    // `light` (may be null): this light's colour arriving at points of x's face, after shadows
    // (DipoleObject::light_colour), and at x. Where the cloud's light changes along the line (a
    // shadow's edge within reach) and the face is flat over it, the ratio is the light's own
    // visibility along the line instead, its steps located to 1/64 of their interval (the
    // cloud's window smooths a shadow's edge over a few sample spacings: Ketchup's edge under
    // light at 70 degrees read +8.6 % of the plateau one pixel into the light).
    Rgb single_scatter_upstream(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                                const Vec3& to_light, const LightAlongLine* light = nullptr) const;
    // `method auto`: whether the object `key` (smallest bounding-box extent `extent`, scene
    // units; infinity: unbounded) is walked; each object is counted once in the statistics.
    bool auto_walks(const void* key, double extent) const;

    // Base sample spacing for an object whose bounding box has the given largest extent: the
    // user's, or the larger of half the smallest channel's mean free path 1/sigma_t' and
    // extent / max_lines (bounds the point count); refinement goes finer where it matters.
    double sample_spacing(double extent) const;
    // Refinement levels below base spacing h0 (settings: max_levels, edge_fraction).
    int refinement_levels(double h0) const;
    // Per channel, the single scattering this finish adds to a pixel (by the BRDF, or at each
    // lookup), as the half-space's: per unit irradiance entering at normal incidence,
    // hemispherical; 0 with single scattering off.
    Rgb single_scatter_shown() const;
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
    // ... and up to which a thicker point may still pass light through to its other face
    // (transmit_threshold at 1e-4 of R_inf; slab_threshold's or more): a lookup there takes
    // the slab's profiles where that light could matter (transmits()).
    double transmit_threshold() const { return transmit_threshold_; }
    bool wants_thickness(const PointCloud& cloud) const { return cloud.thinnest() < transmit_threshold_; }
    // ... at a point with transmitted irradiance E_t: a cloud thinner than slab_threshold()
    // somewhere, or one whose thinnest part could pass light that matters there (transmits():
    // T is largest at the least thickness, so a lit face of a thick object casts no ray).
    bool wants_thickness(const PointCloud& cloud, const Rgb& irradiance_here) const {
        return cloud.thinnest() < slab_threshold_ ||
               (cloud.thinnest() < transmit_threshold_ && transmits(cloud, cloud.thinnest(), irradiance_here));
    }
    // The slab profiles used for a point of thickness d < slab_threshold() (d is rounded to one
    // of 32 nodes per octave from 0.01 mean free paths up; built on first use, lock-free after).
    const SlabProfiles& slab(double d) const;

    // The near/far split of this finish for a cloud of spacing h: R0 = 2h.
    static double near_radius(double h) { return 2.0 * h; }
    Rgb near_reflectance(double h) const { return profile_->near_reflectance(h); }

    // pixel += radiance(...): exit_factor(cos_o) M(x) (RGB; RadialProfile::exit_factor, the
    // dipole's is Ft(eta, cos_o)) at x (normal n) on an object whose
    // cloud is `cloud`, with E_t(x) the transmitted irradiance at x itself; 0 when the viewer
    // is below the surface. With settings.curvature, M(x) times 1 + curvature_length() H per
    // channel (H the cloud's mean curvature about x; curvature.h).
    // exit_ratio: incidence_exit_ratio's, which multiplies the half-space's exit factor.
    Rgb radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                 const Rgb& irradiance_here, const Rgb& exit_ratio = Rgb(1.0)) const;
    // The same at a point of local thickness `thickness` (SurfaceSampler::thickness): below
    // reflect_threshold() the slab's profiles (far_exitance_sided, the near field from R;
    // between the two thickness nodes around it, the same face's part linear in ln d, the
    // opposite face's geometric in d); up to transmit_threshold() the same where transmits()
    // (above reflect_threshold() a face reflects as the half-space's: a block whose far face is
    // dark takes its lookup, with `directional` its shifts); else exactly the call above.
    // (exit_ratio: the half-space's; on a slab, onto its lit face's own light, faded in with
    // the thickness from 4 to 8 transport mfp (half_space_share); the light through the far
    // face keeps the slab's exits.)
    // lights: the directions toward the lights at x (no shadow rays): a slab lookup takes each
    // face's incidence factor for them (slab_incidence).
    Rgb radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                 const Rgb& irradiance_here, double thickness, const Rgb& exit_ratio = Rgb(1.0),
                 const LightDirections& lights = LightDirections()) const;

    // At a point between reflect_threshold() and transmit_threshold() thick: whether the light
    // through its far face could exceed kSlabTolerance of its own face's (T_total at its
    // thickness times the cloud's brightest sample against R_total times its own E_t, in any
    // channel): a back-lit face, a shadowed one, a dark side.
    bool transmits(const PointCloud& cloud, double thickness, const Rgb& irradiance_here) const;
    // ... and at x (normal n): a sample of the far face within half the thickness of x - n d
    // is that bright (PointCloud::brighter_within); with `directional on`, also where the
    // surface about x is flat against the thickness (a sheet, not a ball: kDirectionalSlabCurvature).
    // `curvature`: where it took the mean curvature about x (over curved()'s window), it is
    // stored there for the lookup that follows.
    bool transmits(const PointCloud& cloud, const Vec3& x, const Vec3& n, double thickness,
                   const Rgb& irradiance_here, double* curvature = nullptr) const;

private:
    // The mean of the exit weight w over the near field of spacing h (its share of Rd, (1 -
    // window) Rd 2 pi r on [0, 3h]; 8-point Gauss-Legendre on [0, h/8], [h/8, h/2], [h/2, h]
    // and the ramp [h, 3h]): the factor of level_near's part.
    Rgb near_weight(const RadialWeight& w, double h) const;
    // The half-space's exit weight for a slab's own face (RadialProfile::exit_weight), faded in
    // per channel with the thickness d: whole from 8 transport mfp on, none below 4 (a thin
    // slab's exits spread otherwise). nullptr: no weight for any channel.
    const RadialWeight* slab_weight(double cos_o, double d, RadialWeight* w) const;
    // ... that fade per channel: 0 below 4 transport mfp, 1 from 8 on. It also takes the
    // half-space's oblique exits (exit_ratio) onto a slab face's own light.
    Rgb half_space_share(double d) const;
    // A slab's incidence factors over the half-space's (SlabProfiles::incidence; the samples'
    // light holds the half-space's) for the lights at x: on x's face (normal n) for the light
    // that entered there, on the opposite face (normal -n) for the light through it; each the
    // mean over the lights facing it weighted as the samples' light is (entry factor x cos),
    // faded to 1 as their largest cosine falls from kObliqueFade to 0 (past a terminator the
    // light entered elsewhere); 1 where no light faces a face or the profiles have none.
    // (The lights facing either face, with their weights: made once per lookup, read by both
    // thickness nodes.)
    class SlabLights {
    public:
        SlabLights(const RadialProfile& model, const Vec3& n, const LightDirections& lights);
        SlabLights(const SlabLights&) = delete;
        SlabLights& operator=(const SlabLights&) = delete;

    private:
        friend class Subsurface;
        struct Lit {
            double cos = 0;
            bool same = true;  // faces n (x's own face), else -n
            Rgb w;
        };
        static constexpr std::size_t kOnStack = 8;
        Lit stack_[kOnStack];
        std::vector<Lit> heap_;
        Lit* lit_ = stack_;
        std::size_t count_ = 0;
        double largest_[2] = {0, 0};
    };
    void slab_incidence(const SlabProfiles& p, const SlabLights& lights, Rgb* same, Rgb* opposite) const;
    // One thickness node's radiance at x (cos_o > 0), before interpolation: the node's
    // profiles on the geometry of x's own thickness (the opposite face's lateral distance is
    // taken across that thickness, not the node's); *opposite_part: the opposite face's part
    // of it. node_b (optional): the other node around the thickness, in the same traversal of
    // the cloud, into *result_b and *opposite_part_b.
    Rgb slab_radiance(const SlabCache::Node& node, const SlabCache::Node* node_b, const PointCloud& cloud, const Vec3& x,
                      const Vec3& n, double cos_o, double thickness, const Rgb& irradiance_here, int level,
                      std::size_t* visited, const RadialWeight* weight, const SlabLights& lights,
                      double flat, Rgb* opposite_part, Rgb* result_b, Rgb* opposite_part_b) const;
    Dipole dipole_;
    SubsurfaceSettings settings_;
    std::shared_ptr<const RadialProfile> model_;
    std::shared_ptr<const RdProfile> profile_;
    double reach_ = 0;  // radius holding 99 % of Rd: how far from the view refinement matters
    double slab_threshold_ = 0;
    double reflect_threshold_ = 0;  // <= slab_threshold_: a slab's R within kSlabTolerance of R_inf
    double transmit_threshold_ = 0;  // >= slab_threshold_
    bool slab_single_ = false;
    bool directional_ = false;  // the profile has entry shifts and settings.directional is on
    bool oblique_exits_ = false;  // the profile has oblique exits and settings.oblique_exits is on
    Rgb curvature_length_;      // settings.curvature: c(eta, alpha') mfp' per channel, else 0
    bool curving_ = false;      // some channel's curvature_length_ is not 0
    // The exitance m at x times 1 + curvature_length_ H (H from the cloud about x, in the window
    // of its base spacing, or of x's lookup level `level` where that is coarser).
    // (H: the mean curvature about x where the caller has taken it over the same window;
    // kNoCurvature: take it here.)
    static constexpr double kNoCurvature = -std::numeric_limits<double>::infinity();
    Rgb curved(const Rgb& m, const PointCloud& cloud, const Vec3& x, const Vec3& n, int level,
               double H = kNoCurvature) const;
    // ... for the mean curvature H about x, already taken.
    Rgb curved_by(const Rgb& m, double H) const;
    // The half-space's lookup (the public radiance() without a thickness), the curvature about x given where known.
    Rgb half_space(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                   const Rgb& irradiance_here, const Rgb& exit_ratio, double H) const;
    // The window (spacing) over which the curvature and the shift field's divergence are read
    // about a point of lookup level `level`: the base spacing's, whatever the level.
    static double curvature_window(const PointCloud& cloud, int level);
    // transmits(): the slab node of `thickness` where a far face's light is considered at all
    // (below transmit_threshold()); null elsewhere.
    const SlabProfiles* transmit_profiles(double thickness) const;
    std::unique_ptr<SlabCache> slabs_;  // thin geometry: null when off
    std::unique_ptr<const RandomWalk> walk_;  // method random_walk / auto: null otherwise
    mutable std::mutex auto_mutex_;
    mutable std::unordered_set<const void*> auto_counted_;  // method auto: objects in the statistics
    CloudCache clouds_;
    std::shared_ptr<const PointCloud> build(const ParallelFor& parallel, SurfaceSampler& sampler) const;
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
