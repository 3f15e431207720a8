// The dipole subsurface finish: irradiance sampled over an object's surface once per render,
// integrated against the dipole profile Rd with a hierarchical (octree) evaluation, in the
// spirit of Jensen & Buhler, "A Rapid Hierarchical Rendering Technique for Translucent
// Materials", SIGGRAPH 2002.
//
// What a renderer does with it (POV's adapter in patches/; nothing here knows POV types):
//  1. For each object whose finish has a Subsurface, once, on first use: sample points over the
//     object's surface (position, outward normal, area) and the Fresnel-transmitted irradiance
//     E_t at each, in POV's units (sum over lights of Ft(eta, cos_l) cos_l x light colour x
//     visibility: the light loop of a surface whose BRDF is transmittance_brdf()). Build the
//     PointCloud from them (Subsurface::cloud, thread-safe, once per object key).
//  2. At a shading point x seen from direction wo: pixel += Ft(eta, cos_o) M(x), where M(x),
//     the radiant exitance, is Jensen 2001's integral of Rd(|x - p|) E_t(p) over the surface.
//     Since POV's pixel is pi x radiance, this is L_o = (1/pi) Ft(wo) M. M splits at a window
//     w(r) that rises smoothly from 0 at R0 - h to 1 at R0 + h (h the sample spacing, R0 = 2h):
//       near: E_t(x) * integral of (1 - w(r)) Rd(r) 2 pi r dr   (the surface taken as flat
//             within R0 and lit like x: E_t(x) comes from the light loop at x itself);
//       far:  sum_i w(r_i) Rd(r_i) A_i E_t,i over the samples (hierarchically, PointCloud).
//     The near integral holds Rd's sharp peak (finite at r = 0, but ~1/r^3 for zr << r << 1/
//     sigma_tr): integrated analytically, not sampled, so nothing is regularised by hand and
//     there is no grid pattern for any spacing.
//  3. The single-scattering term is a BRDF (Dipole::single_scatter_brdf) lit by the ordinary
//     light loop: the finish model's brdf includes it.
// Lengths are scene units (Medium::mm_per_unit converts the published 1/mm coefficients).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "shading/brdf.h"
#include "shading/dipole.h"
#include "shading/radial_profile.h"

namespace shading {

// One surface sample: position and outward unit normal (scene units), the area it stands for,
// and the irradiance transmitted into the medium there (POV units, see above).
struct SurfacePoint {
    Vec3 p, n;
    double area = 0;
    Rgb irradiance;
};

// Rd(r) of a dipole per channel with its first two derivatives, tabulated once per medium on
// r = r_s (exp(t L) - 1), t uniform in [0, 1], L = ln(1 + r_max / r_s), r_s the smallest
// source depth zr: uniform within zr of the peak, logarithmic beyond (the same relative step
// everywhere along the exponential or, without absorption, power-law tail); linear between
// nodes; 0 beyond r_max. The octree's inner loop reads it instead of evaluating six
// exponentials per lookup. Relative error below 1e-4 wherever Rd > 1e-9 Rd(0)
// (SubsurfaceRdProfile test).
class RdProfile {
public:
    RdProfile(const Dipole& dipole, double r_max, int nodes = 16384);
    // Any per-channel profile rd(r) (radial_profile.h), r_s its smallest length scale.
    RdProfile(const std::function<Rgb(double)>& rd, double r_s, double r_max, int nodes = 16384);
    Rgb rd(double r) const;
    // Rd and its derivatives d/dr, d2/dr2 at r.
    void eval(double r, Rgb* f, Rgb* d1, Rgb* d2) const;
    double r_max() const { return r_max_; }

private:
    double index(double r) const { return std::log1p(r / r_s_) * inv_step_; }
    double r_max_, r_s_ = 1, inv_step_ = 1;
    std::vector<Rgb> f_, d1_, d2_;  // nodes + 1 samples each
};

struct CloudStats {
    std::size_t points = 0, nodes = 0;
    double total_area = 0;
};

// An octree over surface points with per-node aggregates (area, transmitted flux A E_t, and
// the flux-weighted centre) for the hierarchical sum.
class PointCloud {
public:
    // `spacing`: the distance between neighbouring samples h (sets the near/far split);
    // `near`: the dipole's reflectance inside the split (Subsurface::near_reflectance(h)).
    PointCloud(std::vector<SurfacePoint> points, double spacing, const Rgb& near = Rgb(0.0));
    double spacing() const { return spacing_; }
    const Rgb& near_reflectance() const { return near_; }

    // The far part of M(x): sum over points of w(r) Rd(r) A E_t per channel (window w of
    // NearField), with a node's aggregate used in place of its points when the node does not
    // contain x and its size seen from x is below `max_angle` (node diagonal / distance to its
    // centre), and nodes farther than `cutoff` (scene units) from x skipped. An aggregate is
    // the node's flux times Rd at its centre plus the second-order term of Rd's Taylor
    // expansion about the centre, (1/2) tr(H Sigma) with Sigma the node's covariance: the
    // error falls from O(angle^2) to O(angle^4). `visited` (optional) counts nodes opened.
    Rgb far_exitance(const RdProfile& rd, const Vec3& x, double r0, double h, double max_angle, double cutoff,
                     std::size_t* visited = nullptr) const;
    // The same sum over every point, no aggregation and no cutoff: the reference.
    Rgb far_exitance_exact(const Dipole& dipole, const Vec3& x, double r0, double h) const;

    // The window: 0 below r0 - h, 1 above r0 + h, smoothstep between.
    static double window(double r, double r0, double h);

    const std::vector<SurfacePoint>& points() const { return points_; }
    CloudStats stats() const;

private:
    struct Node {
        Vec3 lo, hi;         // bounds of the node's points
        Vec3 centre;         // flux-weighted (area-weighted if no flux) centre
        double cov[6] = {0, 0, 0, 0, 0, 0};  // the same weights' covariance: xx yy zz xy xz yz
        Rgb flux;            // sum of A E_t
        double area = 0;     // sum of A
        double diagonal = 0; // |hi - lo|
        int first = 0, count = 0;  // points_[first, first + count) (leaves)
        int child = -1;            // index of the first of `children` consecutive nodes, -1: leaf
        int children = 0;
    };
    void build(int index, int first, int count, int depth);
    double spacing_ = 0;
    Rgb near_;
    std::vector<SurfacePoint> points_;
    std::vector<Node> nodes_;
};

struct SubsurfaceSettings {
    double spacing = 0;        // sample spacing in scene units; 0: automatic (sample_spacing())
    double max_angle = 0.7;    // hierarchical error threshold (PointCloud::far_exitance)
    bool single_scatter = true;
    int max_lines = 200;       // automatic spacing: at most this many sample lines per bbox axis
};

// Counters for POV's statistics (process-wide, all subsurface finishes).
struct SubsurfaceStats {
    std::size_t clouds = 0, points = 0, lookups = 0, nodes_visited = 0;
    double build_seconds = 0;
    std::size_t unbounded = 0;  // objects that could not be sampled (no finite bounding box)
    std::size_t thin = 0;       // objects thinner than the mean free path in > 10 % of places
};
SubsurfaceStats subsurface_stats();
// The adapter reports these (they become warnings in the statistics).
void subsurface_note_unbounded();
void subsurface_note_thin();

// What one `dipole { }` finish holds: the medium, its settings, and the per-object clouds.
class Subsurface {
public:
    // Multiple scattering from the dipole (Jensen 2001) ...
    Subsurface(const Medium& medium, const SubsurfaceSettings& settings, FdrModel fdr = FdrModel::JensenFit);
    // ... or from another profile of the same medium (ExactProfile); the dipole stays for the
    // single-scattering BRDF.
    Subsurface(const Medium& medium, const SubsurfaceSettings& settings, std::shared_ptr<const RadialProfile> model);
    ~Subsurface();
    Subsurface(const Subsurface&) = delete;
    Subsurface& operator=(const Subsurface&) = delete;

    const Dipole& dipole() const { return dipole_; }
    const RdProfile& profile() const { return *profile_; }
    const RadialProfile& model() const { return *model_; }
    const SubsurfaceSettings& settings() const { return settings_; }

    // Sample spacing for an object whose bounding box has the given largest extent: the user's,
    // or the larger of half the smallest channel's mean free path 1/sigma_t' (finer gains
    // nothing: the near field within 2h is integrated analytically) and extent / max_lines
    // (bounds the point count; the shadow edges' resolution is then ~2h).
    double sample_spacing(double extent) const;
    // Rd is negligible (below 1e-6 of its integral) beyond this distance, every channel.
    double cutoff() const { return cutoff_; }
    // Smallest mean free path 1/sigma_t' over the channels (scene units): geometry thinner
    // than this is outside the dipole's assumptions (the adapter warns).
    double mean_free_path() const;

    // The cloud of the object `key`, built by `make_points` the first time (once, whichever
    // thread asks first; the others wait). make_points returns the samples and sets the
    // spacing it used. An empty result is kept too (nothing to scatter).
    const PointCloud& cloud(const void* key,
                            const std::function<std::vector<SurfacePoint>(double* spacing)>& make_points) const;

    // The near/far split of this finish for a cloud of spacing h: R0 = 2h.
    static double near_radius(double h) { return 2.0 * h; }
    // Integral of (1 - w(r)) Rd(r) 2 pi r dr per channel (dimensionless): the part of the
    // diffuse reflectance taken from the local irradiance (computed once per cloud).
    Rgb near_reflectance(double h) const;

    // pixel += radiance(...): exit_factor(cos_o) M(x) (RGB; the dipole's is Ft(eta, cos_o)) at x (normal n) on an object whose
    // cloud of spacing h is `cloud`, with E_t(x) the transmitted irradiance at x itself;
    // 0 when the viewer is below the surface.
    Rgb radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                 const Rgb& irradiance_here) const;

    // Handle of a finish model (finish.h registry) whose BRDF is entry_factor(cos_i) / pi (the
    // dipole's: Ft(eta, cos_i) / pi): lit by the renderer's light loop it yields the transmitted
    // irradiance E_t at a point.
    int transmittance_handle() const { return transmit_handle_; }

private:
    void init();
    Dipole dipole_;
    SubsurfaceSettings settings_;
    std::shared_ptr<const RadialProfile> model_;
    double cutoff_ = 0;
    std::unique_ptr<RdProfile> profile_;
    int transmit_handle_ = 0;
    struct Entry;
    mutable std::mutex mutex_;
    mutable std::map<const void*, std::shared_ptr<Entry>> entries_;
};

// Ft(eta, cos_i) / pi as a Brdf (wo ignored above the surface): the transmitted irradiance's
// light loop (Subsurface::transmittance_handle).
class TransmittanceBrdf final : public Brdf {
public:
    explicit TransmittanceBrdf(double eta) : eta_(eta) {}
    Rgb f(const Vec3& wo, const Vec3& wi) const override;
    std::string describe() const override;

private:
    double eta_;
};

// RadialProfile::entry_factor(cos_i) / pi as a Brdf (wo ignored above the surface): the
// transmitted irradiance's light loop of a profile other than the dipole.
class ProfileTransmittanceBrdf final : public Brdf {
public:
    explicit ProfileTransmittanceBrdf(std::shared_ptr<const RadialProfile> model) : model_(std::move(model)) {}
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
