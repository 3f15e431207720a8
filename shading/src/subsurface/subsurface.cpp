// The dipole subsurface finish: its settings, the profile's table, planning each object's
// sampling, and the lookup at a shaded point; see subsurface.h.
#include "shading/subsurface/subsurface.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "shading/core/quadrature.h"

namespace shading {

namespace {

// Thin geometry (slab.h): slabs within 0.5 % of the half-space are the half-space; thickness
// nodes from 0.01 transport mean free paths (thinner is taken as that).
constexpr double kSlabTolerance = 0.005;
// Thicker than slab_threshold, a slab's faces reflect as the half-space's (within
// kSlabTolerance) but may still pass light from one to the other: T / R_inf up to
// kSlabTolerance. Such a point's lookup takes the slab's profiles where its far face's light
// could matter (Subsurface::transmits): up to the thickness where T falls below this fraction of
// R_inf in every channel (a back light 40x the white point then shows less than one 8-bit step).
// Before: a back-lit Skin1 sheet of 16 mfp' (20.73 mm, its threshold 20.70) rendered -97 %.
constexpr double kTransmitFraction = 1e-4;
constexpr double kSlabMinMfp = 0.01;
// Directional lookups: the shift field's divergence undone (Subsurface::radiance) within this
// factor of 1, as the curvature's gain is bounded: a crease or a small bump is no sphere.
constexpr double kMaxShiftDivergence = 0.3;
// Directional lookups between the slab thresholds: a slab's where the surface about x is this
// flat against its thickness (|H| d; a sheet 0, a cylinder seen across 1, a ball 2).
constexpr double kDirectionalSlabCurvature = 0.5;

}  // namespace

Subsurface::Subsurface(const Medium& medium, const SubsurfaceSettings& settings, FdrModel fdr,
                       std::shared_ptr<const RadialProfile> model)
    : dipole_(medium, fdr), settings_(settings), model_(std::move(model)) {
    if (!(settings_.max_angle > 0 && settings_.max_angle <= 2.0))
        throw std::invalid_argument("dipole: error threshold must be in (0, 2], got " + std::to_string(settings_.max_angle));
    if (!(settings_.spacing >= 0) || !std::isfinite(settings_.spacing))
        throw std::invalid_argument("dipole: spacing must be >= 0 (0: automatic)");
    if (!model_) model_ = std::make_shared<const DipoleRadialProfile>(dipole_);
    profile_ = make_rd_profile(model_);
    reach_ = profile_->radius_containing(0.99);
    // Direction-aware: a profile that knows how far slanted light travels on inside.
    directional_ = settings_.directional && model_->entry_shift(0.5).max_component() > 0;
    oblique_exits_ = settings_.oblique_exits && model_->oblique_exits();
    if (settings_.curvature) {
        const Medium& m = dipole_.medium();
        const Rgb sp = m.sigma_s_prime(), st = sp + m.sigma_a;  // 1/mm
        for (int k = 0; k < 3; ++k)
            if (sp[k] > 0)  // (without scattering nothing leaves by the profile)
                curvature_length_[k] = curvature_coefficient(m.eta, sp[k] / st[k]) * curvature_anisotropy_weight(m.g[k]) /
                                       (st[k] * m.mm_per_unit);
        curving_ = curvature_length_[0] != 0 || curvature_length_[1] != 0 || curvature_length_[2] != 0;
    }
    // ... and then single scattering at each lookup, lit from upstream (single_scatter_upstream),
    // not by the light loop's BRDF
    if (settings_.single_scatter_points < 0 || settings_.single_scatter_points > kMaxSingleScatterPoints)
        throw std::invalid_argument("dipole: single_scatter_samples must be 0 (the half-space's formula) to " +
                                    std::to_string(kMaxSingleScatterPoints) + ", got " +
                                    std::to_string(settings_.single_scatter_points));
    // ... and so does single scattering traced in the object's shape
    if ((directional_ || settings_.single_scatter_points > 0) && settings_.method == SubsurfaceSettings::Method::Profile) {
        settings_.auto_single_scatter = settings_.single_scatter;
        settings_.single_scatter = false;
    }
    if (settings_.method != SubsurfaceSettings::Method::Profile || settings_.single_scatter_points > 0)
        walk_ = std::make_unique<const RandomWalk>(medium, settings_.walk);
    if (settings_.method == SubsurfaceSettings::Method::RandomWalk)
        return;  // no cloud, no slabs: the walk is exact in any geometry
    if (settings_.thin) {
        slab_threshold_ = shading::slab_threshold(dipole_, kSlabTolerance);
        reflect_threshold_ = std::min(slab_threshold_, shading::reflect_threshold(dipole_, kSlabTolerance));
        transmit_threshold_ = std::max(slab_threshold_, shading::transmit_threshold(dipole_, kTransmitFraction));
        const double d_min = kSlabMinMfp * mean_free_path();
        if (slab_threshold_ > d_min && d_min > 0) {
            // (auto_single_scatter holds it under `method auto` and with `directional on`, which
            // add it at each lookup; the BRDF's single_scatter else). A direction-aware lookup
            // too: its upstream single scattering is the half-space's, +109 % on the lit side of
            // a 0.25 mfp' Skin1 sheet without the slab's correction.
            const bool at_lookup = settings_.method == SubsurfaceSettings::Method::Auto || directional_;
            slab_single_ = !traced_single_scatter() &&
                           (at_lookup ? settings_.auto_single_scatter : settings_.single_scatter);
            const bool apart = traced_single_scatter() || slab_single_;
            slabs_ = std::make_unique<SlabCache>(d_min, transmit_threshold_,
                                                 [this, apart](double d) { return model_->slab_profiles(dipole_, d, apart); });
        } else {
            slab_threshold_ = reflect_threshold_ = transmit_threshold_ = 0;  // (a medium without scattering: nothing to do)
        }
    }
}

Subsurface::~Subsurface() = default;

double Subsurface::mean_free_path() const { return model_->mean_free_path(); }

bool Subsurface::auto_walks(const void* key, double extent) const {
    // unbounded objects (a plane: a half-space) have no cloud; the walk handles them
    const bool walk = !(extent < kInf) || extent < settings_.auto_lengths * diffusion_length();
    // the statistics count each object once; a thread's run of lookups on one object takes
    // no lock (the decision itself needs none: it is the object's size against the medium's)
    thread_local const Subsurface* last_owner = nullptr;
    thread_local const void* last_key = nullptr;
    if (last_owner != this || last_key != key) {
        last_owner = this;
        last_key = key;
        std::lock_guard<std::mutex> lock(auto_mutex_);
        if (auto_counted_.insert(key).second) random_walk_count_auto(walk);
    }
    return walk;
}

double Subsurface::diffusion_length() const {
    double l = 0;
    for (int c = 0; c < 3; ++c) {
        const DipoleChannel& ch = dipole_.channel(c);
        if (!ch.empty) l = std::max(l, ch.sigma_tr > 0 ? 1.0 / ch.sigma_tr : kInf);
    }
    return l;
}

double Subsurface::sample_spacing(double extent) const {
    if (settings_.spacing > 0) return settings_.spacing;
    double fine = 0.5 * mean_free_path();
    double cap = extent / std::max(1, settings_.max_lines);
    double h = std::max(fine, cap);
    return h > 0 ? h : 1.0;
}

Rgb Subsurface::single_scatter_shown() const {
    // At each lookup (method auto, directional, traced: auto_single_scatter holds the user's
    // switch, the constructor moved it there) or by the BRDF (single_scatter).
    const bool at_lookup =
        settings_.method != SubsurfaceSettings::Method::Profile || directional_ || settings_.single_scatter_points > 0;
    if (!(at_lookup ? settings_.auto_single_scatter : settings_.single_scatter)) return Rgb(0.0);
    // Lit straight on: 2 pi integral of f_ss(mu) mu dmu over the outside cosine, 4 panels of
    // 8-point Gauss-Legendre (f_ss is smooth in mu but for Fresnel's fall at grazing).
    const Vec3 wi(0.0, 0.0, 1.0);
    Rgb sum(0.0);
    for (int panel = 0; panel < 4; ++panel)
        for (int i = 0; i < 8; ++i) {
            const double mu = 0.25 * (panel + kGaussLegendre8UnitX[i]);
            const Vec3 wo(std::sqrt(std::max(0.0, 1.0 - mu * mu)), 0.0, mu);
            sum += dipole_.single_scatter_brdf(wo, wi) * (0.25 * kGaussLegendre8UnitW[i] * mu);
        }
    const double ft = fresnel_transmittance(1.0, dipole_.medium().eta);
    return ft > 0 ? sum * (2.0 * kPi / ft) : Rgb(0.0);
}

int Subsurface::refinement_levels(double h0) const {
    if (settings_.max_levels >= 0) return std::min(settings_.max_levels, 12);
    // Automatic: halve until the near field (the part of Rd taken from E_t at x alone, wrong by
    // up to half of it next to a shadow edge) holds at most edge_fraction of what every
    // channel reflects, at most 8 levels. What a channel reflects counts the single scattering
    // the pixel shows beside Rd: a low-albedo channel is mostly single scattering (Ketchup's
    // blue at ior 1.3: Rd 2.4e-5 of the light entering, single scattering 2.4e-3), and
    // resolving its tiny, short-ranged Rd to 5 % of itself drove Ketchup's clouds 3-4 levels
    // deeper than its red needs, for an error no pixel showed.
    const Rgb total = profile_->total() + single_scatter_shown();
    int k = 0;
    for (double h = h0; k < 8; h *= 0.5, ++k) {
        const Rgb near = profile_->near_reflectance(h);
        bool ok = true;
        for (int c = 0; c < 3; ++c)
            if (total[c] > 0 && near[c] > settings_.edge_fraction * total[c]) ok = false;
        if (ok) break;
    }
    return k;
}

const PointCloud& Subsurface::cloud(const void* key, SurfaceSampler& sampler) const {
    return clouds_.get(key, sampler,
                       [this](const ParallelFor& parallel, SurfaceSampler& s) { return build(parallel, s); });
}

std::shared_ptr<const PointCloud> Subsurface::build(const ParallelFor& parallel, SurfaceSampler& sampler) const {
    const auto t0 = std::chrono::steady_clock::now();
    CloudReport report;
    std::vector<SurfacePoint> points;
    Vec3 lo, hi;
    double h0 = 1.0;
    int levels = 0;
    if (sampler.bounds(&lo, &hi)) {
        const Vec3 len = hi - lo;
        const double extent = std::max({len.x, len.y, len.z});
        if (extent > 0 && std::isfinite(extent)) {
            h0 = sample_spacing(extent);
            levels = refinement_levels(h0);
            SamplingPlan plan;
            plan.view = sampler.view();
            // Where no part of the image is within reach, the base spacing may be coarser: those
            // samples only light visible points from beyond the reach (1 % of Rd), where a few
            // spacings of 1/4 the reach integrate Rd smoothly. At most 3 halvings, and at least
            // 16 spacings across the object.
            int coarse = 0;
            if (plan.view.kind != ViewVolume::Kind::Everywhere && settings_.max_levels != 0)
                while (coarse < 3 && h0 * std::ldexp(1.0, coarse + 1) <= 0.25 * reach_ &&
                       h0 * std::ldexp(1.0, coarse + 1) <= extent / 16)
                    ++coarse;
            plan.lo = lo;
            plan.hi = hi;
            plan.h0 = h0 * std::ldexp(1.0, coarse);
            plan.levels = levels + coarse;
            plan.view_levels = coarse;
            plan.tolerance = settings_.tolerance;
            plan.max_points = settings_.max_points;
            plan.mean_free_path = mean_free_path();
            plan.thickness = slab_threshold_ > 0;
            plan.reach = reach_;
            if (directional_)
                plan.incidence = [this](double cos_i, Rgb* entry, Rgb* shift) {
                    *entry = model_->entry_factor(cos_i);
                    *shift = model_->entry_shift(cos_i);
                };
            points = sample_surface(parallel, plan, &report);
        } else {
            report.unbounded = true;
        }
    } else {
        report.unbounded = true;
    }
    auto built = std::make_shared<PointCloud>(std::move(points), [this](double h) { return near_reflectance(h); },
                                              &parallel);
    built->set_view_spacing(h0);
    std::shared_ptr<const PointCloud> cloud = std::move(built);

    CloudRecord r;
    r.points = cloud->points().size();
    r.refined = report.refined;
    r.edge_means = report.edge_means;
    r.levels = report.levels;
    r.finest_spacing = cloud->stats().finest_spacing;
    r.unbounded = report.unbounded;
    r.slab_object = cloud->thinnest() < transmit_threshold_;  // (where it may take slab lookups)
    r.thin = !r.slab_object && report.thin && !(slab_threshold_ > 0);  // thin geometry off: the old warning
    if (r.slab_object) {
        r.thinnest = cloud->thinnest();
        r.thinnest_mfp = cloud->thinnest() / mean_free_path();
        r.finish_note = model_->slab_note();
    }
    const double L = diffusion_length();
    if (!report.unbounded && !cloud->points().empty() && report.extent < 3.0 * L)
        r.note = small_object_note(sampler.describe(), report.centre, report.extent, L, dipole_.medium().mm_per_unit,
                                   r.slab_object, cloud->thinnest());
    r.build_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count();
    record_cloud(r);
    return cloud;
}

namespace {

// single_scatter_upstream: the cloud's light along the line changes where some node's differs
// from x's by more than this fraction (a shadow's edge in reach; ...
constexpr double kUpstreamChange = 0.02;
// ... and x's face is flat over it where every normal within the line's weighted reach (3 of
// the longest channel's mean offsets) is within this angle, over the light's inside tangent, of
// x's: the cosine of incidence then changes along the line by under 1 %, and the light's
// visibility alone is the ratio of the light upstream to the light at x. (The mean curvature
// is no test of it: a saddle's is 0, and on the study's bumpy mesh the line's shadow rays left
// from inside the bumps.)
constexpr double kUpstreamFlat = 0.01;
// Bisections that locate a step of the light's visibility between two nodes of the line.
constexpr int kUpstreamBisections = 6;

// integral over [a, b] (in units of the mean offset) of e^-t times the linear interpolant of
// f0 at a and f1 at b
double exp_linear(double a, double b, double f0, double f1) {
    const double ea = std::exp(-a), eb = std::exp(-b), w = b - a;
    const double i0 = ea - eb;                      // integral e^-t
    const double i1 = (a + 1) * ea - (b + 1) * eb;  // integral t e^-t
    return (f0 * (b * i0 - i1) + f1 * (i1 - a * i0)) / w;
}

}  // namespace

Rgb Subsurface::single_scatter_upstream(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                                        const Vec3& to_light, const LightAlongLine* light) const {
    const double eta = dipole_.medium().eta;
    // inside tangent of a ray at outside cosine c, and the unit tangential direction its
    // refracted continuation travels along (away from the side it came from)
    auto inside = [&](const Vec3& w, double c, Vec3* t) {
        const Vec3 tan = n * c - w;
        const double len = length(tan);
        *t = len > 1e-12 ? tan * (1.0 / len) : Vec3(0, 0, 0);
        const double ci = std::max(1e-6, refracted_cos(c, eta));
        return std::pair<double, double>(std::sqrt(std::max(0.0, 1.0 - ci * ci)) / ci, ci);
    };
    const double co = std::clamp(dot(n, to_eye), 0.0, 1.0), cl = std::clamp(dot(n, to_light), 0.0, 1.0);
    Vec3 to, tl;
    const auto [tan_o, mu_o] = inside(to_eye, co, &to);
    const auto [tan_l, mu_l] = inside(to_light, cl, &tl);
    // the view's refracted ray goes down along `to`; the light that meets it at depth z entered
    // z tan_l back along its own travel
    const Vec3 D = to * tan_o - tl * tan_l;
    const Rgb st = dipole_.medium().sigma_t() * dipole_.medium().mm_per_unit;
    const double dlen = length(D);
    Rgb ratio(1.0);
    // mean single-scattering depth's offset per channel: z = 1 / (sigma_t (1/mu_o + 1/mu_l))
    double L[3], lmin = kInf, lmax = 0;
    for (int c = 0; c < 3; ++c) {
        L[c] = st[c] > 0 ? dlen / (st[c] * (1.0 / mu_o + 1.0 / mu_l)) : 0.0;
        if (L[c] > 0) lmin = std::min(lmin, L[c]), lmax = std::max(lmax, L[c]);
    }
    if (!(lmax > 0)) return ratio;
    // E_t along the upstream line at d_0 = 0 and geometric steps from lmin / 20 to 8 lmax, linear
    // between them (a shadow edge is a step: the exponential's average of it needs more than a
    // few nodes), integrated exactly against each channel's exponential e^(-d/L) / L.
    constexpr int kSteps = 10;
    double d[kSteps + 1];
    Rgb e[kSteps + 1];
    const Vec3 dir = D * (1.0 / dlen);
    d[0] = 0;
    e[0] = cloud.irradiance_about(x, cloud.level_spacing(cloud.lookup_level(x)));
    const double d1 = 0.05 * lmin, q = std::pow(8.0 * lmax / d1, 1.0 / (kSteps - 1));
    for (int j = 1; j <= kSteps; ++j) {
        d[j] = d1 * std::pow(q, j - 1);
        const Vec3 y = x + dir * d[j];
        e[j] = cloud.irradiance_about(y, cloud.level_spacing(cloud.lookup_level(y)));
    }
    // A shadow's edge on a flat face: the light's own visibility along the line (its colour
    // there over at x, per channel), each step between two nodes located by bisection; between
    // nodes where it does not step, linear.
    double step_at[kSteps];  // where the visibility steps from node j's to node j+1's; -1: linear
    bool visible = false;
    if (light) {
        bool changes = false;
        for (int j = 1; j <= kSteps && !changes; ++j)
            for (int c = 0; c < 3; ++c)
                if (std::fabs(e[j][c] - e[0][c]) > kUpstreamChange * e[0][c]) changes = true;
        if (changes && cloud.flat_within(x, n, 3.0 * lmax, std::cos(kUpstreamFlat / std::max(1.0, tan_l)))) {
            const Rgb& here = light->here;
            if (here.max_component() > 0) {
                visible = true;
                auto vis = [&](double t) {
                    const Rgb l = light->at(x + dir * t);
                    Rgb v;
                    for (int c = 0; c < 3; ++c) v[c] = here[c] > 0 ? l[c] / here[c] : 0.0;
                    return v;
                };
                e[0] = Rgb(1.0);
                for (int j = 1; j <= kSteps; ++j) e[j] = vis(d[j]);
                for (int j = 0; j < kSteps; ++j) {
                    step_at[j] = -1;
                    double jump = 0;
                    for (int c = 0; c < 3; ++c) jump = std::max(jump, std::fabs(e[j + 1][c] - e[j][c]));
                    if (!(jump > kUpstreamChange)) continue;
                    // the last point still like node j's, the first like node j+1's
                    double lo = d[j], hi = d[j + 1];
                    for (int b = 0; b < kUpstreamBisections; ++b) {
                        const double mid = 0.5 * (lo + hi);
                        const Rgb v = vis(mid);
                        double to_lo = 0, to_hi = 0;
                        for (int c = 0; c < 3; ++c) {
                            to_lo = std::max(to_lo, std::fabs(v[c] - e[j][c]));
                            to_hi = std::max(to_hi, std::fabs(v[c] - e[j + 1][c]));
                        }
                        (to_lo <= to_hi ? lo : hi) = mid;
                    }
                    step_at[j] = 0.5 * (lo + hi);
                }
            }
        }
    }
    for (int c = 0; c < 3; ++c) {
        if (!(e[0][c] > 0) || !(L[c] > 0)) continue;
        // integral of e^(-d/L)/L times the linear interpolant on [d_j, d_j+1] (or the step
        // located in it), the last value held beyond d_K
        double avg = 0;
        for (int j = 0; j < kSteps; ++j) {
            const double a = d[j] / L[c], b = d[j + 1] / L[c];
            if (visible && step_at[j] >= 0) {
                const double s = step_at[j] / L[c];
                avg += e[j][c] * (std::exp(-a) - std::exp(-s)) + e[j + 1][c] * (std::exp(-s) - std::exp(-b));
            } else {
                avg += exp_linear(a, b, e[j][c], e[j + 1][c]);
            }
        }
        avg += e[kSteps][c] * std::exp(-d[kSteps] / L[c]);
        // the part of the light upstream that is there: a shadow's visibility, never above 1
        // (where E_t rises upstream, as toward a lit face's centre, the BRDF at x already has
        // its own light; near a terminator E_t about x is ~0 and the ratio means nothing)
        ratio[c] = std::min(1.0, avg / e[0][c]);
    }
    return ratio;
}

const SlabProfiles& Subsurface::slab(double d) const {
    if (!slabs_) throw std::logic_error("Subsurface::slab: thin geometry is off");
    return slabs_->node(d).p;
}

namespace {

// A lit x with no lit sample within kUnresolvedSpacings spacings: the light at x fell between
// the samples, and the cloud carries none of it under the surface (counted for the statistics'
// warning: DIPOLE.md 10.7). Lit means above `tolerance` of the cloud's brightest sample (any
// light where the cloud has none). One small search per lit lookup (+0.05 % of a blob's
// instructions). Not for an empty cloud: an unbounded object, which has its own warning.
// At 3 spacings (the near field's outer edge), 2 of 15 000 lookups of the CSG difference in
// Skin1 (a concave edge) and 1 of the bumpy mesh in marble (a self-shadow's edge) counted, their
// nearest lit samples 3-4.5 spacings away: gaps along edges of the geometry or of the light,
// not a lit area the cloud missed.
constexpr double kUnresolvedSpacings = 8;
void check_resolved(const PointCloud& cloud, const Vec3& x, double h, const Rgb& irradiance_here, double tolerance) {
    const double e = irradiance_here.max_component();
    if (e > 0 && !cloud.points().empty() && e >= tolerance * cloud.max_irradiance() && !cloud.lit_within(x, kUnresolvedSpacings * h))
        count_unresolved(h, x);
}

// 1 + fade (num / den - 1) per channel, 1 where den is 0: the mean of a ratio over the lights
// facing a face (weights summed in den), faded to 1 as their largest cosine falls from
// kObliqueFade to 0 (at a terminator and past it the light at x entered elsewhere).
Rgb faded_ratio(const Rgb& num, const Rgb& den, double largest) {
    Rgb out(1.0);
    if (!(largest > 0)) return out;
    const double fade = std::min(1.0, largest / Subsurface::kObliqueFade);
    for (int c = 0; c < 3; ++c)
        if (den[c] > 0) out[c] = 1.0 + fade * (num[c] / den[c] - 1.0);
    return out;
}

}  // namespace

Rgb Subsurface::incidence_exit_ratio(const Vec3& n, const Vec3& to_eye, const Vec3* to_lights, std::size_t count) const {
    const double cos_o = dot(n, to_eye);
    if (!oblique_exits_ || !(cos_o > 0)) return Rgb(1.0);
    // the view's tangential direction (any at normal view: the tables' azimuths meet there)
    Vec3 t_o = to_eye - n * cos_o;
    const double lo = length(t_o);
    t_o = lo > 1e-9 ? t_o * (1.0 / lo) : Vec3(0.0, 0.0, 0.0);
    Rgb num(0.0), den(0.0);
    double largest = 0;
    for (std::size_t i = 0; i < count; ++i) {
        const double cos_i = dot(n, to_lights[i]);
        if (!(cos_i > 0)) continue;
        largest = std::max(largest, cos_i);
        // the entering beam travels away from the light: its tangential direction is -to_light's
        Vec3 t_i = n * cos_i - to_lights[i];
        const double li = length(t_i);
        const double cos_phi = li > 1e-9 && lo > 1e-9 ? dot(t_i, t_o) / li : 1.0;
        const Rgb w = model_->entry_factor(cos_i) * cos_i;
        num += w * model_->exit_factor_oblique(cos_i, cos_o, cos_phi);
        den += w;
    }
    if (!(largest > 0)) return Rgb(1.0);
    return faded_ratio(num, den * model_->exit_factor(cos_o), largest);  // over the normal exit factor
}

Rgb Subsurface::radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                         const Rgb& irradiance_here, const Rgb& exit_ratio) const {
    return half_space(cloud, x, n, to_eye, irradiance_here, exit_ratio, kNoCurvature);
}

Rgb Subsurface::half_space(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                           const Rgb& irradiance_here, const Rgb& exit_ratio, double H) const {
    const double cos_o = dot(n, to_eye);
    if (!(cos_o > 0)) return Rgb(0.0);
    std::size_t visited = 0;
    // The exit distribution's change with distance (DIPOLE.md 10.3, 10.7): Rd weighted per
    // distance for this view; the near field's part (within 3 h of x) by the weight's mean over
    // it (near_weight).
    RadialWeight weight;
    const RadialWeight* wt = model_->exit_weight(cos_o, &weight) ? &weight : nullptr;
    if (cloud.directional()) {
        // Light that entered at a slant leaves about its shifted entries: the near field is lit
        // by the irradiance upstream of x (PointCloud::far_exitance_shifted), not x's own.
        const int level = cloud.lookup_level_shifted(x);
        const double h = cloud.level_spacing(level), r0 = near_radius(h);
        check_resolved(cloud, x, h, irradiance_here, settings_.tolerance);
        Rgb upstream;
        Rgb m = cloud.far_exitance_shifted(*profile_, x, n, r0, h, settings_.max_angle, cutoff(), &upstream, &visited, wt);
        count_lookup(visited, false);
        m += upstream * cloud.level_near(level) * (wt ? near_weight(*wt, h) : Rgb(1.0));
        // Each entry's light leaves about images moved along its own tangent plane; on a curved
        // face those planes turn from point to point, so the shifts of neighbouring entries
        // differ even under one parallel light, and where they diverge (a convex face, every
        // shift pointing away from where the light falls straight) the images thin out: a
        // density (1 - div s) that the flat half-space's shift does not have (its field is
        // uniform) and that the profile's calibrated curvature term (6d) already holds. Undone
        // to first order: a Skin1 sphere of 3 diffusion lengths' radius lost 8.4 % of its flux
        // with the shifts, 4.6 % without, 1.7 % now (DIPOLE.md 6b). Over the base spacing's window, as the
        // curvature (the window follows x's own level, not the shifted lookup's).
        const int own = cloud.lookup_level(x);
        const Rgb div = cloud.shift_divergence_about(x, n, curvature_window(cloud, own));
        for (int k = 0; k < 3; ++k) m[k] *= 1.0 + std::clamp(div[k], -kMaxShiftDivergence, kMaxShiftDivergence);
        return curved(m, cloud, x, n, curving_ ? own : 0, H) * model_->exit_factor(cos_o) * exit_ratio;
    }
    const int level = cloud.lookup_level(x);
    const double h = cloud.level_spacing(level), r0 = near_radius(h);
    check_resolved(cloud, x, h, irradiance_here, settings_.tolerance);
    Rgb m = cloud.far_exitance(*profile_, x, r0, h, settings_.max_angle, cutoff(), &visited, wt);
    count_lookup(visited, false);
    m += irradiance_here * cloud.level_near(level) * (wt ? near_weight(*wt, h) : Rgb(1.0));
    return curved(m, cloud, x, n, level, H) * model_->exit_factor(cos_o) * exit_ratio;
}

Subsurface::SlabLights::SlabLights(const RadialProfile& model, const Vec3& n, const LightDirections& lights) {
    if (lights.count > kOnStack) heap_.resize(lights.count);
    lit_ = lights.count > kOnStack ? heap_.data() : stack_;
    for (std::size_t i = 0; i < lights.count; ++i) {
        const double c = dot(n, lights.to_light[i]);
        if (c == 0 || !std::isfinite(c)) continue;  // (in the face's plane: neither face's)
        Lit& l = lit_[count_++];
        l.same = c > 0;
        l.cos = std::fabs(c);
        l.w = model.entry_factor(l.cos) * l.cos;  // as the samples' light holds it
        largest_[l.same ? 0 : 1] = std::max(largest_[l.same ? 0 : 1], l.cos);
    }
}

void Subsurface::slab_incidence(const SlabProfiles& p, const SlabLights& lights, Rgb* same, Rgb* opposite) const {
    *same = *opposite = Rgb(1.0);
    if (!p.incidence) return;
    Rgb num[2], den[2];
    for (std::size_t i = 0; i < lights.count_; ++i) {
        const SlabLights::Lit& l = lights.lit_[i];
        const int side = l.same ? 0 : 1;
        num[side] += l.w * p.incidence(l.cos, l.same);
        den[side] += l.w;
    }
    *same = faded_ratio(num[0], den[0], lights.largest_[0]);
    *opposite = faded_ratio(num[1], den[1], lights.largest_[1]);
}

Rgb Subsurface::near_weight(const RadialWeight& w, double h) const {
    const double r0 = near_radius(h);
    Rgb num, den;
    static const double kParts[5] = {0.0, 0.125, 0.5, 1.0, 3.0};  // in h: the weight's steep start, the ramp
    for (int part = 0; part < 4; ++part) {
        const double a = kParts[part] * h, len = (kParts[part + 1] - kParts[part]) * h;
        for (int q = 0; q < 8; ++q) {
            const double r = a + len * kGaussLegendre8UnitX[q];
            const double f = kGaussLegendre8UnitW[q] * len * r * (1.0 - PointCloud::window(r, r0, h));
            const Rgb rd = profile_->rd(r) * f;
            num += rd * w.at(r);
            den += rd;
        }
    }
    Rgb out(1.0);
    for (int c = 0; c < 3; ++c)
        if (den[c] > 0) out[c] = num[c] / den[c];
    return out;
}

Rgb Subsurface::half_space_share(double d) const {
    Rgb s;
    for (int c = 0; c < 3; ++c) s[c] = std::clamp((d * dipole_.channel(c).sigma_t_prime - 4.0) / 4.0, 0.0, 1.0);
    return s;
}

const RadialWeight* Subsurface::slab_weight(double cos_o, double d, RadialWeight* w) const {
    if (!model_->exit_weight(cos_o, w)) return nullptr;
    bool any = false;
    const Rgb share = half_space_share(d);
    for (int c = 0; c < 3; ++c) {
        const double s = share[c];
        if (s < 1)
            for (int i = 0; i < w->nodes; ++i) w->w[i][c] = 1.0 + s * (w->w[i][c] - 1.0);
        any = any || s > 0;
    }
    return any ? w : nullptr;
}

double Subsurface::curvature_window(const PointCloud& cloud, int level) {
    return std::max(cloud.view_spacing(), cloud.level_spacing(level));
}

Rgb Subsurface::curved(const Rgb& m, const PointCloud& cloud, const Vec3& x, const Vec3& n, int level,
                       double H) const {
    if (!curving_) return m;  // (off, or c 0 in every channel: no need for H)
    if (H != kNoCurvature) return curved_by(m, H);  // (taken already, over the same window)
    // over the base spacing's window whatever the lookup's level: a refined level's smaller
    // window would give a curvature that steps where the level does. The base is the view's
    // (h0), or the lookup's level where the sampler coarsened it (out of the image's reach):
    // the cloud's coarsest spacing, up to 8 h0, would put 64x the points in the window of a
    // point in view (a block reaching far beyond the camera rendered 18x slower).
    return curved_by(m, cloud.mean_curvature_about(x, n, curvature_window(cloud, level)));
}

Rgb Subsurface::curved_by(const Rgb& m, double H) const {
    if (!curving_) return m;
    Rgb out = m;
    for (int k = 0; k < 3; ++k)
        out[k] *= 1.0 + std::clamp(curvature_length_[k] * H, -kMaxCurvatureGain, kMaxCurvatureGain);
    return out;
}

Rgb Subsurface::radiance(const PointCloud& cloud, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                         const Rgb& irradiance_here, double thickness, const Rgb& exit_ratio,
                         const LightDirections& lights) const {
    // From reflect_threshold() on, a face reflects as the half-space's: it takes the half-space's
    // lookup (with `directional`, its shifts) unless the far face's light could show
    // (transmits()). A block of a near-conservative medium, a slab up to several diffusion
    // lengths (Skimmilk's red: 81 mm at the 0.5 % tolerance on R and T, 39 mm on R alone), is
    // then lit as the half-space where nothing lights its far face: a shadow edge on 60 mm of it
    // under light at 45 degrees was 9-12 % of the plateau off with the slab's unshifted lookups.
    double known = kNoCurvature;  // (transmits() may take H, over the curvature's window)
    if (!(thickness < reflect_threshold_) && !transmits(cloud, x, n, thickness, irradiance_here, &known))
        return half_space(cloud, x, n, to_eye, irradiance_here, exit_ratio, known);
    const double cos_o = dot(n, to_eye);
    if (!(cos_o > 0)) return Rgb(0.0);
    // Between the two thickness nodes around it (SlabCache::around): the same face's part
    // linear in ln d; the opposite face's geometrically in d, as T falls (~ e^{-k d}: linear
    // interpolation of a Skin1 slab's blue T 12 mm thick, k d = 17, was +12 % between nodes).
    const SlabCache::Around slab = slabs_->around(thickness);
    const int level = cloud.lookup_level(x);
    // The surface's mean curvature about x (the curvature's window: curved()), for the
    // curvature term and for how flat a slab x's is: the slab's incidence factors are a flat
    // sheet's, lit where x is; on a ball (|H| d = 2) the light through it entered at every
    // incidence, and x's own says nothing of it (the balls of dipole_preset, two lights, against
    // the walk: 0.4-0.9 % more off with the factors taken whole). Faded out as |H| d goes to 1.
    const bool incident = lights.count > 0 && (slab.a->p.incidence || (slab.b && slab.b->p.incidence));
    const bool need_h = curving_ || incident;
    const double H = !need_h                ? 0.0
                     : known != kNoCurvature ? known
                                             : cloud.mean_curvature_about(x, n, curvature_window(cloud, level));
    const double flat = std::clamp(1.0 - std::fabs(H) * thickness, 0.0, 1.0);
    check_resolved(cloud, x, cloud.level_spacing(level), irradiance_here, settings_.tolerance);
    std::size_t visited = 0;
    RadialWeight weight;
    const RadialWeight* wt = slab_weight(cos_o, thickness, &weight);
    Rgb opposite, mb, opposite_b;
    const SlabLights lit(*model_, n, incident ? lights : LightDirections());
    Rgb m = slab_radiance(*slab.a, slab.b, cloud, x, n, cos_o, thickness, irradiance_here, level, &visited, wt, lit,
                          flat, &opposite, &mb, &opposite_b);
    // The exit distribution for the lights' incidence (exit_ratio, the half-space's) on this
    // face's own light, faded in with the thickness as the distance weight: the oblique exits
    // are the first orders' beneath the face, which a slab 8 transport mfp thick has as the
    // half-space does. (Without it a 60 mm block of Skimmilk, a slab for its 18 mm diffusion
    // length, read +6.4 % under light at 70 degrees, ior 1; DIPOLE.md 6e.)
    const Rgb share = half_space_share(thickness);
    Rgb ratio;
    for (int c = 0; c < 3; ++c) ratio[c] = 1.0 + share[c] * (exit_ratio[c] - 1.0);
    if (slab.b) {
        const double u = (thickness - slab.a->p.d) / (slab.b->p.d - slab.a->p.d);
        for (int c = 0; c < 3; ++c) {
            const double same = (m[c] - opposite[c]) * (1.0 - slab.t) + (mb[c] - opposite_b[c]) * slab.t;
            const double a = opposite[c], b = opposite_b[c];
            const double opp = a > 0 && b > 0 ? a * std::pow(b / a, u) : a * (1.0 - slab.t) + b * slab.t;
            m[c] = same * ratio[c] + opp;
        }
    } else {
        for (int c = 0; c < 3; ++c) m[c] = (m[c] - opposite[c]) * ratio[c] + opposite[c];
    }
    count_lookup(visited, true);
    return curved_by(m, H);
}

const SlabProfiles* Subsurface::transmit_profiles(double thickness) const {
    if (!(thickness < transmit_threshold_)) return nullptr;
    return &slabs_->node(thickness).p;
}

namespace {

// The far face's light could matter where T times its irradiance e_far is more than
// kSlabTolerance of the light this face reflects at x (`bound`, per channel), in some channel.
bool far_face_shows(const SlabProfiles& p, double e_far, const Rgb& bound) {
    for (int c = 0; c < 3; ++c)
        if (p.T_total[c] * e_far > bound[c]) return true;
    return false;
}

Rgb reflected_bound(const SlabProfiles& p, const Rgb& irradiance_here) {
    Rgb bound;
    for (int c = 0; c < 3; ++c) bound[c] = kSlabTolerance * p.R_total[c] * irradiance_here[c];
    return bound;
}

}  // namespace

bool Subsurface::transmits(const PointCloud& cloud, double thickness, const Rgb& irradiance_here) const {
    // The far face's light can be no brighter than the cloud's brightest sample. Where even that
    // could not show, the half-space's lookup differs from the slab's by less than
    // kSlabTolerance, and so does its R (within kSlabTolerance of R_inf at this thickness).
    const SlabProfiles* p = transmit_profiles(thickness);
    return p && far_face_shows(*p, cloud.max_irradiance(), reflected_bound(*p, irradiance_here));
}

bool Subsurface::transmits(const PointCloud& cloud, const Vec3& x, const Vec3& n, double thickness,
                           const Rgb& irradiance_here, double* curvature) const {
    // ... and does, where a sample of the far face (facing away from x's, within half the
    // thickness of the point across from x: T's reach) is bright enough. On a sphere lit from
    // one side, a lit point's far face is its dark side: no slab lookup there.
    const SlabProfiles* p = transmit_profiles(thickness);
    if (!p) return false;
    const Rgb bound = reflected_bound(*p, irradiance_here);
    if (!(far_face_shows(*p, cloud.max_irradiance(), bound) &&
          cloud.brighter_within(x - n * thickness, 0.5 * thickness, n * -1.0, p->T_total, bound)))
        return false;
    // With `directional on`, only where the object is a flat sheet about x (|H| d under
    // kDirectionalSlabCurvature; a ball's is 2): a slab lookup does not shift, and on a ball
    // whose diameter lies between the thresholds the dark side near the terminator lost the
    // shifted light it gets (a Skin1 sphere of 3 diffusion lengths: 10.4 -> 16.3 % pixel rms
    // against exact transport). A flat back-lit sheet there has no shifts to lose; with the
    // half-space's lookup its light through was lost (-88 % at 18 mm of sigma_s' 1, sigma_a 0.05).
    if (!directional_) return true;
    const double H = cloud.mean_curvature_about(x, n, curvature_window(cloud, cloud.lookup_level(x)));
    if (curvature) *curvature = H;
    return std::fabs(H) * thickness < kDirectionalSlabCurvature;
}

Rgb Subsurface::slab_radiance(const SlabCache::Node& node, const SlabCache::Node* node_b, const PointCloud& cloud,
                              const Vec3& x, const Vec3& n, double cos_o, double thickness, const Rgb& irradiance_here,
                              int level, std::size_t* visited, const RadialWeight* weight,
                              const SlabLights& lights, double flat, Rgb* opposite_part, Rgb* result_b,
                              Rgb* opposite_part_b) const {
    const double h = cloud.level_spacing(level), r0 = near_radius(h);
    Rgb near_same[2], near_opposite[2];
    node.near(h, &near_same[0], &near_opposite[0]);
    if (node_b) node_b->near(h, &near_same[1], &near_opposite[1]);
    Rgb m[2], opposite[2];
    std::size_t seen = 0;
    // Both nodes in one traversal of the cloud (the second's sums beside the first's).
    // rho across x's own thickness: with the node's (up to 9 % thinner) every point of a flat
    // far face would sit at least sqrt(thickness^2 - p.d^2) (0.42 thickness) off x's normal,
    // past T's peak: a back-lit Skin1 slab 8 mfp' thick rendered 7 / 12 / 23 % dark between nodes.
    const PointCloud::SecondProfiles second{node_b ? node_b->p.same.get() : nullptr,
                                            node_b ? node_b->p.transmit.get() : nullptr, near_opposite[1], &m[1],
                                            &opposite[1]};
    m[0] = cloud.far_exitance_sided(*node.p.same, *node.p.transmit, x, n, thickness, r0, h, settings_.max_angle,
                                    near_opposite[0], &seen, &opposite[0], weight, node_b ? &second : nullptr);
    *visited += seen;
    const Rgb near = irradiance_here * (weight ? near_weight(*weight, h) : Rgb(1.0));
    Rgb out[2];
    for (int k = 0; k < (node_b ? 2 : 1); ++k) {
        const SlabProfiles& p = (k == 0 ? node : *node_b).p;
        m[k] += near * near_same[k];
        // The exact slab tables: each face's own exit distribution (DIPOLE.md 6a), and its own
        // incidence factor for the lights at x.
        Rgb same_exit, opposite_exit;
        if (p.exit)
            p.exit(cos_o, &same_exit, &opposite_exit);
        else
            same_exit = opposite_exit = model_->exit_factor(cos_o);
        Rgb same_in, opposite_in;
        slab_incidence(p, lights, &same_in, &opposite_in);
        for (int c = 0; c < 3; ++c) {
            same_in[c] = 1.0 + flat * (same_in[c] - 1.0);
            opposite_in[c] = 1.0 + flat * (opposite_in[c] - 1.0);
        }
        const Rgb opp = opposite[k] * opposite_exit * opposite_in;
        out[k] = (m[k] - opposite[k]) * same_exit * same_in + opp;
        opposite[k] = opp;
    }
    *opposite_part = opposite[0];
    if (node_b) {
        *result_b = out[1];
        *opposite_part_b = opposite[1];
    }
    return out[0];
}

// ---------------------------------------------------------------- the surface part

DipoleSurfaceBrdf::DipoleSurfaceBrdf(std::shared_ptr<const Subsurface> s, BrdfPtr coat)
    : s_(std::move(s)), coat_(std::move(coat)) {
    if (!s_) throw std::invalid_argument("DipoleSurfaceBrdf: no subsurface");
}
Rgb DipoleSurfaceBrdf::f(const Vec3& wo, const Vec3& wi) const {
    Rgb v = s_->settings().single_scatter ? s_->dipole().single_scatter_brdf(wo, wi) : Rgb(0.0);
    if (coat_) v += coat_->f(wo, wi);
    return v;
}
std::string DipoleSurfaceBrdf::describe() const {
    return std::string("dipole(") + (s_->settings().single_scatter ? "single scattering" : "no single scattering") +
           (coat_ ? ", coat " + coat_->describe() : "") + ")";
}

}  // namespace shading
