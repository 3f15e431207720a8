// Fresnel reflectance (fresnel.h). Equations: MODELS.md, "Fresnel".
#include "shading/brdf/fresnel.h"

#include <algorithm>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace shading {

double fresnel_dielectric(double cos_d, double eta) {
    // eta == 1: no interface, F == 0 everywhere (the formula below is 0/0 at grazing).
    if (eta == 1.0) return 0.0;
    cos_d = std::clamp(cos_d, -1.0, 1.0);  // rounding may put |cos| a few ulps past 1
    if (cos_d < 0) {                        // light on the transmitted side: swap the media
        eta = 1.0 / eta;
        cos_d = -cos_d;
    }
    // Snell: sin_t = sin_i / eta.
    double sin2_t = (1.0 - cos_d * cos_d) / (eta * eta);
    if (sin2_t >= 1.0) return 1.0;  // total internal reflection
    double cos_t = safe_sqrt(1.0 - sin2_t);
    double den_s = cos_d + eta * cos_t;
    double den_p = eta * cos_d + cos_t;
    // Both denominators vanish only when cos_d = cos_t = 0, i.e. grazing at the critical
    // angle (eta < 1): the limit there is total reflection.
    if (den_s <= 0 || den_p <= 0) return 1.0;
    double r_s = (cos_d - eta * cos_t) / den_s;  // s-polarised amplitude
    double r_p = (eta * cos_d - cos_t) / den_p;  // p-polarised amplitude
    return std::min(1.0, 0.5 * (r_s * r_s + r_p * r_p));
}

namespace {

// The conductor's constants that do not depend on the angle.
struct ConductorIndex {
    double re, im2;  // Re(eta^2) = n^2 - k^2 and Im(eta^2)^2 = (2 n k)^2
    bool none;       // n + ik == 1: no interface
    ConductorIndex(double n, double k) : re(n * n - k * k), im2(sqr(2.0 * n * k)), none(n == 1.0 && k == 0.0) {}
};

// Unpolarised conductor reflectance in real arithmetic (the complex form of MODELS.md,
// "Fresnel", with eta cos_t = sqrt(eta^2 - sin^2) = a + ib written out; e.g. Lagarde 2013,
// "Memo on Fresnel equations"): with x = n^2 - k^2 - sin^2 and t = |eta^2 - sin^2| =
// sqrt(x^2 + 4 n^2 k^2) = a^2 + b^2,
//   a^2 = (t + x) / 2,  b^2 = (t - x) / 2,
//   Rs = ((a - c)^2 + b^2) / ((a + c)^2 + b^2),
//   Rp = Rs ((a c - s^2)^2 + b^2 c^2) / ((a c + s^2)^2 + b^2 c^2)   (s^2 = 1 - c^2).
// Exact (not an approximation); agrees with the complex evaluation to ~1e-15 (fresnel_test).
double conductor_reflectance(double c, const ConductorIndex& e) {
    if (e.none) return 0.0;
    c = std::clamp(c, 0.0, 1.0);  // light from inside a conductor is not modelled
    const double c2 = c * c, s2 = 1.0 - c2;
    const double x = e.re - s2;
    const double t = std::sqrt(x * x + e.im2);
    // Whichever of a^2, b^2 is the sum of two non-negatives is computed directly, the other
    // from a^2 b^2 = (n k)^2 = im2 / 4: no cancellation when |x| >> nk (k -> 0, or a
    // dielectric below its critical angle: b = 0, and above it: a = 0, total reflection).
    double a2, b2;
    if (x >= 0) {
        a2 = 0.5 * (t + x);
        b2 = a2 > 0 ? 0.25 * e.im2 / a2 : 0.0;
    } else {
        b2 = 0.5 * (t - x);
        a2 = 0.25 * e.im2 / b2;  // b2 >= -x > 0
    }
    const double a = std::sqrt(a2);
    // Denominators: (a + c)^2 + b^2 = 0 needs a = b = c = 0, i.e. eta^2 = sin^2 = 1 at
    // grazing: eta == 1, excluded above. (a c + s^2)^2 + b^2 c^2 = 0 needs s^2 = 0 and
    // a c = 0 with c = 1: again a = b = 0, eta^2 = 0 (a perfect mirror, n = k = 0): Rs = 1.
    const double den_s = sqr(a + c) + b2;
    if (!(den_s > 0)) return 1.0;
    const double rs = (sqr(a - c) + b2) / den_s;
    const double den_p = sqr(a * c + s2) + b2 * c2;
    const double rp = den_p > 0 ? rs * (sqr(a * c - s2) + b2 * c2) / den_p : rs;
    // Both ratios are <= 1 analytically (a >= 0, c >= 0); min() absorbs rounding.
    return std::min(1.0, 0.5 * (rs + rp));
}

}  // namespace

double fresnel_conductor(double cos_d, double n, double k) {
    // k = 0 is a dielectric: the same formula, and the same rounding (total internal
    // reflection at the critical angle is a square-root singularity, where the two
    // arrangements of the arithmetic would differ by ~1e-8).
    if (k == 0.0) return fresnel_dielectric(std::clamp(cos_d, 0.0, 1.0), n);
    return conductor_reflectance(cos_d, ConductorIndex(n, k));
}

namespace {
#if defined(__SSE2__)
// (m ? a : b) lane by lane, m all ones or all zeros per lane.
inline __m128d select(__m128d m, __m128d a, __m128d b) { return _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)); }
inline __m128d sq(__m128d v) { return _mm_mul_pd(v, v); }

// conductor_reflectance for two channels (k != 0 in both) in the two lanes of one SSE2
// register: the same operations in the same order as the scalar form, whose branches become
// lane selects (each lane keeps the value its branch computes), so each lane has the scalar
// form's bits. Halves the divisions and square roots of two channels.
inline void conductor_reflectance2(double c, double n0, double k0, double n1, double k1, double* r0, double* r1) {
    c = std::clamp(c, 0.0, 1.0);
    const double c2 = c * c, s2 = 1.0 - c2;
    const __m128d n = _mm_set_pd(n1, n0), k = _mm_set_pd(k1, k0);
    const __m128d vc = _mm_set1_pd(c), vc2 = _mm_set1_pd(c2), vs2 = _mm_set1_pd(s2);
    const __m128d zero = _mm_setzero_pd(), half = _mm_set1_pd(0.5), one = _mm_set1_pd(1.0);
    const __m128d re = _mm_sub_pd(_mm_mul_pd(n, n), _mm_mul_pd(k, k));     // n^2 - k^2
    const __m128d im2 = sq(_mm_mul_pd(_mm_mul_pd(_mm_set1_pd(2.0), n), k));  // (2 n k)^2
    const __m128d x = _mm_sub_pd(re, vs2);
    const __m128d t = _mm_sqrt_pd(_mm_add_pd(_mm_mul_pd(x, x), im2));
    const __m128d xpos = _mm_cmpge_pd(x, zero);
    const __m128d pa2 = _mm_mul_pd(half, _mm_add_pd(t, x));  // x >= 0: a^2 directly
    const __m128d nb2 = _mm_mul_pd(half, _mm_sub_pd(t, x));  // x < 0: b^2 directly
    // The other one from a^2 b^2 = im2 / 4: one division by whichever was computed directly.
    const __m128d q = _mm_div_pd(_mm_mul_pd(_mm_set1_pd(0.25), im2), select(xpos, pa2, nb2));
    const __m128d a2 = select(xpos, pa2, q);
    const __m128d b2 = select(xpos, _mm_and_pd(_mm_cmpgt_pd(pa2, zero), q), nb2);
    const __m128d a = _mm_sqrt_pd(a2);
    const __m128d den_s = _mm_add_pd(sq(_mm_add_pd(a, vc)), b2);
    const __m128d rs = _mm_div_pd(_mm_add_pd(sq(_mm_sub_pd(a, vc)), b2), den_s);
    const __m128d ac = _mm_mul_pd(a, vc), b2c2 = _mm_mul_pd(b2, vc2);
    const __m128d den_p = _mm_add_pd(sq(_mm_add_pd(ac, vs2)), b2c2);
    const __m128d rp_full = _mm_div_pd(_mm_mul_pd(rs, _mm_add_pd(sq(_mm_sub_pd(ac, vs2)), b2c2)), den_p);
    const __m128d rp = select(_mm_cmpgt_pd(den_p, zero), rp_full, rs);
    const __m128d r = _mm_min_pd(_mm_mul_pd(half, _mm_add_pd(rs, rp)), one);  // min(1, .): NaN gives 1 too
    const __m128d out = select(_mm_cmpgt_pd(den_s, zero), r, one);             // !(den_s > 0): 1
    *r0 = _mm_cvtsd_f64(out);
    *r1 = _mm_cvtsd_f64(_mm_unpackhi_pd(out, out));
}
#endif
}  // namespace

Rgb fresnel_conductor(double cos_d, const Rgb& n, const Rgb& k) {
#if defined(__SSE2__)
    if (k.r != 0.0 && k.g != 0.0) {  // then neither is the "no interface" n + ik == 1
        Rgb f;
        conductor_reflectance2(cos_d, n.r, k.r, n.g, k.g, &f.r, &f.g);
        f.b = fresnel_conductor(cos_d, n.b, k.b);
        return f;
    }
#endif
    return {fresnel_conductor(cos_d, n.r, k.r), fresnel_conductor(cos_d, n.g, k.g),
            fresnel_conductor(cos_d, n.b, k.b)};
}

}  // namespace shading
