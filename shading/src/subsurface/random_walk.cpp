// Random-walk subsurface transport: see random_walk.h and shading/DIPOLE.md, "Random walk".
#include "shading/subsurface/random_walk.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "shading/brdf/fresnel.h"
#include "shading/core/random.h"

namespace shading {
namespace {

// The step in u (radians near the solution) of the forward differences that give a beam's
// focusing, and the cap of that factor at a caustic.
constexpr double kFocusStep = 3e-4;
constexpr double kMaxFocus = 100.0;
// The least survival probability of a beam's roulette before its solve (beam_path).
constexpr double kMinBeamKeep = 0.1;
// single_scatter: a mirrored beam predicted weaker than this (times the beam's strength) is
// followed by roulette.
constexpr double kSingleMirrorFloor = 1e-4;

std::atomic<std::uint64_t> g_walks{0}, g_vertices{0}, g_light_paths{0}, g_truncated{0}, g_auto_walked{0},
    g_auto_profiled{0}, g_single_points{0};

Rgb exp_neg(const Rgb& sigma, double t) {
    return Rgb(std::exp(-sigma.r * t), std::exp(-sigma.g * t), std::exp(-sigma.b * t));
}

// The channel whose share of `q` (non-negative, positive sum `total`) contains u in [0, 1).
int pick_channel(const Rgb& q, double total, double u) {
    const double x = u * total;
    if (x < q.r) return 0;
    if (x < q.r + q.g) return 1;
    return q.b > 0 ? 2 : (q.g > 0 ? 1 : 0);
}

}  // namespace

WalkStats random_walk_stats() {
    WalkStats s;
    s.walks = g_walks.load(std::memory_order_relaxed);
    s.vertices = g_vertices.load(std::memory_order_relaxed);
    s.light_paths = g_light_paths.load(std::memory_order_relaxed);
    s.truncated = g_truncated.load(std::memory_order_relaxed);
    s.auto_walked = g_auto_walked.load(std::memory_order_relaxed);
    s.auto_profiled = g_auto_profiled.load(std::memory_order_relaxed);
    s.single_points = g_single_points.load(std::memory_order_relaxed);
    return s;
}

void random_walk_count_auto(bool walked) { (walked ? g_auto_walked : g_auto_profiled).fetch_add(1, std::memory_order_relaxed); }

Vec3 sample_henyey_greenstein(const Vec3& axis, double g, double u1, double u2) {
    double c;
    if (std::fabs(g) < 1e-3) {
        c = 1.0 - 2.0 * u1;
    } else {
        // inverse of the HG cosine CDF
        const double s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u1);
        c = (1.0 + g * g - s * s) / (2.0 * g);
    }
    c = std::clamp(c, -1.0, 1.0);
    const double sn = std::sqrt(std::max(0.0, 1.0 - c * c)), phi = 2.0 * kPi * u2;
    const Frame f = Frame::from_normal(axis);
    return normalize(f.t * (sn * std::cos(phi)) + f.b * (sn * std::sin(phi)) + axis * c);
}

bool refract_into(const Vec3& d, const Vec3& n, double eta, Vec3* t) {
    const double cos_i = -dot(d, n);  // > 0: d goes against n
    const double sin2_t = std::max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) return false;
    const double cos_t = std::sqrt(1.0 - sin2_t);
    *t = normalize(d * (1.0 / eta) + n * (cos_i / eta - cos_t));
    return true;
}

RandomWalk::RandomWalk(const Medium& medium, const WalkSettings& settings) : settings_(settings) {
    const std::string problem = medium.validate();
    if (!problem.empty()) throw std::invalid_argument(problem);
    for (int c = 0; c < 3; c++)
        if (!(std::fabs(medium.g[c]) < 1.0))
            throw std::invalid_argument("random walk: anisotropy must be inside (-1, 1), found " +
                                        std::to_string(medium.g[c]));
    if (settings.samples < 1) throw std::invalid_argument("random walk: samples must be at least 1");
    eta_ = medium.eta;
    guide_ = settings.guide_g >= 0 && std::max({medium.g.r, medium.g.g, medium.g.b}) > settings.guide_g;
    probe_ = guide_ && settings.probe && medium.g.r == medium.g.g && medium.g.g == medium.g.b;
    sigma_s_ = medium.sigma_s_per_unit();
    sigma_t_ = sigma_s_ + medium.sigma_a_per_unit();
    g_ = medium.g;
}

bool RandomWalk::beam_path(WalkScene& scene, int light, const Vec3& v, int reflections, Vec3 w, BeamPath* out,
                           double floor, std::uint64_t& state) const {
    constexpr int kMax = 4;
    // One evaluation of F: from v along w, mirrored at `reflections` faces, to the face where
    // the light enters; *next: the light's direction back at v, reversed (F(w)). The first
    // evaluation also decides the roulette of a weak mirrored beam (out->keep).
    struct Eval {
        WalkScene::Hit h{};
        Vec3 to_light, dir, next;  // dir: the last leg's direction at the entry
        double length = 0, mirror = 1;
    };
    bool first = true;
    auto evaluate = [&](const Vec3& wv, Eval* e) {
        Vec3 normals[kMax];
        Vec3 o = v;
        e->dir = wv;
        e->length = 0;
        e->mirror = 1;
        for (int j = 0; j < reflections; j++) {
            if (!scene.leave(o, e->dir, &e->h)) return false;
            const double c = dot(e->dir, e->h.n);
            if (!(c > 0)) return false;
            e->length += e->h.t;
            e->mirror *= fresnel_dielectric(c, 1.0 / eta_);
            if (j == 0 && first) {
                // a reflected beam that would arrive weaker than `floor` in every channel is
                // followed by roulette (unbiased): a deep vertex's mirrored light is negligible
                const double target = e->mirror * exp_neg(sigma_t_, e->length).max_component() / floor;
                if (target < out->keep) {
                    if (!(uniform_double(splitmix64(state)) * out->keep < target)) return false;
                    out->keep = target;
                }
            }
            normals[j] = e->h.n;
            e->dir = normalize(e->dir - e->h.n * (2.0 * c));
            o = e->h.p;
        }
        first = false;
        if (!scene.leave(o, e->dir, &e->h)) return false;
        e->length += e->h.t;
        Vec3 along;  // at the entry point: the refracted beam
        if (!scene.light_direction(light, e->h.p, &e->to_light)) return false;
        if (!(dot(e->to_light, e->h.n) > 0)) return false;  // the light is behind the face it would enter
        if (eta_ == 1.0)
            along = -e->to_light;
        else if (!refract_into(-e->to_light, e->h.n, eta_, &along))
            return false;
        // the beam back to v: mirrored at the same faces in the opposite order
        for (int j = reflections - 1; j >= 0; j--) along = normalize(along - normals[j] * (2.0 * dot(along, normals[j])));
        e->next = -along;
        return true;
    };
    // The fixed point w = F(w) by Broyden's method in the plane of the first guess:
    // w(u) = normalize(w0 + u0 e1 + u1 e2), G(u) = P(F(w(u))) - u with P the central projection
    // onto that plane. Its first step is the plain iteration w = F(w) (H = -I), exact in one step
    // on a flat face; on a curved face the plain iteration contracts only by ~(1 - 1/eta)
    // length / radius per step, and where it reached the limit of steps the light was dropped
    // (a Marble sphere of 9 mm: 59 % of the beams, 2.5-3.4 % of the pixels' light); Broyden's
    // secant updates converge superlinearly instead.
    const Vec3 w0 = w;
    const Frame plane = Frame::from_normal(w0);
    auto residual = [&](const Eval& e, const double uu[2], double G[2]) {
        const double c0 = dot(e.next, w0);
        if (!(c0 > 1e-3)) return false;  // F turned the guess by ~90 degrees or more: no entry near it
        G[0] = dot(e.next, plane.t) / c0 - uu[0];
        G[1] = dot(e.next, plane.b) / c0 - uu[1];
        return true;
    };
    auto at = [&](const double uu[2]) { return normalize(w0 + plane.t * uu[0] + plane.b * uu[1]); };
    double u[2] = {0, 0}, u_last[2] = {0, 0}, g_last[2] = {0, 0};
    double H[2][2] = {{-1, 0}, {0, -1}};  // inverse Jacobian estimate of G
    bool have_last = false;
    for (int step = 0; step < settings_.fixed_point_steps; step++) {
        Eval e;
        if (!evaluate(w, &e)) return false;
        double G[2];
        if (!residual(e, u, G)) return false;
        if (step == 0 && floor > 0) {
            // Roulette before the solve (the solve, ~6 evaluations, is most of a deep vertex's
            // cost), from the first evaluation's path: the direct beam's length predicted
            // along the refracted direction F(w) to the entry's tangent plane (exact on a flat
            // face), a mirrored beam's as its first guess ran, times its reflectances. Kept
            // with probability bound / floor (a mirrored beam may already have been, after its
            // first leg), never below kMinBeamKeep here, so that a prediction too long (a
            // curved face) cannot give a surviving beam a large weight.
            const double along = dot(e.next, e.h.n), depth = dot(e.h.p - v, e.h.n);
            const double predicted = reflections == 0 && along > 0 && depth > 0 ? std::min(depth / along, e.length)
                                                                                  : e.length;
            const double bound = e.mirror * exp_neg(sigma_t_, predicted).max_component();
            out->bound = bound;
            const double target = bound < floor ? std::max(bound / floor, kMinBeamKeep) : 1.0;
            if (target < out->keep) {
                if (!(uniform_double(splitmix64(state)) * out->keep < target)) return false;
                out->keep = target;
            }
        }
        if (dot(e.next, w) > 1.0 - 1e-12) {
            // The beam's focusing (DIPOLE.md, random walk): the light entering over dA at the
            // entry crosses v through dA_perp = t^2 |det J_G| dw (its offset at v is -t G), while
            // dA = t^2 dw / cos_t: irradiance across the beam E cos_i (1 - F) / (cos_t |det J_G|).
            // A flat face: J_G = -I. J_G by one-sided differences in u (the other side where a
            // step leaves the face, at a silhouette).
            double J[2][2];
            for (int k = 0; k < 2; k++) {
                bool done = false;
                for (double delta : {kFocusStep, -kFocusStep}) {
                    double uk[2] = {u[0], u[1]};
                    uk[k] += delta;
                    Eval ek;
                    double Gk[2];
                    if (!evaluate(at(uk), &ek) || !residual(ek, uk, Gk)) continue;
                    J[0][k] = (Gk[0] - G[0]) / delta;
                    J[1][k] = (Gk[1] - G[1]) / delta;
                    done = true;
                    break;
                }
                if (!done) return false;
            }
            const double det = std::fabs(J[0][0] * J[1][1] - J[0][1] * J[1][0]);
            if (!std::isfinite(det)) return false;
            out->entry = e.h;
            out->to_light = e.to_light;
            out->w = w;
            out->length = e.length;
            out->mirror = e.mirror;
            out->cos_t = std::max(0.0, dot(e.dir, e.h.n));
            // a caustic (det -> 0) is integrable but has no variance bound: capped
            out->focus = std::min(kMaxFocus, det > 0 ? 1.0 / det : kMaxFocus);
            return true;
        }
        if (have_last) {
            // good Broyden, inverse form: H += (du - H dG) (du^T H) / (du^T H dG)
            const double du[2] = {u[0] - u_last[0], u[1] - u_last[1]}, dG[2] = {G[0] - g_last[0], G[1] - g_last[1]};
            const double HdG[2] = {H[0][0] * dG[0] + H[0][1] * dG[1], H[1][0] * dG[0] + H[1][1] * dG[1]};
            const double duH[2] = {du[0] * H[0][0] + du[1] * H[1][0], du[0] * H[0][1] + du[1] * H[1][1]};
            const double den = du[0] * HdG[0] + du[1] * HdG[1];
            if (std::fabs(den) > 1e-300)
                for (int i = 0; i < 2; i++)
                    for (int j = 0; j < 2; j++) H[i][j] += (du[i] - HdG[i]) * duH[j] / den;
        }
        u_last[0] = u[0];
        u_last[1] = u[1];
        g_last[0] = G[0];
        g_last[1] = G[1];
        have_last = true;
        u[0] -= H[0][0] * G[0] + H[0][1] * G[1];
        u[1] -= H[1][0] * G[0] + H[1][1] * G[1];
        w = at(u);
    }
    return false;
}

Rgb RandomWalk::next_event(WalkScene& scene, const Vec3& v, const Vec3& d, const Rgb& beta, double floor,
                           double mirror_floor, std::uint64_t& state, Vec3* guide, bool* has_guide) const {
    Rgb sum(0.0);
    double strongest = 0;
    const int lights = scene.light_count();
    const int reflections = eta_ == 1.0 ? 0 : std::min(settings_.beam_reflections, 4);
    for (int i = 0; i < lights; i++) {
        Vec3 to_light;
        if (!scene.light_direction(i, v, &to_light)) continue;
        Vec3 beam_dir = -to_light;  // where the beam goes inside, roughly: the first guess of each path
        double direct = 1.0;        // the direct beam's predicted attenuation (beam_path's first evaluation)
        for (int k = 0; k <= reflections; k++) {
            BeamPath b;
            if (k > 0 && direct < floor) {
                // A mirrored beam is longer than the direct one on a slab (and as a rule on a
                // convex face; where not, kMinBeamKeep bounds the survivor's weight): where the
                // direct beam is predicted weaker than `floor`, the mirrored ones are followed
                // by roulette before their first leg (kept with probability direct / floor, at
                // least kMinBeamKeep; beam_path's roulettes go on from it).
                b.keep = std::max(direct / floor, kMinBeamKeep);
                if (!(uniform_double(splitmix64(state)) < b.keep)) continue;
            }
            // k = 0: toward the light; k odd: along the beam (to the face that mirrors it back);
            // k even: against it
            const Vec3 guess = k == 0 ? to_light : (k % 2 == 1 ? beam_dir : -beam_dir);
            g_light_paths.fetch_add(1, std::memory_order_relaxed);
            const bool found = beam_path(scene, i, v, k, guess, &b, k == 0 ? floor : mirror_floor, state);
            if (k == 0) direct = b.bound;
            if (!found) continue;
            if (k == 0) beam_dir = -b.w;
            const double cos_i = dot(b.to_light, b.entry.n), cos_t = b.cos_t;
            if (!(cos_i > 0 && cos_t > 0)) continue;
            // the beam's irradiance across its own direction inside: what crosses a unit of
            // surface (c cos_i Ft) spread over cos_t of it; a flat mirror keeps it, times F
            const double unkept = cos_i * (1.0 - fresnel_dielectric(cos_i, eta_)) / cos_t * b.focus * b.mirror;
            const double beam = unkept / b.keep;
            const Rgb tr = exp_neg(sigma_t_, b.length);
            const double cos_phase = dot(b.w, d);  // light along -w, scattered to -d
            Rgb f;
            for (int ch = 0; ch < 3; ch++) f[ch] = beta[ch] * beam * tr[ch] * henyey_greenstein(cos_phase, g_[ch]);
            if (!(f.max_component() > 0)) continue;
            if (k == 0) {
                // the guide for the next direction: the unshadowed strength per unit phase
                const double strength = unkept * tr.max_component() * beta.max_component();
                if (strength > strongest) {
                    strongest = strength;
                    *guide = b.w;
                    *has_guide = true;
                }
            }
            // the shadow test (the costly part: a ray through the scene) by roulette where the
            // beam arrives weaker than `floor` of its strength in every channel (unbiased)
            const double most = tr.max_component() * b.mirror;
            double keep = 1.0;
            if (most < floor && k == 0 && b.keep == 1.0) {  // (b.keep < 1: already rouletted before its solve)
                keep = most / floor;
                if (!(uniform_double(splitmix64(state)) < keep)) continue;
            }
            const Rgb c = scene.light_colour(i, b.entry.p, b.entry.n, b.to_light);
            sum += c * f * (1.0 / keep);
        }
    }
    return sum;
}

double RandomWalk::exit_weight(double cos_o) const {
    return (1.0 - fresnel_dielectric(cos_o, eta_)) / (eta_ * eta_);
}

Rgb RandomWalk::walk(WalkScene& scene, const Vec3& x, const Vec3& n, const Vec3& to_eye,
                     std::uint64_t& state) const {
    const double cos_o = dot(n, to_eye);
    if (!(cos_o > 0)) return Rgb(0.0);
    Vec3 d;
    if (!refract_into(-to_eye, n, eta_, &d)) return Rgb(0.0);
    g_walks.fetch_add(1, std::memory_order_relaxed);
    const double start = exit_weight(cos_o);
    Rgb beta(start), sum(0.0);
    const bool same_g = g_.r == g_.g && g_.g == g_.b;
    Vec3 p = x;
    auto uniform = [&]() { return uniform_double(splitmix64(state)); };
    std::uint64_t vertices = 0;
    // the probe's balance-heuristic share of the next point's light (1: no probe covers it)
    double pending = 1.0;
    int k = 0;
    for (; k < settings_.max_vertices; k++) {
        WalkScene::Hit h{};
        const double tb = scene.leave(p, d, &h) ? h.t : kInf;
        const double total = beta.r + beta.g + beta.b;
        if (!(total > 0)) break;
        const int c = pick_channel(beta, total, uniform());
        const Rgb q = beta * (1.0 / total);
        const double t = sigma_t_[c] > 0 ? -std::log(1.0 - uniform()) / sigma_t_[c] : kInf;
        if (t >= tb) {
            // the flight reaches the surface: probability exp(-sigma_t tb) in each channel
            const Rgb tr = exp_neg(sigma_t_, tb);
            const double pdf = q.r * tr.r + q.g * tr.g + q.b * tr.b;
            if (!(pdf > 0)) break;
            beta = beta * tr * (1.0 / pdf);
            const double cos_i = dot(d, h.n);
            const double f = eta_ == 1.0 ? 0.0 : fresnel_dielectric(cos_i, 1.0 / eta_);
            if (!(uniform() < f)) break;  // leaves: the outside is lit only by the lights
            d = normalize(d - h.n * (2.0 * cos_i));
            p = h.p;
            pending = 1.0;  // a mirrored path: no probe reaches it
            continue;
        }
        if (!std::isfinite(t)) break;
        p = p + d * t;
        vertices++;
        const Rgb tr = exp_neg(sigma_t_, t);
        const Rgb dens = sigma_t_ * tr;
        const double pdf = q.r * dens.r + q.g * dens.g + q.b * dens.b;
        if (!(pdf > 0)) break;
        beta = beta * sigma_s_ * tr * (1.0 / pdf);
        Vec3 guide;
        bool has_guide = false;
        const double light_floor = settings_.light_floor;
        sum += next_event(scene, p, d, beta, light_floor, light_floor, state, &guide, &has_guide) * pending;
        pending = 1.0;
        const bool probing = probe_ && has_guide;
        if (probing) {
            // The probe: the light at the NEXT scattering point, along a direction drawn from
            // the phase lobe about the beam instead of the walk's own (a second strategy for
            // the same paths, balance heuristic: each weighted p_d / (p_d + p_beam)), so the
            // directions where the phase function meets the beam are not left to chance.
            const Vec3 xd = sample_henyey_greenstein(guide, g_.r, uniform(), uniform());
            const double pd = henyey_greenstein(dot(d, xd), g_.r), pg = henyey_greenstein(dot(guide, xd), g_.r);
            WalkScene::Hit hp{};
            const double tp = scene.leave(p, xd, &hp) ? hp.t : kInf;
            const double totalp = beta.r + beta.g + beta.b;
            const int cp = pick_channel(beta, totalp, uniform());
            const double t2 = sigma_t_[cp] > 0 ? -std::log(1.0 - uniform()) / sigma_t_[cp] : kInf;
            if (t2 < tp && pd + pg > 0) {
                const Rgb tr2 = exp_neg(sigma_t_, t2), dens2 = sigma_t_ * tr2;
                const double pdf2 = (beta.r * dens2.r + beta.g * dens2.g + beta.b * dens2.b) / totalp;
                if (pdf2 > 0) {
                    const Rgb bp = beta * sigma_s_ * tr2 * (pd / ((pd + pg) * pdf2));
                    Vec3 unused;
                    bool unused_flag = false;
                    sum += next_event(scene, p + xd * t2, xd, bp, light_floor, light_floor, state, &unused,
                                      &unused_flag);
                }
            }
        }
        // the next direction, from the phase function of a channel drawn by weight
        const double total2 = beta.r + beta.g + beta.b;
        if (!(total2 > 0)) break;
        const double u_ch = uniform(), u1 = uniform(), u2 = uniform();
        const int j = same_g ? 0 : pick_channel(beta, total2, u_ch);
        // forward scattering: half the directions from the phase lobe about the strongest
        // light's beam (toward where it enters), weighted by the mixture (one-sample MIS):
        // the next point's light is then sampled where the phase function peaks
        const bool guided = !probe_ && has_guide && guide_ && vertices <= std::uint64_t(settings_.guided_vertices);
        const double share = settings_.guided_share;
        const Vec3 axis = guided && uniform() < share ? guide : d;
        const Vec3 next = sample_henyey_greenstein(axis, g_[j], u1, u2);
        if (!same_g || guided) {
            const double cs = dot(d, next), cg = guided ? dot(guide, next) : 0.0;
            const Rgb ph(henyey_greenstein(cs, g_.r), henyey_greenstein(cs, g_.g), henyey_greenstein(cs, g_.b));
            Rgb pdf = ph;
            if (guided)
                for (int ch = 0; ch < 3; ch++) pdf[ch] = (1.0 - share) * ph[ch] + share * henyey_greenstein(cg, g_[ch]);
            const double mixture = same_g ? pdf.r : (beta.r * pdf.r + beta.g * pdf.g + beta.b * pdf.b) / total2;
            if (!(mixture > 0)) break;
            beta = beta * ph * (1.0 / mixture);
        }
        if (probing) {
            const double pd = henyey_greenstein(dot(d, next), g_.r), pg = henyey_greenstein(dot(guide, next), g_.r);
            pending = pd + pg > 0 ? pd / (pd + pg) : 1.0;
        }
        d = next;
        // Russian roulette on the largest channel weight
        const double m = beta.max_component(), floor = settings_.roulette_weight * start;
        if (m < floor) {
            const double survive = m / floor;
            if (!(uniform() < survive)) break;
            beta = beta * (1.0 / survive);
        }
    }
    if (k == settings_.max_vertices) g_truncated.fetch_add(1, std::memory_order_relaxed);
    g_vertices.fetch_add(vertices, std::memory_order_relaxed);
    return sum * kPi;
}

Rgb RandomWalk::single_scatter(WalkScene& scene, const Vec3& x, const Vec3& n, const Vec3& to_eye, int points,
                               std::uint64_t seed) const {
    const double cos_o = dot(n, to_eye);
    if (!(cos_o > 0) || points < 1) return Rgb(0.0);
    Vec3 d;
    if (!refract_into(-to_eye, n, eta_, &d)) return Rgb(0.0);
    const double start = exit_weight(cos_o);
    g_single_points.fetch_add(1, std::memory_order_relaxed);
    WalkScene::Hit h{};
    const double tb = scene.leave(x, d, &h) ? h.t : kInf;
    // The depths follow the light's own attenuation: at depth t along the view ray the light
    // has come s(t) inside, so channel c's integrand is about exp(-sigma_t (t + s(t))) times
    // the phase and the entering light. With s(t) ~ s(0) + k t the depths are drawn from
    // exp(-sigma_t (1 + k) t) over [0, tb): on a flat face lit from above s(0) = 0 and k =
    // cos_o' / cos_l' (the refracted cosines) exactly; through a sheet lit from behind k < 0
    // (deeper is nearer the light; k = -1 under light and view straight on: uniform depths).
    // k is read from the object itself: the length of the light's refracted path back to the
    // surface at x and at a probe depth (a mean free path of the deepest-reaching channel, at
    // most half way to the far face), for the light most nearly along the normal, preferring
    // one above x (its beam refracted at x; one behind, at a face parallel to x's). Each
    // channel's points are its own (the estimate of channel c reads only them): on a flat face
    // every point then weighs the same and the sum is exact; on a curved face, where the light
    // comes in from the side near the terminator (the half-space's k would put every depth at
    // the surface), or through a finite thickness, the remaining ratio is smooth.
    double k = 0, along = 0;
    bool above = false;
    Vec3 beam_in;  // the chosen light's direction of travel inside
    for (int i = 0, lights = scene.light_count(); i < lights; i++) {
        Vec3 l, t;
        if (!scene.light_direction(i, x, &l)) continue;
        const double cos_l = dot(l, n);
        const bool up = cos_l > 0;
        if (up ? !refract_into(-l, n, eta_, &t) : !(cos_l < 0 && refract_into(-l, -n, eta_, &t))) continue;
        if ((up && !above) || (up == above && std::fabs(cos_l) > along)) along = std::fabs(cos_l), above = up, beam_in = t;
    }
    const double sigma_t_min = std::min({sigma_t_.r, sigma_t_.g, sigma_t_.b});
    // The slope along a straight part of the view path from o (lit_face: o is where the chosen
    // light's beam enters, its path back there 0): the length of that path at o and at the
    // probe depth, over the probe depth.
    auto slope = [&](const Vec3& o, const Vec3& dir, double length, bool lit_face) {
        const double tp = std::min(1.0 / std::max(sigma_t_min, 1e-300), 0.5 * length);
        WalkScene::Hit at_o{}, at_p{};
        if (!(tp > 0 && std::isfinite(tp)) || !(lit_face || scene.leave(o + dir * (1e-9 * tp), -beam_in, &at_o)) ||
            !scene.leave(o + dir * tp, -beam_in, &at_p))
            return 0.0;
        return std::clamp((at_p.t - (lit_face ? 0.0 : at_o.t)) / tp, -1e3, 1e3);
    };
    if (along > 0) k = slope(x, d, tb, above);
    std::uint64_t state = seed;
    Rgb sum(0.0);
    Vec3 guide;
    bool has_guide = false;
    // One straight part of the view path inside: from `o` along `dir` for `length` (kInf: it
    // never leaves), `before` already travelled inside, its weight `w`, the depths drawn with
    // slope `slope` (as k above). Where the faces mirror beams and the part is finite, half the
    // depths are uniform instead (a beam mirrored by the far face comes back along the view
    // ray: under forward scattering it can outweigh the direct beam the slope follows; on a
    // 0.25 mfp' g 0.9 sheet seen along the light, 16 depths by the slope alone read 10 % low),
    // every depth weighted by the mixture of both densities (the balance heuristic).
    const bool mirrors = eta_ != 1.0 && settings_.beam_reflections > 0;
    auto segment = [&](const Vec3& o, const Vec3& dir, double length, double before, double w, double slope) {
        for (int c = 0; c < 3; c++) {
            if (!(sigma_s_[c] > 0) || !(sigma_t_[c] > 0)) continue;
            double rate = sigma_t_[c] * (1.0 + slope);
            if (!std::isfinite(length) && !(rate > 0)) rate = sigma_t_[c];  // an unbounded ray needs a decaying density
            if (std::isfinite(length) && rate * length < -700.0) rate = -700.0 / length;  // growing: e^700 stays finite
            // exp(-rate t) truncated at the far face (rate of either sign; uniform when rate
            // length is negligible): its mass and, per stratum, the depth
            const bool uniform = std::isfinite(length) && std::fabs(rate * length) < 1e-9;
            const double mass = std::isfinite(length) ? -std::expm1(-rate * length) : 1.0;
            // (only where the far face is near enough for its mirrored beam to matter: a beam
            // attenuated below kSingleMirrorFloor on the way keeps the slope's exact sum)
            const bool near = std::isfinite(length) && std::exp(-sigma_t_[c] * length) > kSingleMirrorFloor;
            const int n_uniform = mirrors && near && !uniform && points > 1 ? points / 2 : 0;
            const int n_slope = points - n_uniform;
            auto p_slope = [&](double t) { return uniform ? 1.0 / length : rate * std::exp(-rate * t) / mass; };
            for (int j = 0; j < points; j++) {
                const bool by_slope = j < n_slope;
                const double u = by_slope ? (j + 0.5) / n_slope : (j - n_slope + 0.5) / n_uniform;
                const double t = !by_slope || uniform ? u * length : -std::log1p(-u * mass) / rate;
                // n_slope p_slope + n_uniform / length: the density of all the depths together
                const double density = n_slope * p_slope(t) + (n_uniform > 0 ? n_uniform / length : 0.0);
                if (!(density > 0) || !std::isfinite(t)) continue;
                Rgb beta(0.0);
                beta[c] = w * sigma_s_[c] * std::exp(-sigma_t_[c] * (before + t)) / density;
                // floor 0: no roulette of the direct beams (a flat face's sum stays exact); a
                // mirrored one by roulette below kSingleMirrorFloor (a sheet's mirrored beams,
                // ~Fresnel's 2 %, stay above it; on a sphere of 3 diffusion lengths at eta 1.3
                // they never connect: 20 % of its trace saved, the image bit-identical)
                const Vec3 v = o + dir * t;
                sum[c] += next_event(scene, v, dir, beta, 0.0, kSingleMirrorFloor, state, &guide, &has_guide)[c];
            }
        }
    };
    segment(x, d, tb, 0.0, start, k);
    // The view path mirrored once at the far face (Fresnel's reflectance from inside): light
    // scattered toward that face and reflected there to the eye. Under forward scattering with
    // light and view along one line it is the forward peak (a g 0.9 sheet seen along the light:
    // as much as the rest of single scattering). Left out where the mirrored path would arrive
    // weaker than kSingleMirrorFloor in every channel (a ball several mean free paths across);
    // mirrored twice or more: Fresnel's reflectance squared (a sheet at eta 1.3: 3e-4). With
    // beam_reflections 0 no internal reflection is followed, this one neither.
    if (mirrors && std::isfinite(tb) && along > 0) {
        const double cos_f = dot(d, h.n);
        const double f = cos_f > 0 ? fresnel_dielectric(cos_f, 1.0 / eta_) : 0.0;
        if (f * std::exp(-sigma_t_min * tb) > kSingleMirrorFloor) {
            const Vec3 d2 = normalize(d - h.n * (2.0 * cos_f));
            WalkScene::Hit h2{};
            const double tb2 = scene.leave(h.p, d2, &h2) ? h2.t : kInf;
            // the slope along the mirrored part, read as for the first (its start on the far face)
            const double k2 = slope(h.p, d2, tb2, false);
            segment(h.p, d2, tb2, tb, start * f, k2);
        }
    }
    return sum * kPi;
}

Rgb RandomWalk::radiance(WalkScene& scene, const Vec3& x, const Vec3& n, const Vec3& to_eye, std::uint64_t seed) const {
    Rgb sum(0.0);
    std::uint64_t state = seed;
    for (int s = 0; s < settings_.samples; s++) {
        std::uint64_t walk_state = splitmix64(state);  // one stream per walk
        sum += walk(scene, x, n, to_eye, walk_state);
    }
    return sum * (1.0 / settings_.samples);
}

}  // namespace shading
