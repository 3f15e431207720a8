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

// One point source at signed height z above the evaluation plane (the plane's normal pointing
// towards the source is +): z (1 + s d) e^{-s d} / d^3, d = sqrt(r^2 + z^2) (the dipole's term).
inline double source_term(double r, double z, double s) {
    const double d = std::hypot(r, z);
    if (!(d > 0)) return 0.0;  // a source on the plane at r = 0: measure zero
    return (z / d) * (1.0 + s * d) * std::exp(-s * d) / (d * d);
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
    // Images out to |z| = 3 cutoffs at least; where little is absorbed the pairs' differences
    // fall only as a power of |z| (the truncated sum was 1 % low in total without absorption
    // at 3 cutoffs): out to 15 cutoffs or 30 / sigma_tr, whichever is nearer.
    const double reach = std::max(3.0 * c.cutoff, std::min(15.0 * c.cutoff, c.sigma_tr > 0 ? 30.0 / c.sigma_tr : kInf));
    c.pairs = std::min(2000, int(std::ceil(reach / (2.0 * L))) + 1);
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
    for (int i = -pairs; i <= pairs; ++i) {
        const double zr = 2.0 * i * L + z0, zv = 2.0 * i * L - z0 - 2.0 * zb;
        sum += opposite ? source_term(r, d - zr, s) - source_term(r, d - zv, s)
                        : source_term(r, zr, s) - source_term(r, zv, s);
    }
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
    // totals above are the independent check (SlabProfile tests).
    out.same = std::make_shared<const RdProfile>(same, RdProfile::Fn(), scale, cutoff);
    out.transmit = std::make_shared<const RdProfile>(transmit, RdProfile::Fn(), scale, cutoff);
    return out;
}

double slab_threshold(const Dipole& dipole, double tolerance) {
    double zr = kInf;
    bool any = false;
    for (int c = 0; c < 3; ++c)
        if (!dipole.channel(c).empty) {
            zr = std::min(zr, dipole.channel(c).zr);
            any = true;
        }
    if (!any) return 0.0;
    auto close = [&](double d) {
        for (int c = 0; c < 3; ++c) {
            const DipoleChannel& ch = dipole.channel(c);
            if (ch.empty) continue;
            const SlabChannel s = SlabChannel::make(ch, d);
            const double inf = ch.rd_total();
            if (!(inf > 0)) continue;
            if (std::fabs(s.R_total() - inf) + s.T_total() > tolerance * inf) return false;
        }
        return true;
    };
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

}  // namespace shading
