// The multipole slab profiles (slab.h; Donner & Jensen 2005 section 3).
#include "shading/subsurface/slab.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "shading/subsurface/rd_profile.h"

namespace shading {

namespace {

// At most this many image pairs either side of the slab are summed term by term (image_sum).
constexpr int kExactPairs = 6;

// One point source at signed height z above the evaluation plane (the plane's normal pointing
// towards the source is +): z (1 + s d) e^{-s d} / d^3, d = sqrt(r^2 + z^2) (the dipole's term).
inline double source_term(double r, double z, double s) {
    const double d = std::sqrt(r * r + z * z);
    if (!(d > 0)) return 0.0;  // a source on the plane at r = 0: measure zero
    return (z / d) * (1.0 + s * d) * std::exp(-s * d) / (d * d);
}

// The source term is -dG/dz with G = e^{-s d} / d (d = sqrt(r^2 + z^2)), so a row of equal
// images at z = b + i D, i > n, sums by Euler-Maclaurin (midpoint form) to
//     G(m) / D + (D / 24) f'(m) - (7 D^3 / 5760) f'''(m) + ...,   m = b + (n + 1/2) D,
// for either sign of D (f = source_term): its integral from the midpoint outwards and the
// first correction.
inline double potential(double r, double z, double s) {
    const double d = std::sqrt(r * r + z * z);
    return std::exp(-s * d) / d;
}
// d/dz of source_term: (1 + s d) e / d^3 - z^2 (s^2 d^2 + 3 s d + 3) e / d^5, e = e^{-s d}.
inline double source_slope(double r, double z, double s) {
    const double d2 = r * r + z * z, d = std::sqrt(d2), e = std::exp(-s * d), sd = s * d;
    return e / (d2 * d) * ((1.0 + sd) - z * z * (sd * sd + 3.0 * sd + 3.0) / d2);
}

// Both tails (i > n and i < -n) of the row of images at z = b + 2 i L.
inline double image_tails(double r, double b, double L, int n, double s) {
    const double m = (2.0 * n + 1.0) * L;
    return (potential(r, b + m, s) - potential(r, b - m, s)) / (2.0 * L) +
           (2.0 * L / 24.0) * (source_slope(r, b + m, s) - source_slope(r, b - m, s));
}

// sinh(s x) / sinh(s L) and friends stay finite for large s L: evaluated as exponentials.
// sinh(s x) cosh(s zb) / sinh(s L) for 0 <= x <= L.
double ratio(double s, double x, double zb, double L) {
    if (!(s * L > 1e-8)) return x / L;  // no absorption: the linear 1-D solution
    // sinh(sx) cosh(s zb) / sinh(sL) = (e^{s(x+zb-L)} + e^{s(x-zb-L)} - e^{-s(x-zb+L)} - e^{-s(x+zb+L)})
    //                                   / (2 (1 - e^{-2 s L}))
    const double num = std::exp(s * (x + zb - L)) + std::exp(s * (x - zb - L)) - std::exp(-s * (x - zb + L)) -
                       std::exp(-s * (x + zb + L));
    return num / (2.0 * -std::expm1(-2.0 * s * L));
}

}  // namespace

SlabChannel SlabChannel::make(const DipoleChannel& ch, double d) {
    SlabChannel c;
    c.d = d;
    if (ch.empty || !(d > 0)) return c;
    c.empty = false;
    const double st = ch.sigma_t_prime;
    // Mean depth of first scattering in [0, d] and the power scattered there (expm1: exact for
    // small sigma_t' d, and exp overflow beyond ~700 mean free paths gives the semi-infinite limit).
    const double x = st * d;
    c.power = ch.alpha_prime * -std::expm1(-x);
    c.z0 = x > 700 ? 1.0 / st : (1.0 / st - d / std::expm1(x));
    c.zb = 0.5 * (ch.zv - ch.zr);  // zv = zr + 4 A D = zr + 2 zb (Jensen 2001)
    c.sigma_tr = ch.sigma_tr;
    const double L = d + 2 * c.zb;
    // Beyond r ~ L the profile decays as exp(-kappa r), kappa = sqrt(s^2 + (pi/L)^2) (the first
    // eigenmode across the slab): 30 / kappa leaves e^-30 of it.
    const double kappa = std::sqrt(c.sigma_tr * c.sigma_tr + (kPi / L) * (kPi / L));
    c.cutoff = 30.0 / kappa;
    // Pairs summed term by term out to |z| = 3 cutoffs, at most kExactPairs of them; the rest
    // of each row of images by Euler-Maclaurin (image_tails: where little is absorbed the
    // pairs' differences fall only as a power of |z|, and a sum truncated at 3 cutoffs was 1 %
    // low in total). Against a 200,000-pair direct sum, the profile at 0 within 9e-8 at 6
    // pairs (1.7e-9 at 12, 9e-7 at 4; the tails' integral alone: 4.6e-7 at 12).
    c.pairs = std::min(kExactPairs, int(std::ceil(3.0 * c.cutoff / (2.0 * L))) + 1);
    return c;
}

// Donner & Jensen 2005: (P / 4 pi) sum_i [ term(z_r,i) - term(z_v,i) ], the depths measured from
// the entry face (R) or from the opposite face, d - z (T).
double SlabChannel::image_sum(double r, bool opposite) const {
    if (empty) return 0.0;
    r = std::fabs(r);
    if (!(r < cutoff)) return 0.0;
    const double L = d + 2 * zb, s = sigma_tr;
    double sum = 0;
    // Real images at z = br + 2 i L, virtual ones at z = bv + 2 i L (either face: the rows of
    // the opposite face, d - z, run the other way, which the symmetric sum does not mind).
    const double br = opposite ? d - z0 : z0, bv = opposite ? d + z0 + 2.0 * zb : -z0 - 2.0 * zb;
    for (int i = -pairs; i <= pairs; ++i)
        sum += source_term(r, br + 2.0 * i * L, s) - source_term(r, bv + 2.0 * i * L, s);
    sum += image_tails(r, br, L, pairs, s) - image_tails(r, bv, L, pairs, s);
    return std::max(0.0, power / (4.0 * kPi) * sum);
}

double SlabChannel::R(double r) const { return image_sum(r, false); }
double SlabChannel::T(double r) const { return image_sum(r, true); }

double SlabChannel::R_total() const {
    if (empty) return 0.0;
    const double L = d + 2 * zb, a = z0 + zb;
    return power * ratio(sigma_tr, L - a, zb, L);
}

double SlabChannel::T_total() const {
    if (empty) return 0.0;
    const double L = d + 2 * zb, a = z0 + zb;
    return power * ratio(sigma_tr, a, zb, L);
}

SlabProfiles make_slab_profiles(const Dipole& dipole, double d, const Rgb& k) {
    if (!(d > 0) || !std::isfinite(d)) throw std::invalid_argument("make_slab_profiles: thickness must be finite and > 0");
    SlabProfiles out;
    out.d = d;
    std::array<SlabChannel, 3> ch;
    double scale = kInf, cutoff = 0;
    for (int c = 0; c < 3; ++c) {
        ch[c] = SlabChannel::make(dipole.channel(c), d);
        if (ch[c].empty) continue;
        out.R_total[c] = k[c] * ch[c].R_total();
        out.T_total[c] = ch[c].T_total();
        scale = std::min(scale, ch[c].z0);
        cutoff = std::max(cutoff, ch[c].cutoff);
    }
    if (!(cutoff > 0)) {  // every channel empty
        scale = cutoff = d;
    }
    scale = std::min(scale, cutoff);
    auto same = [ch, k](double r) { return Rgb(k[0] * ch[0].R(r), k[1] * ch[1].R(r), k[2] * ch[2].R(r)); };
    auto transmit = [ch](double rho) { return Rgb(ch[0].T(rho), ch[1].T(rho), ch[2].T(rho)); };
    // The disc integrals numerically (RdProfile's Gauss-Legendre on its nodes): the closed-form
    // totals above are the independent check (SlabProfile tests). The image sums are called
    // at every 4th node only (kSlabSampleEvery).
    out.same = std::make_shared<const RdProfile>(same, RdProfile::Fn(), scale, cutoff, kSlabSampleEvery);
    out.transmit = std::make_shared<const RdProfile>(transmit, RdProfile::Fn(), scale, cutoff, kSlabSampleEvery);
    return out;
}

namespace {

// The least thickness from which `close(d)` holds (it holds for every thicker slab: the slab's
// totals approach the half-space's monotonically), by doubling from the smallest channel's z_r
// and bisection in log d; 0 for a medium without scattering.
template <class Close>
double thickness_from(const Dipole& dipole, Close close) {
    double zr = kInf;
    bool any = false;
    for (int c = 0; c < 3; ++c)
        if (!dipole.channel(c).empty) {
            zr = std::min(zr, dipole.channel(c).zr);
            any = true;
        }
    if (!any) return 0.0;
    double hi = zr;
    while (!close(hi)) {
        hi *= 2;
        if (hi > 1e12 * zr) return hi;  // (unreachable for valid media: T falls at least as 1/d)
    }
    double lo = hi * 0.5;
    if (close(lo)) return lo;  // (only when the first guess already holds)
    for (int it = 0; it < 40; ++it) {
        const double mid = std::sqrt(lo * hi);
        (close(mid) ? hi : lo) = mid;
    }
    return hi;
}

// The least thickness from which `far(s, R_inf)` is false for the slab s of every channel that
// reflects (R_inf > 0): from there on the slab is close to the half-space in what `far` measures.
template <class Far>
double thickness_where_none(const Dipole& dipole, Far far) {
    return thickness_from(dipole, [&](double d) {
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel& ch = dipole.channel(c);
            if (ch.empty) continue;
            const double inf = ch.rd_total();
            if (inf > 0 && far(SlabChannel::make(ch, d), inf)) return false;
        }
        return true;
    });
}

}  // namespace

double slab_threshold(const Dipole& dipole, double tolerance) {
    return thickness_where_none(dipole, [&](const SlabChannel& s, double inf) {
        return std::fabs(s.R_total() - inf) + s.T_total() > tolerance * inf;
    });
}

double reflect_threshold(const Dipole& dipole, double tolerance) {
    return thickness_where_none(dipole, [&](const SlabChannel& s, double inf) {
        return std::fabs(s.R_total() - inf) > tolerance * inf;
    });
}

double transmit_threshold(const Dipole& dipole, double fraction) {
    return thickness_where_none(dipole, [&](const SlabChannel& s, double inf) { return s.T_total() > fraction * inf; });
}

}  // namespace shading
