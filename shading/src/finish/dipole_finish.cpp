// dipole finishes: a block's keywords into a Subsurface under the finish's coat, and the
// renderer's object behind the subsurface layer's SurfaceSampler.
#include "shading/finish/dipole_finish.h"

#include <cstdio>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "shading/core/random.h"
#include "shading/subsurface/media_presets.h"
#include "shading/subsurface/radial_profile.h"
#include "shading/subsurface/ss_profile.h"
#include "shading/subsurface/subsurface.h"

namespace shading {
namespace {

// A message for the user with one "dipole" in front (the library's own may carry it already).
std::string prefixed(const std::string& message) {
    return message.rfind("dipole", 0) == 0 ? message : "dipole: " + message;
}

// How the notes name a medium: its preset, or its coefficients.
std::string medium_name(const DipoleParams& p, const Medium& m) {
    auto rgb = [](const Rgb& c) {
        char buf[96];
        std::snprintf(buf, sizeof buf, "%g,%g,%g", c.r, c.g, c.b);
        return std::string(buf);
    };
    return p.preset.empty() ? "dipole medium sigma_s' " + rgb(m.sigma_s_prime()) + " sigma_a " + rgb(m.sigma_a)
                            : "dipole medium '" + p.preset + "'";
}

// The exact profile of `medium` from subsurface_profiles.ssp and, where found, the slab files
// (subsurface_slabs.ssp, g 0; subsurface_slabs_forward.ssp, g 0 to 0.95): without one that
// covers the medium thin objects use the multipole, and the statistics say so. A slab file is
// read only when the one before it does not cover the medium.
std::shared_ptr<const ExactProfile> exact_profile(const Medium& medium, const FindFile& find) {
    const char* name = "subsurface_profiles.ssp";
    std::unique_ptr<FoundFile> file = find(name);
    if (!file)
        throw std::invalid_argument(std::string("dipole: profile exact needs '") + name +
                                    "' on the library path (make brdf-data builds it into build/brdf_data), "
                                    "or not permitted by the I/O restrictions; write `profile dipole` to use the "
                                    "dipole without it.");
    auto load = [](const FoundFile& in, const char* file_name) {
        const std::int64_t size = in.size();
        if (size < 0 || size > (std::int64_t(1) << 30))  // a folder can read as 2^63 - 1
            throw ProfileError(std::string(file_name) + ": offset 0: expected a readable table file of at most 1 GiB");
        std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
        if (size > 0 && !in.read(bytes.data(), bytes.size()))
            throw ProfileError(std::string(file_name) + ": offset 0: expected " + std::to_string(size) + " bytes, read fewer");
        return load_profile_tables(bytes.data(), bytes.size(), file_name);
    };
    std::shared_ptr<const ExactProfile> profile;
    try {
        std::shared_ptr<const ProfileTables> tables =
            shared_profile_tables(file->key, [&]() { return load(*file, name); });
        auto slab_tables = [&](const char* slab_name) -> std::shared_ptr<const ProfileTables> {
            std::unique_ptr<FoundFile> slab_file = find(slab_name);
            if (!slab_file) return nullptr;
            return shared_profile_tables(slab_file->key, [&]() { return load(*slab_file, slab_name); });
        };
        std::shared_ptr<const ProfileTables> slabs = slab_tables(ExactProfile::kSlabFile), forward;
        profile = std::make_shared<const ExactProfile>(medium, tables, slabs);
        if (!profile->slab_tables()) {
            forward = slab_tables(ExactProfile::kForwardSlabFile);
            if (forward) profile = std::make_shared<const ExactProfile>(medium, tables, slabs, forward);
        }
    } catch (const std::exception& e) {
        throw std::invalid_argument(prefixed(e.what()));
    }
    return profile;
}

// The renderer's object as the subsurface layer's sampler.
class Sampler final : public SurfaceSampler {
public:
    explicit Sampler(DipoleObject& object) : object_(object) {}
    bool bounds(Vec3* lo, Vec3* hi) override { return object_.bounds(lo, hi); }
    void line_hits(int axis, const Vec3& origin, std::vector<Hit>* hits) override {
        found_.clear();
        object_.line_hits(axis, origin, &found_);
        for (const DipoleObject::Hit& h : found_) hits->push_back(Hit{h.t, h.p, h.n, h.lift});
    }
    void segment_hits(int axis, const Vec3& origin, double t0, double t1, std::vector<Hit>* hits) override {
        found_.clear();
        object_.segment_hits(axis, origin, t0, t1, &found_);
        for (const DipoleObject::Hit& h : found_) hits->push_back(Hit{h.t, h.p, h.n, h.lift});
    }
    Rgb irradiance(const Vec3& p, const Vec3& n) override { return object_.irradiance(p, n); }
    std::string describe() override { return object_.describe(); }
    ViewVolume view() override {
        const DipoleObject::CameraView c = object_.camera();
        ViewVolume v;
        v.kind = c.kind == DipoleObject::CameraView::Kind::Perspective    ? ViewVolume::Kind::Perspective
                 : c.kind == DipoleObject::CameraView::Kind::Orthographic ? ViewVolume::Kind::Orthographic
                                                                      : ViewVolume::Kind::Everywhere;
        v.location = c.location;
        v.direction = c.direction;
        v.right = c.right;
        v.up = c.up;
        v.lens = c.lens;
        return v;
    }
    double thickness(const Vec3& p, const Vec3& n) override { return object_.thickness(p, n); }
    int light_count() override { return object_.light_count(); }
    bool light_direction(int i, const Vec3& p, Vec3* l) override { return object_.light_direction(i, p, l); }
    Rgb light_colour(int i, const Vec3& p, const Vec3& n, const Vec3& l) override { return object_.light_colour(i, p, n, l); }

private:
    DipoleObject& object_;
    std::vector<DipoleObject::Hit> found_;
};

// The renderer's object as the random walk's scene.
class Walker final : public WalkScene {
public:
    explicit Walker(DipoleObject& object) : object_(object) {}
    bool leave(const Vec3& o, const Vec3& d, Hit* hit) override {
        DipoleObject::Hit h{};
        if (!object_.leave(o, d, &h)) return false;
        *hit = Hit{h.t, h.p, h.n};
        return true;
    }
    int light_count() override { return object_.light_count(); }
    bool light_direction(int i, const Vec3& p, Vec3* l) override { return object_.light_direction(i, p, l); }
    Rgb light_colour(int i, const Vec3& p, const Vec3& n, const Vec3& l) override { return object_.light_colour(i, p, n, l); }

private:
    DipoleObject& object_;
};

// The walks of a pixel are named by the shaded point: the same point, the same walks.
std::uint64_t point_seed(const Vec3& x) {
    std::uint64_t state = 0x5eed5eed5eedULL;
    for (double v : {x.x, x.y, x.z}) {
        std::uint64_t bits;
        std::memcpy(&bits, &v, sizeof bits);
        state ^= bits;
        state = splitmix64(state);
    }
    return state;
}

}  // namespace

void dipole_preset_check(const std::string& name) { (void)media_preset(name); }

std::shared_ptr<FinishModel> make_dipole_finish(const DipoleParams& p, const FinishModel* coat, const FindFile& find) {
    if (p.sigma_s && p.sigma_s_prime)
        throw std::invalid_argument("dipole: give sigma_s (with anisotropy) or sigma_s_prime, not both.");
    if (p.preset.empty() && !(p.sigma_s || p.sigma_s_prime))
        throw std::invalid_argument("dipole: expected a preset name or sigma_s / sigma_s_prime (1/mm).");
    if (p.preset.empty() && !p.sigma_a)
        throw std::invalid_argument("dipole: expected sigma_a (1/mm) with sigma_s / sigma_s_prime.");
    Medium medium;
    medium.sigma_s = medium.sigma_a = medium.g = Rgb(0.0);
    if (!p.preset.empty()) {
        try {
            medium = media_preset(p.preset);
        } catch (const std::exception& e) {
            throw std::invalid_argument(prefixed(e.what()));
        }
    }
    if (p.sigma_s) medium.sigma_s = *p.sigma_s;
    if (p.sigma_a) medium.sigma_a = *p.sigma_a;
    if (p.anisotropy) medium.g = *p.anisotropy;
    if (p.ior) medium.eta = *p.ior;
    // the scene's own scale unless the block gives one (global_settings mm_per_unit)
    medium.mm_per_unit = p.mm_per_unit ? *p.mm_per_unit : p.scene_mm_per_unit;
    if (p.sigma_s_prime) {
        // sigma_s' alone: an isotropic medium with that scattering (Jensen 2001's tables)
        medium.sigma_s = *p.sigma_s_prime;
        medium.g = Rgb(0.0);
    }
    SubsurfaceSettings settings;
    if (p.sample_spacing) settings.spacing = *p.sample_spacing;
    if (p.error_bound) settings.max_angle = *p.error_bound;
    if (p.refine_levels) settings.max_levels = *p.refine_levels;
    if (p.thin_geometry) settings.thin = *p.thin_geometry;
    // on by default (DIPOLE.md 6b): a shadow edge under light at 45-70 degrees is 10-53 % of the
    // plateau off with the radially symmetric profile, 2-6 % with the shifts (walk_bench, ior
    // 1.3); the library's own default stays off
    settings.directional = p.directional.value_or(true);
    if (p.samples) settings.walk.samples = *p.samples;
    if (p.single_scatter_samples) settings.single_scatter_points = *p.single_scatter_samples;
    if (p.method == DipoleParams::Method::RandomWalk) {
        // exact transport: nothing tabulated, single scattering is part of the walk
        settings.method = SubsurfaceSettings::Method::RandomWalk;
        settings.single_scatter = false;
        std::shared_ptr<const Subsurface> subsurface;
        try {
            subsurface = std::make_shared<const Subsurface>(medium, settings, FdrModel::JensenFit, nullptr);
        } catch (const std::exception& e) {
            throw std::invalid_argument(prefixed(e.what()));
        }
        return finish_model_with_subsurface(coat, subsurface);
    }
    std::shared_ptr<const ExactProfile> exact;
    if (p.exact_profile) exact = exact_profile(medium, find);
    std::shared_ptr<const RadialProfile> profile = exact;
    // the exact profile leaves single scattering to the BRDF; the dipole's Rd stands for it
    settings.single_scatter = p.single_scatter ? *p.single_scatter : p.exact_profile;
    // measured for the exact profile (curvature.h); the dipole keeps Jensen 2001's unless asked
    settings.curvature = p.curvature ? *p.curvature : p.exact_profile;
    if (p.method == DipoleParams::Method::Auto) {
        // walked objects have single scattering in the walk: the profile's objects get it at
        // each lookup (finish_subsurface_radiance), not from the BRDF the light loop adds
        settings.method = SubsurfaceSettings::Method::Auto;
        settings.auto_single_scatter = settings.single_scatter;
        settings.single_scatter = false;
    }
    auto subsurface = std::make_shared<const Subsurface>(medium, settings, FdrModel::JensenFit, profile);
    std::shared_ptr<FinishModel> model = finish_model_with_subsurface(coat, subsurface);
    if (exact)
        for (const std::string& note : exact->notes())
            model->notes.push_back(FinishNote{p.file, p.line, medium_name(p, medium) + ": " + note});
    if (p.single_scatter_samples && *p.single_scatter_samples > 0 && !subsurface->traced_single_scatter())
        model->notes.push_back(FinishNote{p.file, p.line,
                                          medium_name(p, medium) + ": single_scatter_samples has no effect: single "
                                          "scattering is off" +
                                              std::string(p.single_scatter ? " (single_scatter off)"
                                                                           : " (profile dipole leaves it off: its Rd "
                                                                             "stands for it; add single_scatter on to "
                                                                             "trace it)")});
    return model;
}

// (dipole_finish.h) A term below kSlabSingleNegligible of the half-space's single scattering
// for the same angles (a lit face's) is skipped with its shadow ray (the far face of a slab
// several mean free paths thick).
constexpr double kSlabSingleNegligible = 1e-6;

Rgb slab_single_scatter(const Subsurface& s, DipoleObject& object, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                        double d, const Rgb* upstream) {
    const Frame frame = Frame::from_normal(n);
    const Vec3 wo = frame.to_local(to_eye);
    if (!(wo.z > 0)) return Rgb(0.0);
    const Dipole& dipole = s.dipole();
    const Rgb apart = s.slab(d).t_single_apart;
    const bool through = apart.max_component() > 0;
    const Vec3 far = x - n * d;
    Rgb out(0.0);
    for (int i = 0, lights = object.light_count(); i < lights; i++) {
        Vec3 to_light;
        if (object.light_direction(i, x, &to_light) && dot(to_light, n) > 0) {
            const Vec3 wi = frame.to_local(to_light);
            const Rgb half = dipole.single_scatter_brdf(wo, wi);
            // (less than the half-space's where the far face cuts the depth short, more where it
            // reflects much back: thin, at eta > 1 and grazing angles)
            Rgb f = dipole.single_scatter_slab(wo, wi, d) - half;
            if (std::max({std::fabs(f.r), std::fabs(f.g), std::fabs(f.b)}) > kSlabSingleNegligible * half.max_component()) {
                if (upstream) f = f * upstream[i];
                out += object.light_colour(i, x, n, to_light) * f * (kPi * wi.z);
            }
        }
        if (through && object.light_direction(i, far, &to_light) && dot(to_light, n) < 0) {
            const Vec3 wi = frame.to_local(to_light);
            const Rgb f = dipole.single_scatter_slab(wo, wi, d) * apart;
            const double lit_face = dipole.single_scatter_brdf(wo, Vec3(wi.x, wi.y, -wi.z)).max_component();
            if (f.max_component() > kSlabSingleNegligible * lit_face)
                out += object.light_colour(i, far, n * -1.0, to_light) * f * (kPi * -wi.z);
        }
    }
    return out;
}

Rgb finish_subsurface_radiance(const FinishModel& model, const void* key, DipoleObject& object, const Vec3& x,
                               const Vec3& n, const Vec3& to_eye, const std::function<Rgb()>& here) {
    const Subsurface& subsurface = *model.subsurface;
    const SubsurfaceSettings& settings = subsurface.settings();
    const bool automatic = settings.method == SubsurfaceSettings::Method::Auto;
    const RandomWalk* walk = settings.method != SubsurfaceSettings::Method::Profile ? subsurface.walk() : nullptr;
    if (walk) {
        bool walked = !automatic;
        if (automatic) {
            Vec3 lo, hi;
            double extent = kInf;
            if (object.bounds(&lo, &hi)) extent = std::min({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
            walked = subsurface.auto_walks(key, extent);
        }
        if (walked) {
            Walker walker(object);
            return walk->radiance(walker, x, n, to_eye, point_seed(x));
        }
    }
    Sampler sampler(object);
    const PointCloud* cloud = nullptr;
    Rgb single(0.0);
    // Directional lookups: each light's upstream ratio, for the thin slab's correction below (a
    // scene's few lights on the stack; more on the heap).
    constexpr int kOnStack = 16;
    Rgb ratio_stack[kOnStack];
    std::vector<Rgb> ratio_heap;
    Rgb* ratios = nullptr;
    if (subsurface.traced_single_scatter()) {
        // single scattering along the view ray inside the object's own shape (any light
        // direction, curved faces, the back of a sheet): RandomWalk::single_scatter
        Walker walker(object);
        single = subsurface.walk()->single_scatter(walker, x, n, to_eye, settings.single_scatter_points, point_seed(x));
    } else if ((automatic || subsurface.directional()) && settings.auto_single_scatter) {
        // the single-scattering BRDF of a half-space, lit by every light as the light loop would;
        // with a direction-aware profile, times the light upstream over the light at x
        // (Subsurface::single_scatter_upstream)
        const Frame frame = Frame::from_normal(n);
        const Vec3 wo = frame.to_local(to_eye);
        const bool upstream = subsurface.directional();
        if (upstream) {
            cloud = &subsurface.cloud(key, sampler);
            const int count = object.light_count();
            ratios = count <= kOnStack ? ratio_stack : (ratio_heap.resize(std::size_t(count)), ratio_heap.data());
            std::fill(ratios, ratios + count, Rgb(1.0));
        }
        for (int i = 0, lights = object.light_count(); i < lights; i++) {
            Vec3 to_light;
            if (!object.light_direction(i, x, &to_light)) continue;
            const double cos_i = dot(to_light, n);
            if (!(cos_i > 0)) continue;
            Rgb f = subsurface.dipole().single_scatter_brdf(wo, frame.to_local(to_light));
            if (!(f.max_component() > 0)) continue;
            const Rgb lit = object.light_colour(i, x, n, to_light);
            if (!(lit.max_component() > 0)) continue;  // in this light's shadow: nothing from upstream either
            if (upstream) {
                // the light's own visibility upstream, where a shadow's edge is in reach
                struct Along final : LightAlongLine {
                    DipoleObject& object;
                    int i;
                    const Vec3 &n, &to_light;
                    Along(DipoleObject& o, int light, const Vec3& normal, const Vec3& l, const Rgb& at_x)
                        : object(o), i(light), n(normal), to_light(l) {
                        here = at_x;
                    }
                    Rgb at(const Vec3& y) const override { return object.light_colour(i, y, n, to_light); }
                } along(object, i, n, to_light, lit);
                f = f * (ratios[i] = subsurface.single_scatter_upstream(*cloud, x, n, to_eye, to_light, &along));
            }
            single += lit * f * (kPi * cos_i);
        }
    }
    if (!cloud) cloud = &subsurface.cloud(key, sampler);
    const Rgb e = here();
    // the point's own thickness, one ray, only where the object is thinner than the finish's
    // slab threshold somewhere, or could pass light through to here from its other face
    // (thick objects and lit faces of thick-ish ones: infinity, no ray)
    const double thickness = subsurface.wants_thickness(*cloud, e) ? object.thickness(x, n)
                                                                : std::numeric_limits<double>::infinity();
    if (thickness < subsurface.slab_threshold() && subsurface.slab_single_at_lookup())
        single += slab_single_scatter(subsurface, object, x, n, to_eye, thickness, ratios);
    // The lights' directions at x (no shadow rays): the exit distribution for their incidence,
    // and on a slab each face's incidence factor (a scene's few lights on the stack; more on
    // the heap).
    Rgb exit_ratio(1.0);
    Vec3 stack[kOnStack];
    std::vector<Vec3> heap;
    LightDirections lights;
    if (subsurface.oblique_exits() || thickness < subsurface.transmit_threshold()) {
        const int count = object.light_count();
        Vec3* to_lights = count <= kOnStack ? stack : (heap.resize(std::size_t(count)), heap.data());
        for (int i = 0; i < count; i++)
            if (object.light_direction(i, x, &to_lights[lights.count])) ++lights.count;
        lights.to_light = to_lights;
        if (subsurface.oblique_exits()) exit_ratio = subsurface.incidence_exit_ratio(n, to_eye, to_lights, lights.count);
    }
    return subsurface.radiance(*cloud, x, n, to_eye, e, thickness, exit_ratio, lights) + single;
}

std::vector<std::string> finish_statistics() {
    std::vector<std::string> lines;
    char buf[512];
    auto line = [&](const char* format, auto... args) {
        std::snprintf(buf, sizeof buf, format, args...);
        lines.push_back(buf);
    };
    const SubsurfaceStats ss = subsurface_stats();
    if (ss.clouds > 0) {
        line("Dipole objects:     %15.0f         Points: %10.0f", double(ss.clouds), double(ss.points));
        line("Dipole precompute:  %15.3f seconds", ss.build_seconds);
        if (ss.edge_means > 0)
            line("Dipole light edges: %15.0f samples at their cells' mean irradiance", double(ss.edge_means));
        if (ss.max_levels > 0) {
            line("Dipole refinement:  %15d levels  Points: %10.0f", ss.max_levels, double(ss.refined_points));
            line("Dipole finest spacing: %12g units", ss.finest_spacing);
        }
        line("Dipole lookups:     %15.0f         Nodes/lookup: %6.1f", double(ss.lookups),
             ss.lookups > 0 ? double(ss.nodes_visited) / double(ss.lookups) : 0.0);
        if (ss.unbounded > 0)
            line("Dipole warning: %.0f object(s) without a finite bounding box got no subsurface light", double(ss.unbounded));
        if (ss.thin > 0)
            line("Dipole warning: %.0f object(s) thinner than the mean free path in places; the dipole assumes a thick medium",
                 double(ss.thin));
        if (ss.slab_objects > 0) {
            line("Dipole thin geometry: %.0f object(s) thinner than a half-space in places;", double(ss.slab_objects));
            line("  thinnest %g units = %.3g mean free paths: slab profiles in %.0f lookups", ss.thinnest, ss.thinnest_mfp,
                 double(ss.slab_lookups));
        }
        if (ss.unresolved_lookups > 0) {
            // (POV wraps statistics at 80 columns: short lines)
            line("Dipole warning: %.0f lit points with no lit sample within 8 spacings", double(ss.unresolved_lookups));
            line("  (%g units), one at <%.4g, %.4g, %.4g>:", ss.unresolved_spacing, ss.unresolved_at.x,
                 ss.unresolved_at.y, ss.unresolved_at.z);
            lines.push_back("  a lit area smaller than the sample spacing gets no light under the");
            lines.push_back("  surface around it. Give sample_spacing a quarter of the lit area's");
            lines.push_back("  size or less.");
        }
        const std::size_t shown = 10;  // per-object warnings (small objects): the first few, then a count
        for (std::size_t i = 0; i < ss.notes.size() && i < shown; i++) lines.push_back(ss.notes[i]);
        if (ss.notes.size() > shown)
            line("Dipole warning: %.0f more object(s) smaller than 3 diffusion lengths", double(ss.notes.size() - shown));
    }
    const WalkStats ws = random_walk_stats();
    if (ws.auto_walked + ws.auto_profiled > 0)
        line("Dipole method auto: %.0f walked, %.0f by profile (walk: < %g diffusion lengths)", double(ws.auto_walked),
             double(ws.auto_profiled), SubsurfaceSettings().auto_lengths);
    if (ws.single_points > 0)
        line("Dipole traced single scattering: %8.0f points (single_scatter_samples)", double(ws.single_points));
    if (ws.walks > 0) {
        line("Dipole random walks: %14.0f         Vertices/walk: %7.1f", double(ws.walks), double(ws.vertices) / double(ws.walks));
        line("Dipole walk lights: %15.0f paths (next-event estimates)", double(ws.light_paths));
        if (ws.truncated > 0)
            line("Dipole warning: %.0f walk(s) stopped at %d vertices (a medium that almost never absorbs)",
                 double(ws.truncated), WalkSettings().max_vertices);
    }
    const SharedTableStats bt = shared_table_stats();
    if (bt.peak_tables > 0) {
        line("BRDF tables:        %15.0f         Files read: %6.0f  Shared: %6.0f", double(bt.peak_tables), double(bt.loads),
             double(bt.reuses));
        line("BRDF table memory:  %15.0f bytes", double(bt.peak_bytes));
        if (bt.peak_sampler_bytes > 0) line("BRDF sampling data: %15.0f bytes", double(bt.peak_sampler_bytes));
    }
    return lines;
}

}  // namespace shading
