// Dipole subsurface scattering and flat-medium single scattering; see dipole.h and DIPOLE.md.
#include "shading/subsurface/dipole.h"

#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace shading {

namespace {

// Largest coefficient (per length unit) accepted: keeps 1/zr^2 = sigma_t'^2 (the peak of Rd at
// r = 0) far below the double range, so every result stays finite.
constexpr double kMaxCoefficient = 1e100;

}  // namespace

// ---------------------------------------------------------------------------------------------
// Scalar formulas

double refracted_cos(double cos_i, double eta) {
    cos_i = std::clamp(cos_i, 0.0, 1.0);
    double sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    return sin2_t >= 1.0 ? 0.0 : std::sqrt(1.0 - sin2_t);
}

double fresnel_diffuse_reflectance_fit(double eta) {
    if (eta == 1.0) return 0.0;  // no interface; the fits' residual there is ~0.0016
    if (eta > 1.0) {
        // Jensen 2001 (after Egan & Hilgeman 1973), internal Fdr for eta = n_medium/n_outside.
        return -1.440 / (eta * eta) + 0.710 / eta + 0.668 + 0.0636 * eta;
    }
    // d'Eon & Irving 2011 fit in x = 1/eta > 1 (polynomial in 1/x = eta).
    double e = eta;
    return 0.919317 + e * (-3.4793 + e * (6.75335 + e * (-7.80989 + e * (4.98554 + e * -1.36881))));
}

double fresnel_diffuse_reflectance_exact(double eta) {
    // Fdr = int_0^1 Fr(mu; 1/eta) 2 mu dmu: light inside (index eta) leaving to index 1.
    if (eta == 1.0) return 0.0;
    const int n = 4096;  // composite Simpson, even n; integrands below are smooth
    const double inv = 1.0 / eta;
    double base = 0.0;
    auto integrand = [&](double x) -> double {
        if (eta > 1.0) {
            // Substitute the transmitted cosine x = cos_t in [0, 1] to remove the square-root
            // kink at the critical angle: mu^2 = 1 - (1 - x^2)/eta^2, 2 mu dmu = 2 x dx / eta^2.
            double mu = safe_sqrt(1.0 - (1.0 - x * x) * inv * inv);
            return fresnel_dielectric(mu, inv) * 2.0 * x * inv * inv;
        }
        return fresnel_dielectric(x, inv) * 2.0 * x;  // no total internal reflection inside
    };
    if (eta > 1.0) base = 1.0 - inv * inv;  // mu_c^2: the totally reflected cone
    double h = 1.0 / n, s = integrand(0.0) + integrand(1.0);
    for (int i = 1; i < n; ++i) s += integrand(i * h) * (i % 2 ? 4.0 : 2.0);
    return base + s * h / 3.0;
}

double fresnel_diffuse_reflectance(double eta, FdrModel fdr) {
    if (fdr == FdrModel::JensenFit && eta >= kFdrFitMinEta && eta <= kFdrFitMaxEta)
        return fresnel_diffuse_reflectance_fit(eta);
    return fresnel_diffuse_reflectance_exact(eta);  // once per channel and medium, never per pixel
}

double henyey_greenstein(double cos_theta, double g) {
    double num = 1.0 - g * g;
    // |g| = 1: a delta function, no finite density anywhere (see header).
    if (!(num > 0.0)) return 0.0;
    // 1 + g^2 - 2 g cos >= (1 - |g|)^2 > 0 for |g| < 1.
    double denom = 1.0 + g * g - 2.0 * g * std::clamp(cos_theta, -1.0, 1.0);
    return num / (4.0 * kPi * denom * std::sqrt(denom));
}

double dipole_total_reflectance(double alpha_prime, double A) {
    double s = safe_sqrt(3.0 * (1.0 - alpha_prime));  // sigma_tr * zr; rounding may give 1-a' < 0
    return 0.5 * alpha_prime * (1.0 + std::exp(-(4.0 / 3.0) * A * s)) * std::exp(-s);
}

// ---------------------------------------------------------------------------------------------
// DipoleChannel

DipoleChannel DipoleChannel::make(double sigma_s_prime, double sigma_a, double eta, FdrModel fdr) {
    DipoleChannel c;
    c.sigma_s_prime = sigma_s_prime;
    c.sigma_a = sigma_a;
    c.sigma_t_prime = sigma_s_prime + sigma_a;
    c.Fdr = fresnel_diffuse_reflectance(eta, fdr);
    c.A = (1.0 + c.Fdr) / (1.0 - c.Fdr);  // the exact Fdr < 1 for every finite eta > 0
    // No scattering (sigma_s' = 0, e.g. g -> 1 or a clear liquid) or no medium at all:
    // nothing is diffusely reflected; zr = 1/sigma_t' would be infinite in the second case.
    if (!(c.sigma_t_prime > 0.0) || !(sigma_s_prime > 0.0)) {
        c.empty = true;
        return c;
    }
    c.empty = false;
    c.alpha_prime = sigma_s_prime / c.sigma_t_prime;
    c.sigma_tr = std::sqrt(3.0 * sigma_a * c.sigma_t_prime);
    c.zr = 1.0 / c.sigma_t_prime;
    c.zv = c.zr * (1.0 + 4.0 * c.A / 3.0);
    return c;
}

double DipoleChannel::rd(double r) const {
    if (empty) return 0.0;
    r = std::fabs(r);
    if (!(r < kInf)) return 0.0;  // avoids (1 + inf) * exp(-inf) = inf * 0
    // One source: z (1 + sigma_tr d) exp(-sigma_tr d) / d^3, with d >= z > 0 (finite at r = 0).
    auto source = [&](double z) {
        double d = std::hypot(r, z);
        return (z / d) * (1.0 + sigma_tr * d) * std::exp(-sigma_tr * d) / (d * d);
    };
    // Jensen 2001 eq. 5
    return alpha_prime / (4.0 * kPi) * (source(zr) + source(zv));
}

double DipoleChannel::rd_disc(double R) const {
    if (empty || !(R > 0.0)) return 0.0;
    // Per source: exp(-s z) - (z/d) exp(-s d) = exp(-s z) (1 - exp(-log1p(delta/z) - s delta)),
    // delta = d - z = R^2 / (d + z). Written with expm1/log1p so small discs keep full relative
    // precision (the naive difference cancels when R << z).
    if (std::isinf(R)) return 0.5 * alpha_prime * (std::exp(-sigma_tr * zr) + std::exp(-sigma_tr * zv));
    auto source = [&](double z) {
        double d = std::hypot(R, z);
        double delta = R * (R / (d + z));  // R/(d+z) <= 1: no overflow for any finite R
        double x = -std::log1p(delta / z) - sigma_tr * delta;
        return std::exp(-sigma_tr * z) * -std::expm1(x);
    };
    return 0.5 * alpha_prime * (source(zr) + source(zv));
}

double DipoleChannel::rd_total() const {
    return empty ? 0.0 : dipole_total_reflectance(alpha_prime, A);
}

double DipoleChannel::radius_containing(double fraction) const {
    if (empty || !(fraction > 0.0)) return 0.0;
    if (fraction >= 1.0) return kInf;
    double target = fraction * rd_total();
    double hi = zr;
    while (rd_disc(hi) < target && hi < 1e300) hi *= 2.0;
    double lo = 0.0;
    for (int i = 0; i < 200 && hi - lo > 1e-15 * hi; ++i) {
        double mid = 0.5 * (lo + hi);
        (rd_disc(mid) < target ? lo : hi) = mid;
    }
    return hi;
}

// ---------------------------------------------------------------------------------------------
// Medium

Medium Medium::from_reduced(const Rgb& sigma_s_prime, const Rgb& sigma_a, double eta,
                            double mm_per_unit) {
    Medium m;
    m.sigma_s = sigma_s_prime;
    m.sigma_a = sigma_a;
    m.g = Rgb(0.0);
    m.eta = eta;
    m.mm_per_unit = mm_per_unit;
    return m;
}

Rgb Medium::sigma_s_prime() const {
    return {sigma_s.r * (1.0 - g.r), sigma_s.g * (1.0 - g.g), sigma_s.b * (1.0 - g.b)};
}

Rgb Medium::sigma_t() const { return sigma_s + sigma_a; }

std::string Medium::validate() const {
    std::ostringstream err;
    if (!(std::isfinite(mm_per_unit) && mm_per_unit > 0.0)) {
        err << "mm_per_unit = " << mm_per_unit << ": expected a finite value > 0";
        return err.str();
    }
    if (!(eta >= kMinEta && eta <= kMaxEta)) {
        err << "ior (eta) = " << eta << ": expected a value in [" << kMinEta << ", " << kMaxEta
            << "] (n_medium / n_outside)";
        return err.str();
    }
    const char* names[3] = {"r", "g", "b"};
    for (int c = 0; c < 3; ++c) {
        struct { const char* name; double v; } sig[2] = {{"sigma_s", sigma_s[c]}, {"sigma_a", sigma_a[c]}};
        for (auto& s : sig) {
            if (!(std::isfinite(s.v) && s.v >= 0.0)) {
                err << s.name << "." << names[c] << " = " << s.v << ": expected a finite value >= 0 (1/mm)";
                return err.str();
            }
            if (!(s.v * mm_per_unit <= kMaxCoefficient)) {
                err << s.name << "." << names[c] << " * mm_per_unit = " << s.v * mm_per_unit
                    << ": expected <= " << kMaxCoefficient << " per scene unit";
                return err.str();
            }
        }
        if (!(g[c] >= -1.0 && g[c] <= 1.0)) {
            err << "g." << names[c] << " = " << g[c] << ": expected a value in [-1, 1]";
            return err.str();
        }
    }
    return {};
}

// ---------------------------------------------------------------------------------------------
// Dipole

Dipole::Dipole(const Medium& m, FdrModel fdr) : medium_(m) {
    std::string err = m.validate();
    if (!err.empty()) throw std::invalid_argument("dipole medium: " + err);
    Rgb ssp = m.sigma_s_prime_per_unit(), sa = m.sigma_a_per_unit();
    for (int c = 0; c < 3; ++c) ch_[c] = DipoleChannel::make(ssp[c], sa[c], m.eta, fdr);
}

Rgb Dipole::rd(double r) const { return {ch_[0].rd(r), ch_[1].rd(r), ch_[2].rd(r)}; }

Rgb Dipole::rd_disc(double R) const {
    return {ch_[0].rd_disc(R), ch_[1].rd_disc(R), ch_[2].rd_disc(R)};
}

Rgb Dipole::rd_total() const { return {ch_[0].rd_total(), ch_[1].rd_total(), ch_[2].rd_total()}; }

Rgb Dipole::rd_sample(double r, double area) const {
    if (!(area > 0.0)) return Rgb(0.0);
    r = std::fabs(r);
    double rs = std::sqrt(area / kPi);
    // Far samples: the annulus mean differs from rd(r) by O((rs/r)^2) < 1e-8, while the
    // difference of two nearly equal disc integrals would lose that many digits.
    if (rs < 1e-4 * r) return rd(r) * area;
    double lo = std::max(0.0, r - rs), hi = r + rs;
    double ring = kPi * (hi - lo) * (hi + lo);
    Rgb out;
    for (int c = 0; c < 3; ++c) {
        // rd_disc is monotone, the difference is >= 0 up to rounding.
        out[c] = std::max(0.0, ch_[c].rd_disc(hi) - ch_[c].rd_disc(lo)) * (area / ring);
    }
    return out;
}

Rgb Dipole::radius_containing(double fraction) const {
    return {ch_[0].radius_containing(fraction), ch_[1].radius_containing(fraction),
            ch_[2].radius_containing(fraction)};
}

Rgb Dipole::bssrdf(double r, double cos_i, double cos_o) const {
    if (!(cos_i > 0.0) || !(cos_o > 0.0)) return Rgb(0.0);
    double w = fresnel_transmittance(cos_i, medium_.eta) * fresnel_transmittance(cos_o, medium_.eta) * kInvPi;
    return rd(r) * w;  // Jensen 2001 eq. 4
}

Rgb Dipole::diffusion_brdf(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0.0) || !(wi.z > 0.0)) return Rgb(0.0);
    double w = fresnel_transmittance(wi.z, medium_.eta) * fresnel_transmittance(wo.z, medium_.eta) * kInvPi;
    return rd_total() * w;
}

Rgb Dipole::single_scatter_brdf(const Vec3& wo, const Vec3& wi) const {
    if (!(wo.z > 0.0) || !(wi.z > 0.0)) return Rgb(0.0);
    const double eta = medium_.eta;
    double ft_i = fresnel_transmittance(wi.z, eta), ft_o = fresnel_transmittance(wo.z, eta);
    // eta < 1: beyond the critical angle nothing enters (Ft = 0), and the refracted cosines
    // below may both be 0; stop before dividing.
    if (!(ft_i > 0.0) || !(ft_o > 0.0)) return Rgb(0.0);
    double ct_i = refracted_cos(wi.z, eta), ct_o = refracted_cos(wo.z, eta);
    // Propagation directions inside: ti = (-wi.xy/eta, -ct_i) going down, to = (wo.xy/eta, ct_o)
    // going up to the exit point.
    double cos_phase = -(wi.x * wo.x + wi.y * wo.y) / (eta * eta) - ct_i * ct_o;
    double geom = ft_i * ft_o / (eta * eta * (ct_i + ct_o));  // ct_i + ct_o > 0 when Ft > 0
    Rgb out;
    const Rgb st = medium_.sigma_t();
    for (int c = 0; c < 3; ++c) {
        if (!(st[c] > 0.0)) continue;  // vacuum channel: nothing scatters
        double albedo = medium_.sigma_s[c] / st[c];
        out[c] = albedo * henyey_greenstein(cos_phase, medium_.g[c]) * geom;
    }
    return out;
}

namespace {

// The integral of e^(-k0 - k z) over z in [0, d], without overflow for either sign of k.
double exp_integral(double k0, double k, double d) {
    if (k > 0.0) return std::exp(-k0) * -std::expm1(-k * d) / k;
    if (k < 0.0) return std::exp(-k0 - k * d) * -std::expm1(k * d) / -k;
    return std::exp(-k0) * d;
}

}  // namespace

Rgb Dipole::single_scatter_slab(const Vec3& wo, const Vec3& wi, double d) const {
    if (!(wo.z > 0.0) || !(wi.z != 0.0) || !(d >= 0.0)) return Rgb(0.0);
    const double eta = medium_.eta, ci = std::fabs(wi.z);
    const double ft_i = fresnel_transmittance(ci, eta), ft_o = fresnel_transmittance(wo.z, eta);
    if (!(ft_i > 0.0) || !(ft_o > 0.0)) return Rgb(0.0);
    const double mi = refracted_cos(ci, eta), mo = refracted_cos(wo.z, eta);
    if (!(mi > 0.0) || !(mo > 0.0)) return Rgb(0.0);
    // Scattering angles: the incident beam and the ray toward the eye on opposite vertical
    // senses (as a half-space reflects) or the same (as light passes through).
    const double lateral = -(wi.x * wo.x + wi.y * wo.y) / (eta * eta);
    const double cos_opposed = lateral - mi * mo, cos_along = lateral + mi * mo;
    const double base = ft_i * ft_o / (eta * eta * mi * mo);
    const double ri = 1.0 - ft_i, ro = 1.0 - ft_o;  // inside, at the refracted angles
    const bool through = wi.z < 0.0;
    const double len = d * medium_.mm_per_unit;
    Rgb out;
    const Rgb st = medium_.sigma_t();
    for (int c = 0; c < 3; ++c) {
        if (!(st[c] > 0.0)) continue;
        // Depth z from the face the light enters. The beam: down (toward the far face) Ni e^(-A z),
        // back up after reflecting there Ni ri e^(-A (2d - z)); the way out toward the eye from a
        // scattering at z, through the exit face at depth z_x (0: the entry face, d: the far
        // one): straight Ni.. No e^(-B |z - z_x|), or first off the other face No ro e^(-B (2d -
        // |z - z_x|)); Ni, No sum the bounces between the faces (DIPOLE.md 5a).
        const double A = st[c] / mi, B = st[c] / mo;
        const double Ni = 1.0 / (1.0 - ri * ri * std::exp(-2.0 * A * len));
        const double No = 1.0 / (1.0 - ro * ro * std::exp(-2.0 * B * len));
        double opposed, along;
        if (!through) {
            opposed = exp_integral(0.0, A + B, len) + ri * ro * exp_integral(2.0 * (A + B) * len, -(A + B), len);
            along = ro * exp_integral(2.0 * B * len, A - B, len) + ri * exp_integral(2.0 * A * len, B - A, len);
        } else {
            along = exp_integral(A * len, B - A, len) + ri * ro * exp_integral((A + 2.0 * B) * len, A - B, len);
            opposed = ro * exp_integral((A + 2.0 * B) * len, -(A + B), len) + ri * exp_integral(A * len, A + B, len);
        }
        const double g = medium_.g[c];
        out[c] = medium_.sigma_s[c] * base * Ni * No *
                 (henyey_greenstein(cos_opposed, g) * opposed + henyey_greenstein(cos_along, g) * along);
    }
    return out;
}

std::string SubsurfaceBrdf::describe() const {
    const Medium& m = dipole_.medium();
    char buf[400];
    std::snprintf(buf, sizeof buf,
                  "subsurface(sigma_s=%g,%g,%g sigma_a=%g,%g,%g g=%g,%g,%g eta=%g mm_per_unit=%g)",
                  m.sigma_s.r, m.sigma_s.g, m.sigma_s.b, m.sigma_a.r, m.sigma_a.g, m.sigma_a.b,
                  m.g.r, m.g.g, m.g.b, m.eta, m.mm_per_unit);
    return buf;
}

}  // namespace shading
