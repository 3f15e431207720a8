// Random-walk subsurface transport inside an object's own surface (`method random_walk`): exact
// volumetric transport for any shape the renderer can intersect, where no profile can be right
// (slanted light, thin sheets, forward-scattering media, small and concave objects).
// shading/DIPOLE.md, section "Random walk", derives every factor below.
//
// A walk starts where the camera ray meets the surface and follows light backwards:
//  * in: the camera direction refracted at the surface; the radiance that leaves is
//    Ft(cos_o) / eta^2 times the radiance inside (Fresnel transmittance, the n^2 law);
//  * free flights with per-channel sigma_t: the channel that sets each flight is drawn in
//    proportion to the walk's weight in that channel, and every channel is weighted by the
//    one-sample balance heuristic over the channels (the mixture of the three exponentials),
//    so one walk serves three media of very different reach without bias;
//  * Henyey-Greenstein scattering, g per channel, sampled and weighted the same way;
//  * at the surface (a flight that reaches it): exact unpolarised Fresnel from inside, total
//    internal reflection included; reflected with probability F, else the walk leaves (the
//    outside is lit only by the renderer's lights, which the next step counts);
//  * next-event estimation at every scattering vertex v, for every light: the light enters at
//    the surface point x_i whose refracted ray passes through v (found by following the
//    refracted direction back from v, a fixed point that is exact for a flat face and
//    converges in a few steps on curved ones), arrives as a collimated beam of irradiance
//    E c cos_i Ft(cos_i) / cos_t across its own direction, is attenuated by exp(-sigma_t s)
//    over the distance s from x_i, and scatters by the phase function into the walk.
//    The beam's own internal reflections are followed the same way (a path from v mirrored at
//    one or two faces before it reaches x_i, times the Fresnel reflectances): in a thin sheet
//    of a forward-scattering medium, the beam its back face mirrors lights the front.
//    Shadows, spotlights and light colours are the renderer's, asked at x_i; where the
//    light could add little (a deep vertex), the shadow test is made by roulette.
// * forward scattering (g > 0.3): at every scattering point a probe direction drawn about the
//   strongest light's beam gives a second estimate of the next point's light, combined with
//   the walk's own by the balance heuristic (channels with different g: the first direction
//   is steered instead, weighted by the mixture of both lobes), so where the phase function
//   lines up with the beam is found often instead of rarely.
// Russian roulette on the largest channel weight bounds the walk without bias.
//
// Lengths in scene units (the medium's coefficients are per mm, times mm_per_unit).
// Pixel values are pi x radiance (POV-Ray's convention: a light's colour is the irradiance it
// gives a surface facing it).
#pragma once

#include <atomic>
#include <cstdint>

#include "shading/core/vec.h"
#include "shading/subsurface/dipole.h"  // Medium

namespace shading {

// The object's surface and the scene's lights, as a walk inside the object sees them.
class WalkScene {
public:
    virtual ~WalkScene() = default;
    struct Hit {
        double t;   // distance from the ray's origin
        Vec3 p, n;  // point and OUTWARD unit normal there
    };
    // Where origin + t d (origin inside the object, d unit) first leaves the object, t > 0:
    // the nearest crossing behind which the object is not. False: it never does (an unbounded
    // medium, e.g. a half-space).
    virtual bool leave(const Vec3& origin, const Vec3& d, Hit* hit) = 0;
    virtual int light_count() = 0;
    // Unit direction from p toward light i (a parallel light: its direction); false: the light
    // cannot reach p (none there).
    virtual bool light_direction(int i, const Vec3& p, Vec3* to_light) = 0;
    // Light i's colour arriving at the surface point p (outward normal n) from to_light, after
    // the scene's shadows, spotlight cone and fading: the irradiance it gives a surface facing it.
    virtual Rgb light_colour(int i, const Vec3& p, const Vec3& n, const Vec3& to_light) = 0;
};

struct WalkSettings {
    int samples = 16;                  // walks per shaded point
    double roulette_weight = 0.05;     // roulette below this largest channel weight
    // A walk stops here whatever its weight: a medium that never absorbs, in an unbounded
    // object (a plane), would otherwise wander for minutes per pixel. Real media end far sooner
    // (marble: about 300 on average); the statistics count walks that reach it.
    int max_vertices = 1 << 16;
    int fixed_point_steps = 10;        // refraction-point iterations (Broyden) for next-event estimation
    // Shadow rays for a beam attenuated below this (exp(-sigma_t s) in every channel: a deep
    // vertex) are traced by roulette, with probability attenuation / light_floor.
    double light_floor = 1e-2;
    // Internal reflections of the unscattered beam followed by next-event estimation (eta != 1):
    // a forward-scattering sheet sees the beam its back face mirrors (up to 4).
    int beam_reflections = 2;
    // Where some channel's g is above this, half the scattering directions are drawn from the
    // phase lobe about the strongest light's beam (one-sample MIS with the phase function's own
    // lobe): with a forward-peaked phase function, next-event estimation's variance comes from
    // the rare directions that line up with the beam. Negative: never.
    double guide_g = 0.3;
    // ... at the first this many scattering points only: each guided step multiplies the walk's
    // weight by up to 1 / (1 - guided_share) (mean 1), and a long walk's product of such factors
    // is heavy-tailed. Measured (half-space, g 0.9, light at 70 degrees, variance x time per
    // walk): at 1, Ketchup's green and blue 5x and 15x better, red and Skin1-like media as
    // before or better; at 4, Ketchup's green and blue 100x better and high albedos worse.
    int guided_vertices = 1;
    double guided_share = 0.5;  // the part of those directions drawn about the beam
    // Instead (one g for all channels): at every scattering point a probe direction drawn about
    // the beam carries a second estimate of the next point's light, combined with the walk's
    // own by the balance heuristic; the walk itself is not steered, so no weight grows.
    bool probe = true;
};

// Counters of every walk of the process (relaxed atomics: statistics only).
struct WalkStats {
    std::uint64_t walks = 0, vertices = 0, light_paths = 0, truncated = 0;
    std::uint64_t auto_walked = 0, auto_profiled = 0;  // method auto: objects
    std::uint64_t single_points = 0;  // shaded points whose single scattering was traced (single_scatter)
};
// `method auto`'s decisions, one per object.
void random_walk_count_auto(bool walked);
WalkStats random_walk_stats();

// The walk's coefficients in scene units, checked once.
class RandomWalk {
public:
    // Throws std::invalid_argument with Medium::validate()'s message, or for g with |g| >= 1.
    RandomWalk(const Medium& medium, const WalkSettings& settings);
    const WalkSettings& settings() const { return settings_; }

    // pi x radiance leaving the surface at x (outward unit normal n) toward to_eye (unit, on
    // n's side), averaged over settings().samples walks. `seed` names the walks: the same seed
    // gives the same pixel (the renderer seeds with the hit point).
    Rgb radiance(WalkScene& scene, const Vec3& x, const Vec3& n, const Vec3& to_eye, std::uint64_t seed) const;

    // Single scattering alone, in the object's own shape: pi x radiance leaving x toward to_eye
    // from light scattered once inside, along the refracted view ray up to where it leaves the
    // object and, where the faces mirror (eta != 1, beam_reflections > 0), once more along its
    // reflection there (shading/DIPOLE.md 6c), every light by next_event (its beam entering
    // through whichever face it crosses, curved or the back of a sheet, its internal
    // reflections included). `points` depths per channel, one per stratum of
    // exp(-sigma_t (1 + k) t) truncated at the far face, k the slope of the light's path inside
    // against depth, read from the object by a probe for the light most nearly along the
    // normal: exact on a flat face and through parallel faces lit from behind, a smooth
    // remainder elsewhere; where the faces mirror, half of a finite part's depths uniform. The direct beams without roulette (next_event's
    // floor 0: on a flat face the sum is exact); a mirrored beam predicted weaker than 1e-4
    // of its strength by roulette from `seed` (the same seed, the same value). For
    // `single_scatter_samples` (the profile's finish), instead of the half-space's
    // single-scattering BRDF.
    Rgb single_scatter(WalkScene& scene, const Vec3& x, const Vec3& n, const Vec3& to_eye, int points,
                       std::uint64_t seed) const;

    // One walk (for tests that need per-walk values): pi x radiance estimate of a single walk.
    Rgb walk(WalkScene& scene, const Vec3& x, const Vec3& n, const Vec3& to_eye, std::uint64_t& rng_state) const;

private:
    // A light's beam from where it enters to a scattering point v, mirrored on the way at
    // `reflections` faces (internal Fresnel reflection of the unscattered beam).
    struct BeamPath {
        WalkScene::Hit entry{};  // where the light enters (outward normal)
        Vec3 to_light, w;        // at the entry: toward the light; at v: toward the first face
        double length = 0;       // inside the medium
        double mirror = 1;       // product of the Fresnel reflectances on the way
        double cos_t = 0;        // cosine of the refracted beam with the inward normal at the entry
        double keep = 1;         // in: survival probability so far; out: of the whole roulette before the solve
        double bound = 1;        // predicted attenuation at the first evaluation (times the reflectances)
        double focus = 1;        // the beam's cross-section at the entry over at v (a curved face's lens: 1 when flat)
    };
    bool beam_path(WalkScene& scene, int light, const Vec3& v, int reflections, Vec3 w, BeamPath* out,
                   double floor, std::uint64_t& state) const;
    // Light from every light scattered at v toward -d, times the walk's weight beta; a beam
    // attenuated below `floor` in every channel is shadow-tested by roulette.
    // *guide: from v toward where the strongest light's beam enters (when *has_guide).
    // mirror_floor: the same for the mirrored beams (the walk: `floor`).
    Rgb next_event(WalkScene& scene, const Vec3& v, const Vec3& d, const Rgb& beta, double floor,
                   double mirror_floor, std::uint64_t& state, Vec3* guide, bool* has_guide) const;

    // Radiance inside to radiance leaving toward the eye at cos_o: Ft(cos_o) / eta^2.
    double exit_weight(double cos_o) const;

    WalkSettings settings_;
    double eta_;
    bool guide_ = false;  // directions guided toward the light's beam (forward scattering)
    bool probe_ = false;  // the next point's light by a second, beam-guided strategy (MIS)
    Rgb sigma_s_, sigma_t_, g_;  // per scene unit
};

// Henyey-Greenstein: a direction about `axis` whose cosine with it has density
// 2 pi henyey_greenstein(cos, g), from two uniforms in [0, 1).
Vec3 sample_henyey_greenstein(const Vec3& axis, double g, double u1, double u2);

// Snell's law: a ray travelling along unit d meets a surface of unit normal n from n's side
// (d . n < 0), where the index is n1, and continues beyond it, where the index is n2;
// eta = n2 / n1. *t: its unit direction there. False: total internal reflection.
bool refract_into(const Vec3& d, const Vec3& n, double eta, Vec3* t);

}  // namespace shading
