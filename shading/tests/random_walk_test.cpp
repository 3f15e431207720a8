// The random walk against closed forms that share nothing with it: Chandrasekhar's exact
// half-space (H-function, index-matched, isotropic), the single-scattering radiance of a
// half-space and of a slab (any g, any eta, slanted light and view), energy in a non-absorbing
// slab, and the HG sampler's moments. Geometry here is analytic (a plane, two planes): the
// renderer's own intersections are checked by the harness against a volumetric reference.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "chandrasekhar_h.h"
#include "shading/brdf/fresnel.h"
#include "shading/core/random.h"
#include "shading/subsurface/random_walk.h"

namespace shading {
namespace {

// A slab -thickness < z < 0 (thickness = inf: a half-space) lit by one parallel light of
// colour `colour` from `to_light`.
class SlabScene final : public WalkScene {
public:
    SlabScene(double thickness, const Vec3& to_light, Rgb colour = Rgb(1.0))
        : d_(thickness), l_(normalize(to_light)), c_(colour) {}
    bool leave(const Vec3& o, const Vec3& d, Hit* h) override {
        if (d.z > 0) {
            h->t = -o.z / d.z;
            h->p = o + d * h->t;
            h->p.z = 0;
            h->n = Vec3(0, 0, 1);
            return true;
        }
        if (d.z < 0 && std::isfinite(d_)) {
            h->t = (-d_ - o.z) / d.z;
            h->p = o + d * h->t;
            h->p.z = -d_;
            h->n = Vec3(0, 0, -1);
            return true;
        }
        return false;
    }
    int light_count() override { return 1; }
    bool light_direction(int, const Vec3&, Vec3* l) override {
        *l = l_;
        return true;
    }
    Rgb light_colour(int, const Vec3&, const Vec3& n, const Vec3& l) override { return dot(n, l) > 0 ? c_ : Rgb(0.0); }

private:
    double d_;
    Vec3 l_;
    Rgb c_;
};

struct Estimate {
    Rgb mean, se;
};

Estimate run(const RandomWalk& rw, WalkScene& scene, const Vec3& n, const Vec3& to_eye, int walks, std::uint64_t seed,
             const Vec3& x = Vec3(0, 0, 0)) {
    Rgb s(0.0), s2(0.0);
    std::uint64_t state = seed;
    for (int i = 0; i < walks; i++) {
        std::uint64_t w = splitmix64(state);
        const Rgb v = rw.walk(scene, x, n, to_eye, w);
        s += v;
        s2 += v * v;
    }
    Estimate e;
    for (int c = 0; c < 3; c++) {
        e.mean[c] = s[c] / walks;
        e.se[c] = std::sqrt(std::max(0.0, s2[c] / walks - e.mean[c] * e.mean[c]) / (walks - 1));
    }
    return e;
}

Vec3 dir_deg(double theta, double phi = 0) {
    const double t = theta * kDegree, p = phi * kDegree;
    return Vec3(std::sin(t) * std::cos(p), std::sin(t) * std::sin(p), std::cos(t));
}

// A grey medium that scatters little (single scattering dominates).
Medium faint_medium(double sigma_s, double sigma_a, double g, double eta) {
    Medium m;
    m.sigma_s = Rgb(sigma_s);
    m.sigma_a = Rgb(sigma_a);
    m.g = Rgb(g);
    m.eta = eta;
    return m;
}

WalkSettings settings() {
    WalkSettings s;
    s.samples = 1;
    return s;
}

// Index-matched isotropic half-space, three channels of different albedo and reach in one walk:
// pi L = mu0 w H(mu) H(mu0) / (4 (mu + mu0)) per unit light colour (Chandrasekhar 1950).
TEST(RandomWalk, HalfSpaceIsChandrasekharsInEveryChannel) {
    Medium m;
    m.sigma_s = Rgb(0.5, 4.5, 9.9);
    m.sigma_a = Rgb(0.5, 0.5, 0.1);  // albedo 0.5, 0.9, 0.99; sigma_t 1, 5, 10
    m.g = Rgb(0.0);
    m.eta = 1.0;
    const RandomWalk rw(m, settings());
    for (double theta_l : {0.0, 60.0}) {
        SlabScene scene(kInf, dir_deg(theta_l));
        const double mu0 = std::cos(theta_l * kDegree), theta_v = 30.0, mu = std::cos(theta_v * kDegree);
        const Estimate e = run(rw, scene, Vec3(0, 0, 1), dir_deg(theta_v, 180), 40000, 7);
        for (int c = 0; c < 3; c++) {
            const double w = m.sigma_s[c] / (m.sigma_s[c] + m.sigma_a[c]);
            const double exact = mu0 * w * chandrasekhar_h(mu, w) * chandrasekhar_h(mu0, w) / (4 * (mu + mu0));
            EXPECT_NEAR(e.mean[c], exact, 4 * e.se[c] + 1e-4 * exact) << "light " << theta_l << " channel " << c;
            EXPECT_LT(e.se[c], 0.01 * exact) << "noise";
        }
    }
}

// Single scattering dominates at a small albedo: pi L = pi w p Ft(mu0) Ft(mu) mu0 / (eta^2 (mu0' + mu'))
// (primes: refracted cosines), at any g and eta, with slanted light and view in any azimuth.
TEST(RandomWalk, SingleScatteringOfAHalfSpaceAtAnyGAndEta) {
    for (double eta : {1.0, 1.3}) {
        for (double g : {0.0, 0.9, -0.5}) {
            const RandomWalk rw(faint_medium(1e-4, 1.0, g, eta), settings());
            const Vec3 l = dir_deg(45), v = dir_deg(35, 150);
            SlabScene scene(kInf, l);
            const Estimate e = run(rw, scene, Vec3(0, 0, 1), v, 20000, 11);
            Vec3 tl, tv;
            ASSERT_TRUE(refract_into(-l, Vec3(0, 0, 1), eta, &tl));
            ASSERT_TRUE(refract_into(-v, Vec3(0, 0, 1), eta, &tv));
            const double mu0 = l.z, mu = v.z, mu0t = -tl.z, mut = -tv.z;
            const double w = 1e-4 / (1.0 + 1e-4);
            const double p = henyey_greenstein(dot(tl, -tv), g);
            const double exact = kPi * w * p * (1 - fresnel_dielectric(mu0, eta)) * (1 - fresnel_dielectric(mu, eta)) * mu0 /
                                 (eta * eta * (mu0t + mut));
            // higher orders are ~w of it
            EXPECT_NEAR(e.mean.r, exact, 4 * e.se.r + 3e-4 * exact) << "eta " << eta << " g " << g;
            EXPECT_LT(e.se.r, 0.02 * exact);
        }
    }
}

// A slab lit from below, seen from above: single scattering of the transmitted beam. At depth z
// the beam has travelled (d - z)/a and the scattered light leaves along z/b (a, b: refracted
// cosines), so L inside = w p E int_0^d exp(-(d - z)/a - z/b) dz / b, E = mu0 Ft(mu0) / a.
TEST(RandomWalk, SingleScatteringThroughASlab) {
    const double eta = 1.3, g = 0.9, d = 0.7;
    const RandomWalk rw(faint_medium(1e-4, 1.0, g, eta), settings());
    const Vec3 l = Vec3(0.3, 0.1, -1.0);  // the light is below the slab
    const Vec3 v = dir_deg(20, 10);
    SlabScene scene(d, normalize(l));
    const Estimate e = run(rw, scene, Vec3(0, 0, 1), v, 20000, 5);
    Vec3 tl, tv;
    const Vec3 ln = normalize(l);
    ASSERT_TRUE(refract_into(-ln, Vec3(0, 0, -1), eta, &tl));  // enters through the bottom face
    ASSERT_TRUE(refract_into(-v, Vec3(0, 0, 1), eta, &tv));
    const double mu0 = -ln.z, mu = v.z, a = tl.z, b = -tv.z;  // refracted cosines (both > 0)
    const double w = 1e-4 / (1.0 + 1e-4);
    // L_in = int_0^d sigma_s p E exp(-(d - z)/a) exp(-z/b) dz / b, E = mu0 Ft(mu0) / a
    const double k = 1.0 / b - 1.0 / a;
    const double integral = std::exp(-d / a) * (1 - std::exp(-k * d)) / k;
    const double exact = kPi * (1 - fresnel_dielectric(mu, eta)) / (eta * eta) * w * henyey_greenstein(dot(tl, -tv), g) *
                         mu0 * (1 - fresnel_dielectric(mu0, eta)) / a * integral / b;
    EXPECT_NEAR(e.mean.r, exact, 4 * e.se.r + 3e-4 * exact);
    EXPECT_LT(e.se.r, 0.02 * exact);
}

// Single scattering in a slab with every internal reflection: the beam mirrored a = 0, 1, 2
// times by the faces before it scatters (the walk's next-event paths) and the scattered light
// mirrored b times before it leaves toward the eye (the walk's own Fresnel reflections). Each
// term is an exponential in depth, integrated in closed form. Forward scattering (g 0.9) makes
// the mirrored beam matter: the back face sends it toward the eye at a small angle.
TEST(RandomWalk, SingleScatteringOfASlabWithItsInternalReflections) {
    const double eta = 1.3, g = 0.9, d = 1.0, ws = 1e-4;
    const RandomWalk rw(faint_medium(ws, 1.0 - ws, g, eta), settings());  // sigma_t = 1
    const Vec3 l = dir_deg(45, 180), v = dir_deg(30);  // the beam travels toward +x, the eye sees it from +x
    SlabScene scene(d, l);
    const Estimate e = run(rw, scene, Vec3(0, 0, 1), v, 100000, 9);
    Vec3 tl, tv;
    ASSERT_TRUE(refract_into(-l, Vec3(0, 0, 1), eta, &tl));
    ASSERT_TRUE(refract_into(-v, Vec3(0, 0, 1), eta, &tv));
    const double a0 = -tl.z, b0 = -tv.z;  // refracted cosines
    const double fa = fresnel_dielectric(a0, 1.0 / eta), fb = fresnel_dielectric(b0, 1.0 / eta);
    const double E = l.z * (1 - fresnel_dielectric(l.z, eta)) / a0;
    double inside = 0, missing = 0, direct = 0;
    for (int a = 0; a <= 8; a++) {
        for (int b = 0; b <= 8; b++) {
            // beam after a reflections: going down (a even) or up; depth z in [0, d]:
            // its length is (a d + z)/a0 going down, ((a + 1) d - z)/a0 going up; the same for
            // the eye's path with b reflections.
            const double sa = a % 2 == 0 ? 1 : -1, sb = b % 2 == 0 ? 1 : -1;
            const Vec3 beam(tl.x, tl.y, a % 2 == 0 ? tl.z : -tl.z);
            const Vec3 out(-tv.x, -tv.y, b % 2 == 0 ? -tv.z : tv.z);  // the light's direction toward the eye
            const double p = henyey_greenstein(dot(beam, out), g);
            const double c0 = (a % 2 == 0 ? a * d : (a + 1) * d) / a0 + (b % 2 == 0 ? b * d : (b + 1) * d) / b0;
            const double k = sa / a0 + sb / b0;  // exponent: -(c0 + k z)
            const double integral = std::fabs(k) < 1e-12 ? d * std::exp(-c0) : std::exp(-c0) * (1 - std::exp(-k * d)) / k;
            const double term = std::pow(fa, a) * std::pow(fb, b) * ws * p * E * integral / b0;
            (a <= 2 ? inside : missing) += term;
            if (a == 0) direct += term;
        }
    }
    const double exact = kPi * (1 - fresnel_dielectric(v.z, eta)) / (eta * eta) * inside;
    EXPECT_LT(missing, 1e-4 * inside);       // orders the walk does not follow
    EXPECT_GT(inside - direct, 0.1 * inside);  // the mirrored beam is a tenth or more of it
    EXPECT_NEAR(e.mean.r, exact, 4 * e.se.r + 3e-4 * exact);
    EXPECT_LT(e.se.r, 0.03 * exact);
}

// single_scatter (single scattering alone, a deterministic sum along the view ray) against the
// same closed forms at any albedo (it counts one scattering only). Tolerances stated before
// measuring: on a flat face, and through parallel faces lit from behind, its depths follow the
// integrand exactly, so only rounding is left (kFlatSingleTol); where the beams mirrored by the
// faces add to it the remaining ratio is smooth and 32 strata per channel hold it to
// kSlabSingleTol.
constexpr double kFlatSingleTol = 1e-9;
constexpr double kSlabSingleTol = 2e-3;

TEST(RandomWalkSingleScatter, HalfSpaceIsTheClosedFormAtAnyGAndEta) {
    for (double eta : {1.0, 1.3}) {
        for (double g : {0.0, 0.9}) {
            Medium m;
            m.sigma_s = Rgb(0.5, 4.5, 9.9);
            m.sigma_a = Rgb(0.5, 0.5, 0.1);
            m.g = Rgb(g);
            m.eta = eta;
            const RandomWalk rw(m, settings());
            const Vec3 l = dir_deg(45), v = dir_deg(35, 150);
            SlabScene scene(kInf, l, Rgb(0.7, 1.0, 1.3));
            const Rgb got = rw.single_scatter(scene, Vec3(0, 0, 0), Vec3(0, 0, 1), v, 4, 3);
            Vec3 tl, tv;
            ASSERT_TRUE(refract_into(-l, Vec3(0, 0, 1), eta, &tl));
            ASSERT_TRUE(refract_into(-v, Vec3(0, 0, 1), eta, &tv));
            const double mu0 = l.z, mu = v.z, mu0t = -tl.z, mut = -tv.z;
            const double p = henyey_greenstein(dot(tl, -tv), g);
            for (int c = 0; c < 3; c++) {
                const double w = m.sigma_s[c] / (m.sigma_s[c] + m.sigma_a[c]);
                const double colour = c == 0 ? 0.7 : (c == 1 ? 1.0 : 1.3);
                const double exact = colour * kPi * w * p * (1 - fresnel_dielectric(mu0, eta)) *
                                     (1 - fresnel_dielectric(mu, eta)) * mu0 / (eta * eta * (mu0t + mut));
                EXPECT_NEAR(got[c], exact, kFlatSingleTol * exact) << "eta " << eta << " g " << g << " channel " << c;
            }
        }
    }
}

TEST(RandomWalkSingleScatter, ThroughASlabLitFromBehind) {
    const double eta = 1.3, g = 0.9, d = 0.7;
    Medium m = faint_medium(0.6, 0.4, g, eta);  // sigma_t 1, albedo 0.6: single scattering alone is asked for
    const RandomWalk rw(m, settings());
    const Vec3 ln = normalize(Vec3(0.3, 0.1, -1.0));  // the light is below the slab
    const Vec3 v = dir_deg(20, 10);
    SlabScene scene(d, ln);
    const Rgb got = rw.single_scatter(scene, Vec3(0, 0, 0), Vec3(0, 0, 1), v, 16, 5);
    Vec3 tl, tv;
    ASSERT_TRUE(refract_into(-ln, Vec3(0, 0, -1), eta, &tl));
    ASSERT_TRUE(refract_into(-v, Vec3(0, 0, 1), eta, &tv));
    const double mu0 = -ln.z, mu = v.z, a = tl.z, b = -tv.z;
    const double k = 1.0 / b - 1.0 / a;
    const double integral = std::exp(-d / a) * (1 - std::exp(-k * d)) / k;
    // beam_reflections (2): the beam mirrored by the top face, then by the bottom one, scatters
    // too; the unmirrored beam alone is the closed form above, the mirrored ones add less than
    // F(a)^1 of it: compare with the walk's own count of them instead (k = 0 only here).
    WalkSettings only_direct = settings();
    only_direct.beam_reflections = 0;
    const RandomWalk direct(m, only_direct);
    const Rgb got0 = direct.single_scatter(scene, Vec3(0, 0, 0), Vec3(0, 0, 1), v, 16, 5);
    const double exact = kPi * (1 - fresnel_dielectric(mu, eta)) / (eta * eta) * 0.6 * henyey_greenstein(dot(tl, -tv), g) *
                         mu0 * (1 - fresnel_dielectric(mu0, eta)) / a * integral / b;
    EXPECT_NEAR(got0.r, exact, kFlatSingleTol * exact);  // parallel faces: k is exact here too
    EXPECT_GE(got.r, got0.r);  // the mirrored beams add light
}

TEST(RandomWalkSingleScatter, SlabWithItsInternalReflectionsOfTheBeamAndTheView) {
    // The closed form of SingleScatteringOfASlabWithItsInternalReflections with the eye's path
    // mirrored at most once (b = 0, 1: single_scatter follows the view ray to the far face and
    // back from it; b = 2 adds Fresnel's reflectance squared, under 1e-3 of it here).
    const double eta = 1.3, g = 0.9, d = 1.0, ws = 0.5;
    const RandomWalk rw(faint_medium(ws, 1.0 - ws, g, eta), settings());
    const Vec3 l = dir_deg(45, 180), v = dir_deg(30);
    SlabScene scene(d, l);
    // 32 depths per channel (16: -0.44 %: the mirrored beams grow with depth where the direct one
    // fades, a ratio the strata follow only to second order)
    const Rgb got = rw.single_scatter(scene, Vec3(0, 0, 0), Vec3(0, 0, 1), v, 32, 9);
    Vec3 tl, tv;
    ASSERT_TRUE(refract_into(-l, Vec3(0, 0, 1), eta, &tl));
    ASSERT_TRUE(refract_into(-v, Vec3(0, 0, 1), eta, &tv));
    const double a0 = -tl.z, b0 = -tv.z;
    const double fa = fresnel_dielectric(a0, 1.0 / eta), fb = fresnel_dielectric(b0, 1.0 / eta);
    const double E = l.z * (1 - fresnel_dielectric(l.z, eta)) / a0;
    double inside = 0, view_mirrored = 0, left_out = 0;
    for (int a = 0; a <= 2; a++) {
        for (int b = 0; b <= 2; b++) {
            const double sa = a % 2 == 0 ? 1 : -1, sb = b % 2 == 0 ? 1 : -1;
            const Vec3 beam(tl.x, tl.y, a % 2 == 0 ? tl.z : -tl.z);
            const Vec3 out(-tv.x, -tv.y, b % 2 == 0 ? -tv.z : tv.z);
            const double p = henyey_greenstein(dot(beam, out), g);
            const double c0 = (a % 2 == 0 ? a * d : (a + 1) * d) / a0 + (b % 2 == 0 ? b * d : (b + 1) * d) / b0;
            const double k = sa / a0 + sb / b0;
            const double integral = std::fabs(k) < 1e-12 ? d * std::exp(-c0) : std::exp(-c0) * (1 - std::exp(-k * d)) / k;
            const double term = std::pow(fa, a) * std::pow(fb, b) * ws * p * E * integral / b0;
            (b <= 1 ? inside : left_out) += term;
            if (b == 1) view_mirrored += term;
        }
    }
    const double exact = kPi * (1 - fresnel_dielectric(v.z, eta)) / (eta * eta) * inside;
    EXPECT_LT(left_out, 1e-3 * inside);
    EXPECT_GT(view_mirrored, 10 * kSlabSingleTol * inside);  // the check sees the view's mirror
    EXPECT_NEAR(got.r, exact, kSlabSingleTol * exact);
    std::printf("slab single scattering: %.6f against %.6f (the view path mirrored: %.1f %% of it)\n", got.r, exact,
                100 * view_mirrored / inside);
}

// Guided directions (forward scattering) are weighted by the mixture of both lobes: the same
// expectation as the phase function's own sampling, with every channel of a medium whose
// channels differ in g, and less variance where the walk is short.
TEST(RandomWalk, GuidedDirectionsKeepTheExpectation) {
    Medium m;
    m.sigma_s = Rgb(1.8, 0.7, 0.3);
    m.sigma_a = Rgb(0.061, 0.97, 1.45);
    m.g = Rgb(0.9, 0.9, 0.8);
    m.eta = 1.0;
    WalkSettings plain = settings(), guided = settings();
    plain.guide_g = -1;
    guided.guided_vertices = 4;
    const RandomWalk a(m, plain), b(m, guided);
    SlabScene scene(kInf, dir_deg(70));
    const Estimate ea = run(a, scene, Vec3(0, 0, 1), Vec3(0, 0, 1), 100000, 21);
    const Estimate eb = run(b, scene, Vec3(0, 0, 1), Vec3(0, 0, 1), 100000, 22);
    for (int c = 0; c < 3; c++) {
        EXPECT_NEAR(ea.mean[c], eb.mean[c], 4 * std::hypot(ea.se[c], eb.se[c])) << c;
        EXPECT_LT(eb.se[c], 0.1 * eb.mean[c]) << c;
    }
    EXPECT_LT(eb.se.g, 0.5 * ea.se.g);  // the short (absorbing) channels gain most
    EXPECT_LT(eb.se.b, 0.5 * ea.se.b);
}

// The probe (one g for all channels): a second, beam-guided estimate of the next point's light,
// combined with the walk's own by the balance heuristic. The same expectation as the walk
// alone, and less noise in the absorbing channels, where the light is mostly of low order.
TEST(RandomWalk, ProbeOfTheNextPointKeepsTheExpectation) {
    Medium m;
    m.sigma_s = Rgb(1.8, 0.7, 0.3);
    m.sigma_a = Rgb(0.061, 0.97, 1.45);
    m.g = Rgb(0.9);
    m.eta = 1.3;
    WalkSettings plain = settings(), probed = settings();
    plain.guide_g = -1;
    const RandomWalk a(m, plain), b(m, probed);
    SlabScene scene(kInf, dir_deg(70));
    const Estimate ea = run(a, scene, Vec3(0, 0, 1), dir_deg(20, 180), 40000, 31);
    const Estimate eb = run(b, scene, Vec3(0, 0, 1), dir_deg(20, 180), 40000, 32);
    for (int c = 0; c < 3; c++) EXPECT_NEAR(ea.mean[c], eb.mean[c], 4 * std::hypot(ea.se[c], eb.se[c])) << c;
    EXPECT_LT(eb.se.g, 0.6 * ea.se.g);
    EXPECT_LT(eb.se.b, 0.6 * ea.se.b);
}

// No absorption, index-matched, isotropic: what enters a slab leaves it. With the light
// straight on, the reflected and transmitted radiance integrated over the hemispheres (by
// reciprocity: the walk from each exit direction) adds up to the light that entered.
TEST(RandomWalk, NonAbsorbingSlabReturnsAllTheLight) {
    Medium m;
    m.sigma_s = Rgb(2.0);
    m.sigma_a = Rgb(0.0);
    m.g = Rgb(0.0);
    m.eta = 1.0;
    const RandomWalk rw(m, settings());
    const double d = 1.0;
    SlabScene scene(d, Vec3(0, 0, 1));
    // flux = int pi L cos dw / pi over both hemispheres (+ the unscattered exp(-2)); Gauss in mu
    const double xs[4] = {0.0694318442, 0.3300094782, 0.6699905218, 0.9305681558};
    const double ws[4] = {0.1739274226, 0.3260725774, 0.3260725774, 0.1739274226};
    double total = std::exp(-d * 2.0), var = 0;
    for (int i = 0; i < 4; i++) {
        const double mu = xs[i], s = std::sqrt(1 - mu * mu);
        const Estimate up = run(rw, scene, Vec3(0, 0, 1), Vec3(s, 0, mu), 6000, 100 + i);
        const Estimate down = run(rw, scene, Vec3(0, 0, -1), Vec3(s, 0, -mu), 6000, 200 + i, Vec3(0, 0, -d));
        // pi L is the same in every azimuth: int_0^1 pi L 2 mu dmu
        total += ws[i] * 2 * mu * (up.mean.r + down.mean.r);
        var += sqr(ws[i] * 2 * mu) * (sqr(up.se.r) + sqr(down.se.r));
    }
    // the quadrature's own error on these smooth curves is well under 1e-3
    EXPECT_NEAR(total, 1.0, 4 * std::sqrt(var) + 2e-3);
}

TEST(RandomWalk, HenyeyGreensteinSamplerHasMeanCosineG) {
    std::uint64_t state = 3;
    const Vec3 axis = normalize(Vec3(0.2, -0.5, 0.8));
    for (double g : {0.0, 0.5, 0.9, 0.95, -0.7}) {
        double s = 0, s2 = 0;
        const int n = 200000;
        for (int i = 0; i < n; i++) {
            const double u1 = uniform_double(splitmix64(state)), u2 = uniform_double(splitmix64(state));
            const Vec3 d = sample_henyey_greenstein(axis, g, u1, u2);
            ASSERT_NEAR(length(d), 1.0, 1e-12);
            const double c = dot(d, axis);
            s += c;
            s2 += c * c;
        }
        // <cos> = g, <cos^2> = (1 + 2 g^2) / 3 for HG
        EXPECT_NEAR(s / n, g, 0.005) << g;
        EXPECT_NEAR(s2 / n, (1 + 2 * g * g) / 3, 0.005) << g;
    }
}

TEST(RandomWalk, RefractionKeepsSnellsLawAndStopsAtTotalReflection) {
    const Vec3 n(0, 0, 1);
    Vec3 t;
    const Vec3 d = -dir_deg(50);
    ASSERT_TRUE(refract_into(d, n, 1.3, &t));
    EXPECT_NEAR(std::sqrt(1 - t.z * t.z) * 1.3, std::sin(50 * kDegree), 1e-12);
    EXPECT_LT(t.z, 0);
    EXPECT_TRUE(refract_into(-dir_deg(50), n, 1.0 / 1.3, &t));   // from the dense side: critical 50.28 degrees
    EXPECT_FALSE(refract_into(-dir_deg(50.5), n, 1.0 / 1.3, &t));
}

TEST(RandomWalk, BadMediaAreRefused) {
    Medium m;
    m.sigma_s = Rgb(1.0);
    m.sigma_a = Rgb(0.1);
    m.g = Rgb(1.0);
    EXPECT_THROW(RandomWalk(m, settings()), std::invalid_argument);
    m.g = Rgb(0.0);
    m.sigma_a = Rgb(-1.0);
    EXPECT_THROW(RandomWalk(m, settings()), std::invalid_argument);
}

}  // namespace
}  // namespace shading
