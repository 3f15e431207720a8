// Small value types and the local shading frame used by every model.
//
// Conventions (MODELS.md section 1 says the same at length):
//  * Directions are unit vectors in a local frame where the surface normal is +z
//    and the tangent (for anisotropic models) is +x.
//  * wo points towards the viewer, wi towards the light; both leave the surface.
//  * Brdf::f(wo, wi) returns the BRDF in 1/sr and EXCLUDES cos(theta_i).
//  * POV-Ray has no 1/pi: its light colour acts as irradiance at normal incidence
//    and its pixel values are pi x radiance. A BRDF reaches POV through pov_weight()
//    in brdf.h (pi f cos_i); the subsurface finish returns pixel values itself
//    (RadialProfile::exit_factor is pi L / M).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace shading {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInvPi = 1.0 / kPi;
constexpr double kInf = std::numeric_limits<double>::infinity();
// Radians per degree and degrees per radian (tables and tools speak degrees).
constexpr double kDegree = kPi / 180.0;
constexpr double kRadToDeg = 180.0 / kPi;

struct Vec3 {
    double x = 0, y = 0, z = 0;
    constexpr Vec3() = default;
    constexpr Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
    constexpr Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    constexpr Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    constexpr Vec3 operator-() const { return {-x, -y, -z}; }
    constexpr Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
};

constexpr double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& v) { return std::sqrt(dot(v, v)); }
// Zero vector stays zero (callers test for it) instead of becoming NaN.
inline Vec3 normalize(const Vec3& v) {
    double l = length(v);
    return l > 0 ? v * (1.0 / l) : v;
}

// Linear RGB triple (reflectance, BRDF value or radiance, by context).
struct Rgb {
    double r = 0, g = 0, b = 0;
    constexpr Rgb() = default;
    constexpr explicit Rgb(double v) : r(v), g(v), b(v) {}
    constexpr Rgb(double r_, double g_, double b_) : r(r_), g(g_), b(b_) {}
    constexpr Rgb operator+(const Rgb& o) const { return {r + o.r, g + o.g, b + o.b}; }
    constexpr Rgb operator-(const Rgb& o) const { return {r - o.r, g - o.g, b - o.b}; }
    constexpr Rgb operator*(const Rgb& o) const { return {r * o.r, g * o.g, b * o.b}; }
    constexpr Rgb operator*(double s) const { return {r * s, g * s, b * s}; }
    constexpr Rgb operator/(double s) const { return {r / s, g / s, b / s}; }
    Rgb& operator+=(const Rgb& o) { r += o.r; g += o.g; b += o.b; return *this; }
    constexpr double operator[](int i) const { return i == 0 ? r : (i == 1 ? g : b); }
    double& operator[](int i) { return i == 0 ? r : (i == 1 ? g : b); }
    constexpr double max_component() const { return std::max(r, std::max(g, b)); }
    constexpr double average() const { return (r + g + b) / 3.0; }
};
constexpr Rgb operator*(double s, const Rgb& c) { return c * s; }

// Numerically safe helpers: every clamp below guards against rounding that
// pushes an argument a few ulps outside the function's domain.
inline double safe_sqrt(double x) { return std::sqrt(std::max(0.0, x)); }
inline double safe_acos(double x) { return std::acos(std::clamp(x, -1.0, 1.0)); }
inline double safe_asin(double x) { return std::asin(std::clamp(x, -1.0, 1.0)); }
inline double sqr(double x) { return x * x; }
// acos without libm, for per-light table coordinates (the renderer's hot path):
// acos(x) = sqrt(1 - x) (pi/2 + x P(x)) on [0, 1], P of degree 9 fitted (weighted minimax) to
// acos for this project; |error| < 8e-11 rad on [0, 1] (measured on 2e6 points; 5e-9 deg,
// 5e-9 of a 1 deg table cell), decreasing, exact at 0 and 1. acos(-x) = pi - acos(x), so the
// two halves meet exactly at pi/2. x is clamped to [-1, 1]; NaN gives pi/2.
namespace detail {
#if defined(__SSE2__)
// m ? a : b per lane (m all ones or all zeros): the two-lane functions' branches as masks.
inline __m128d pick_pd(__m128d m, __m128d a, __m128d b) { return _mm_or_pd(_mm_and_pd(m, a), _mm_andnot_pd(m, b)); }
#endif
// q0 ... q9 of acos_approx's P; acos_approx2 reads the same numbers as pairs.
inline constexpr double kAcosQ[10] = {-0.21460182476875928,   0.089048041718750054,  -0.050782478358709512,
                                      0.033587281220832758,   -0.023867732483934753, 0.0169165554678881,
                                      -0.010760133708773498,  0.0053551255856450052, -0.0017482332077248114,
                                      0.0002706349525760654};
}  // namespace detail
inline double acos_approx(double x) {
    const double a = std::fabs(x) < 1.0 ? std::fabs(x) : (std::fabs(x) >= 1.0 ? 1.0 : 0.0);
    // P(a) = q0 + q1 a + ... + q9 a^9 by Estrin's scheme (pairs, then a^2, a^4, a^8): a
    // dependency chain of 5 multiply-adds instead of Horner's 10, on the per-light path.
    const double a2 = a * a, a4 = a2 * a2, a8 = a4 * a4;
    const double* q = detail::kAcosQ;
    const double e0 = q[0] + q[1] * a, e1 = q[2] + q[3] * a, e2 = q[4] + q[5] * a, e3 = q[6] + q[7] * a,
                 e4 = q[8] + q[9] * a;
    const double p = (e0 + e1 * a2) + (e2 + e3 * a2) * a4 + e4 * a8;
    const double r = std::sqrt(1.0 - a) * (kPi / 2 + a * p);
    return x < 0 ? kPi - r : r;
}

// acos_approx of two numbers at once, the same operations in the same order on the two lanes
// of an SSE2 register (so the same bits as two calls: tested): the renderer's per-light
// lookup needs theta_i and phi together.
inline void acos_approx2(double x, double y, double* ax, double* ay) {
#if defined(__SSE2__)
    // Every constant as a ready pair (one aligned load each, no broadcasts); q0 ... q9 from
    // acos_approx's table.
    constexpr const double* q = detail::kAcosQ;
    alignas(16) static constexpr double k[][2] = {
        {1.0, 1.0},   {-0.0, -0.0}, {kPi / 2, kPi / 2}, {kPi, kPi},   {q[0], q[0]}, {q[1], q[1]}, {q[2], q[2]},
        {q[3], q[3]}, {q[4], q[4]}, {q[5], q[5]},       {q[6], q[6]}, {q[7], q[7]}, {q[8], q[8]}, {q[9], q[9]}};
    // Hidden from the optimiser, which would otherwise rebuild each pair from one double.
    const double(*kp)[2] = k;
#if defined(__GNUC__)
    __asm__("" : "+r"(kp));
#endif
    auto K = [&](int i) { return _mm_load_pd(kp[i]); };
    const __m128d v = _mm_set_pd(y, x);
    const __m128d one = K(0);
    const __m128d m = _mm_andnot_pd(K(1), v);  // |v|
    // |v| < 1: |v|; |v| >= 1: 1; NaN (neither): 0
    const __m128d a = _mm_or_pd(_mm_and_pd(_mm_cmplt_pd(m, one), m), _mm_and_pd(_mm_cmpge_pd(m, one), one));
    const __m128d a2 = _mm_mul_pd(a, a), a4 = _mm_mul_pd(a2, a2), a8 = _mm_mul_pd(a4, a4);
    auto lin = [&](int i) { return _mm_add_pd(K(i), _mm_mul_pd(K(i + 1), a)); };
    const __m128d e0 = lin(4), e1 = lin(6), e2 = lin(8), e3 = lin(10), e4 = lin(12);
    const __m128d p = _mm_add_pd(_mm_add_pd(_mm_add_pd(e0, _mm_mul_pd(e1, a2)), _mm_mul_pd(_mm_add_pd(e2, _mm_mul_pd(e3, a2)), a4)),
                                 _mm_mul_pd(e4, a8));
    const __m128d r = _mm_mul_pd(_mm_sqrt_pd(_mm_sub_pd(one, a)), _mm_add_pd(K(2), _mm_mul_pd(a, p)));
    const __m128d neg = _mm_cmplt_pd(v, _mm_setzero_pd());
    const __m128d out = detail::pick_pd(neg, _mm_sub_pd(K(3), r), r);
    _mm_storel_pd(ax, out);
    _mm_storeh_pd(ay, out);
#else
    *ax = acos_approx(x);
    *ay = acos_approx(y);
#endif
}

// atan2(y, x) for y >= 0 (an angle in [0, pi]) without libm, for the per-light half/difference
// lookup. t = min(y, |x|) / max(y, |x|) is reduced to |u| <= tan(pi/8) by atan(t) = pi/4 +
// atan((t - 1) / (t + 1)) (one division either way); then atan(u) = u + u z R(z), z = u^2,
// R of degree 9 fitted (Chebyshev) to (atan(u)/u - 1)/z for this project: relative error
// < 3e-16 on [0, tan(pi/8)] (measured on 4e5 points, and down to 1e-300), so a small angle
// keeps its full relative precision (the half/difference theta_h axis is dense there).
// atan2_upper(0, 0) = 0 and (0, x < 0) = pi, as atan2; NaN stays NaN.
namespace detail {
// r0 ... r9 of atan2_upper's R and tan(pi/8); atan2_upper2 reads the same numbers as pairs.
inline constexpr double kAtanR[10] = {-0.3333333333333319,  0.19999999999915422,  -0.14285714269385189,
                                      0.11111109825767462,  -0.09090857872493935, 0.07691139307584897,
                                      -0.06650402375489083, 0.05740672398985412,  -0.044962952756785274,
                                      0.0229126008553073};
inline constexpr double kTanEighthPi = 0.41421356237309503;
}  // namespace detail
inline double atan2_upper(double y, double x) {
    const double ax = std::fabs(x);
    const double s = y < ax ? y : ax, g = y < ax ? ax : y;
    if (!(g > 0)) return g == 0 ? (x < 0 ? kPi : 0.0) : y + x;
    const bool reduce = s > detail::kTanEighthPi * g;  // t > tan(pi/8)
    const double u = reduce ? (s - g) / (s + g) : s / g;
    // R by Estrin's scheme, as acos_approx's P.
    const double z = u * u, z2 = z * z, z4 = z2 * z2, z8 = z4 * z4;
    const double* c = detail::kAtanR;
    const double e0 = c[0] + c[1] * z, e1 = c[2] + c[3] * z, e2 = c[4] + c[5] * z, e3 = c[6] + c[7] * z,
                 e4 = c[8] + c[9] * z;
    const double r = (e0 + e1 * z2) + (e2 + e3 * z2) * z4 + e4 * z8;
    double a = u + (u * z) * r;
    if (reduce) a += kPi / 4;
    if (y > ax) a = kPi / 2 - a;
    return x < 0 ? kPi - a : a;
}

namespace detail {
// atan2_upper2's rare lanes, out of line (its callers' hot code stays short).
[[gnu::noinline, gnu::cold]] inline void atan2_upper_each(double y0, double x0, double y1, double x1, double* a0,
                                                          double* a1) {
    *a0 = atan2_upper(y0, x0);
    *a1 = atan2_upper(y1, x1);
}
}  // namespace detail

// atan2_upper of two pairs at once: the same operations in the same order on the two lanes
// of an SSE2 register (the branches as masks), so the same bits as two calls (tested); the
// half/difference lookup needs theta_h and phi_d together. A lane with max(y, |x|) zero
// or NaN (rare) sends both to the scalar function.
inline void atan2_upper2(double y0, double x0, double y1, double x1, double* a0, double* a1) {
#if defined(__SSE2__)
    // Every constant as a ready pair, r0 ... r9 from atan2_upper's table.
    constexpr const double* c = detail::kAtanR;
    constexpr double t8 = detail::kTanEighthPi;
    alignas(16) static constexpr double k[][2] = {
        {-0.0, -0.0}, {t8, t8},       {kPi / 4, kPi / 4}, {kPi / 2, kPi / 2}, {kPi, kPi},
        {c[0], c[0]}, {c[1], c[1]},   {c[2], c[2]},       {c[3], c[3]},       {c[4], c[4]},
        {c[5], c[5]}, {c[6], c[6]},   {c[7], c[7]},       {c[8], c[8]},       {c[9], c[9]}};
    const double(*kp)[2] = k;  // hidden from the optimiser, as in acos_approx2
#if defined(__GNUC__)
    __asm__("" : "+r"(kp));
#endif
    auto K = [&](int i) { return _mm_load_pd(kp[i]); };
    using detail::pick_pd;
    const __m128d y = _mm_set_pd(y1, y0), x = _mm_set_pd(x1, x0);
    const __m128d ax = _mm_andnot_pd(K(0), x);
    const __m128d lt = _mm_cmplt_pd(y, ax);
    const __m128d s = pick_pd(lt, y, ax), g = pick_pd(lt, ax, y);
    if (_mm_movemask_pd(_mm_cmpgt_pd(g, _mm_setzero_pd())) != 3) return detail::atan2_upper_each(y0, x0, y1, x1, a0, a1);
    const __m128d reduce = _mm_cmpgt_pd(s, _mm_mul_pd(K(1), g));
    const __m128d u = _mm_div_pd(pick_pd(reduce, _mm_sub_pd(s, g), s), pick_pd(reduce, _mm_add_pd(s, g), g));
    const __m128d z = _mm_mul_pd(u, u), z2 = _mm_mul_pd(z, z), z4 = _mm_mul_pd(z2, z2), z8 = _mm_mul_pd(z4, z4);
    auto lin = [&](int i) { return _mm_add_pd(K(i), _mm_mul_pd(K(i + 1), z)); };
    const __m128d e0 = lin(5), e1 = lin(7), e2 = lin(9), e3 = lin(11), e4 = lin(13);
    const __m128d r = _mm_add_pd(_mm_add_pd(_mm_add_pd(e0, _mm_mul_pd(e1, z2)), _mm_mul_pd(_mm_add_pd(e2, _mm_mul_pd(e3, z2)), z4)),
                                 _mm_mul_pd(e4, z8));
    __m128d a = _mm_add_pd(u, _mm_mul_pd(_mm_mul_pd(u, z), r));
    a = pick_pd(reduce, _mm_add_pd(a, K(2)), a);
    a = pick_pd(_mm_cmpgt_pd(y, ax), _mm_sub_pd(K(3), a), a);
    a = pick_pd(_mm_cmplt_pd(x, _mm_setzero_pd()), _mm_sub_pd(K(4), a), a);
    _mm_storel_pd(a0, a);
    _mm_storeh_pd(a1, a);
#else
    *a0 = atan2_upper(y0, x0);
    *a1 = atan2_upper(y1, x1);
#endif
}

// Local-frame trigonometry (normal = +z, tangent = +x).
inline double cos_theta(const Vec3& w) { return w.z; }
inline double cos2_theta(const Vec3& w) { return w.z * w.z; }
inline double sin2_theta(const Vec3& w) { return std::max(0.0, 1.0 - cos2_theta(w)); }
inline double sin_theta(const Vec3& w) { return std::sqrt(sin2_theta(w)); }
inline double tan2_theta(const Vec3& w) { return sin2_theta(w) / cos2_theta(w); }
// At the pole phi is undefined; return phi = 0 (cos 1, sin 0) so callers stay finite.
inline double cos_phi(const Vec3& w) {
    double s = sin_theta(w);
    return s == 0 ? 1.0 : std::clamp(w.x / s, -1.0, 1.0);
}
inline double sin_phi(const Vec3& w) {
    double s = sin_theta(w);
    return s == 0 ? 0.0 : std::clamp(w.y / s, -1.0, 1.0);
}
// Direction from spherical angles in the local frame.
inline Vec3 spherical_direction(double theta, double phi) {
    double s = std::sin(theta);
    return {s * std::cos(phi), s * std::sin(phi), std::cos(theta)};
}

// Orthonormal frame (t, b, n); to_local/to_world are the only world<->local conversions.
struct Frame {
    Vec3 t{1, 0, 0}, b{0, 1, 0}, n{0, 0, 1};
    // Frame from a unit normal alone: a branch-free orthonormal basis
    // (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
    static Frame from_normal(const Vec3& n) {
        double sign = std::copysign(1.0, n.z);
        double a = -1.0 / (sign + n.z);
        double bb = n.x * n.y * a;
        Frame f;
        f.t = {1.0 + sign * n.x * n.x * a, sign * bb, -sign * n.x};
        f.b = {bb, sign + n.y * n.y * a, -n.y};
        f.n = n;
        return f;
    }
    // Frame whose +x is the projection of `tangent_hint` onto the tangent plane.
    // Fallback when the hint is (nearly) parallel to n: from_normal's basis, so
    // the frame is always defined (anisotropy then has an arbitrary but fixed axis).
    static Frame from_normal_tangent(const Vec3& n, const Vec3& tangent_hint) {
        Vec3 t = tangent_hint - n * dot(n, tangent_hint);
        double l = length(t);
        if (!(l > 1e-9 * std::max(1.0, length(tangent_hint)))) return from_normal(n);
        Frame f;
        f.n = n;
        f.t = t * (1.0 / l);
        f.b = cross(n, f.t);
        return f;
    }
    Vec3 to_local(const Vec3& v) const { return {dot(v, t), dot(v, b), dot(v, n)}; }
    Vec3 to_world(const Vec3& v) const { return t * v.x + b * v.y + n * v.z; }
};

}  // namespace shading
