"""Numpy reference of the dipole subsurface formulas (Jensen et al. 2001) and of exact
transport results used to check them.

Mirrors shading/include/shading/subsurface/dipole.h (same names, same conventions; see shading/DIPOLE.md):
eta = n_medium / n_outside, coefficients in 1/length, radii in the same length, Rd(r) per
length^2. Everything is a pure numpy function of the medium constants, vectorised where it
makes sense, so harness code can compute expected images and tables without the C++ library.

Independent of the C++ code on purpose: it is written from the equations, and the two are
compared through shared numbers (tests on both sides assert the same published values).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "fresnel_dielectric", "refracted_cos", "fdr_fit", "fdr_exact", "henyey_greenstein",
    "rd_total_closed", "Dipole", "single_scatter_brdf", "single_scatter_albedo_normal",
    "chandrasekhar_h", "chandrasekhar_h_iterated", "plane_albedo_isotropic", "plane_radiance_isotropic",
]


# ---------------------------------------------------------------------------------------------
# Fresnel

def fresnel_dielectric(cos_i, eta):
    """Exact unpolarised Fresnel reflectance; cos_i >= 0 on the incident side,
    eta = n_transmitted / n_incident; total internal reflection gives 1; eta == 1 gives 0."""
    cos_i = np.clip(np.asarray(cos_i, dtype=float), 0.0, 1.0)
    eta = np.asarray(eta, dtype=float)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    with np.errstate(invalid="ignore", divide="ignore"):
        rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
        rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        f = 0.5 * (rs * rs + rp * rp)
    f = np.where(tir, 1.0, f)
    return np.where(eta == 1.0, 0.0, f)


def refracted_cos(cos_i, eta):
    """Cosine of the refracted direction (Snell); 0 under total internal reflection."""
    cos_i = np.clip(np.asarray(cos_i, dtype=float), 0.0, 1.0)
    sin2_t = (1.0 - cos_i * cos_i) / (np.asarray(eta, dtype=float) ** 2)
    return np.sqrt(np.maximum(0.0, 1.0 - sin2_t))


def fdr_fit(eta: float) -> float:
    """Internal diffuse Fresnel reflectance, the fits used with the dipole:
    eta > 1 Jensen 2001 (Egan & Hilgeman 1973); eta < 1 d'Eon & Irving 2011 in 1/eta; eta = 1 -> 0."""
    if eta == 1.0:
        return 0.0
    if eta > 1.0:
        return -1.440 / eta**2 + 0.710 / eta + 0.668 + 0.0636 * eta
    e = eta
    return 0.919317 - 3.4793 * e + 6.75335 * e**2 - 7.80989 * e**3 + 4.98554 * e**4 - 1.36881 * e**5


#: Where the fits hold (within 2e-3 of the exact Fdr); the dipole's "fit" uses the exact value
#: outside (the eta > 1 polynomial passes 1 at eta 3.87): shading/dipole.h kFdrFit{Min,Max}Eta.
FDR_FIT_MIN_ETA, FDR_FIT_MAX_ETA = 0.5, 2.0


def fdr_exact(eta: float, n: int = 200001) -> float:
    """Internal diffuse Fresnel reflectance by quadrature: int_0^1 Fr(mu; 1/eta) 2 mu dmu."""
    if eta == 1.0:
        return 0.0
    mu = np.linspace(0.0, 1.0, n)
    f = fresnel_dielectric(mu, 1.0 / eta) * 2.0 * mu
    return float(np.sum((f[1:] + f[:-1]) * 0.5 * np.diff(mu)))


def henyey_greenstein(cos_theta, g):
    """HG phase function in 1/sr; |g| = 1 (a delta) has no finite density and gives 0."""
    cos_theta = np.clip(np.asarray(cos_theta, dtype=float), -1.0, 1.0)
    g = np.asarray(g, dtype=float)
    num = 1.0 - g * g
    den = 1.0 + g * g - 2.0 * g * cos_theta
    with np.errstate(invalid="ignore", divide="ignore"):
        p = num / (4.0 * math.pi * den * np.sqrt(den))
    return np.where(num > 0.0, p, 0.0)


# ---------------------------------------------------------------------------------------------
# Dipole

def rd_total_closed(alpha_prime, A):
    """Jensen 2001 total diffuse reflectance:
    (alpha'/2) (1 + exp(-(4/3) A sqrt(3(1-alpha')))) exp(-sqrt(3(1-alpha')))."""
    a = np.asarray(alpha_prime, dtype=float)
    s = np.sqrt(np.maximum(0.0, 3.0 * (1.0 - a)))
    return 0.5 * a * (1.0 + np.exp(-4.0 / 3.0 * A * s)) * np.exp(-s)


@dataclass(frozen=True)
class Dipole:
    """One channel of the classical dipole. sigma_s_prime = sigma_s (1 - g)."""

    sigma_s_prime: float
    sigma_a: float
    eta: float = 1.0
    fdr: str = "fit"  # "fit" (Jensen 2001 inside [0.5, 2], exact outside) or "exact"

    @property
    def sigma_t_prime(self) -> float:
        return self.sigma_s_prime + self.sigma_a

    @property
    def alpha_prime(self) -> float:
        return self.sigma_s_prime / self.sigma_t_prime if self.sigma_t_prime > 0 else 0.0

    @property
    def sigma_tr(self) -> float:
        return math.sqrt(3.0 * self.sigma_a * self.sigma_t_prime)

    @property
    def Fdr(self) -> float:
        if self.fdr == "exact" or not FDR_FIT_MIN_ETA <= self.eta <= FDR_FIT_MAX_ETA:
            return fdr_exact(self.eta)
        return fdr_fit(self.eta)

    @property
    def A(self) -> float:
        return (1.0 + self.Fdr) / (1.0 - self.Fdr)

    @property
    def zr(self) -> float:
        return 1.0 / self.sigma_t_prime

    @property
    def zv(self) -> float:
        return self.zr * (1.0 + 4.0 * self.A / 3.0)

    @property
    def empty(self) -> bool:
        return not (self.sigma_s_prime > 0.0 and self.sigma_t_prime > 0.0)

    def rd(self, r):
        """Jensen 2001 eq. 5, per length^2."""
        r = np.abs(np.asarray(r, dtype=float))
        if self.empty:
            return np.zeros_like(r)
        st = self.sigma_tr
        out = 0.0
        for z in (self.zr, self.zv):
            d = np.hypot(r, z)
            out = out + z * (1.0 + st * d) * np.exp(-st * d) / d**3
        return self.alpha_prime / (4.0 * math.pi) * out

    def rd_disc(self, R):
        """int_0^R 2 pi r Rd(r) dr in closed form (stable for small R)."""
        R = np.asarray(R, dtype=float)
        if self.empty:
            return np.zeros_like(R)
        st = self.sigma_tr
        out = 0.0
        with np.errstate(invalid="ignore", over="ignore"):
            for z in (self.zr, self.zv):
                d = np.hypot(R, z)
                delta = np.where(np.isinf(R), np.inf, R * (R / (d + z)))
                x = -np.log1p(delta / z) - st * delta
                out = out + math.exp(-st * z) * -np.expm1(x)
        return 0.5 * self.alpha_prime * out

    def rd_annulus_mean(self, r1, r2):
        """Mean of Rd over the annulus r1 <= r < r2 (what a radial MC bin estimates)."""
        r1 = np.asarray(r1, dtype=float)
        r2 = np.asarray(r2, dtype=float)
        return (self.rd_disc(r2) - self.rd_disc(r1)) / (math.pi * (r2 * r2 - r1 * r1))

    def rd_total(self) -> float:
        return 0.0 if self.empty else float(rd_total_closed(self.alpha_prime, self.A))


def slab_totals(ch: Dipole, d: float) -> tuple[float, float]:
    """Diffuse reflectance and transmittance (R, T) of a slab of thickness d (the channel's length
    unit) in the diffusion approximation the shading library's multipole uses (shading/slab.h):
    the laterally integrated fluence phi(z) solves D phi'' - sigma_a phi = -P delta(z - z0) on
    [-zb, d + zb] with phi = 0 at both ends (zb = 2 A D, D = 1/(3 sigma_t')), the source at the
    mean depth of first scattering z0 = 1/sigma_t' - d / (exp(sigma_t' d) - 1) with the power
    scattered in the slab P = alpha' (1 - exp(-sigma_t' d)); R = D phi'(0), T = -D phi'(d).

    Solved here as a linear system for the two exponential pieces on either side of the source
    (continuity and the flux jump), not from the library's closed form."""
    if ch.empty:
        return 0.0, 0.0
    st, s = ch.sigma_t_prime, ch.sigma_tr
    D = 1.0 / (3.0 * st)
    zb = 2.0 * ch.A * D
    x = st * d
    P = ch.alpha_prime * -math.expm1(-x)
    z0 = 1.0 / st if x > 700 else 1.0 / st - d / math.expm1(x)
    if s * (d + 2 * zb) < 1e-6:  # no absorption: linear pieces
        # phi = a (z + zb) below z0, b (d + zb - z) above; continuity and D (a + b) = P
        A_ = np.array([[z0 + zb, -(d + zb - z0)], [D, D]])
        a, b = np.linalg.solve(A_, np.array([0.0, P]))
        return float(D * a), float(D * b)
    # phi = a sinh(s (z + zb)) below z0, b sinh(s (d + zb - z)) above (scaled by exp(-s L) to
    # stay finite): continuity at z0 and D (phi'(z0-) - phi'(z0+)) = P.
    L = d + 2 * zb
    e = lambda u: math.exp(s * (u - L))  # exp(s u) scaled
    sh = lambda u: 0.5 * (e(u) - math.exp(-s * u - s * L))     # sinh(s u) e^{-s L}
    chh = lambda u: 0.5 * (e(u) + math.exp(-s * u - s * L))    # cosh(s u) e^{-s L}
    A_ = np.array([[sh(z0 + zb), -sh(d + zb - z0)],
                   [D * s * chh(z0 + zb), D * s * chh(d + zb - z0)]])
    a, b = np.linalg.solve(A_, np.array([0.0, P]))
    R = D * a * s * chh(zb)
    T = D * b * s * chh(zb)
    return float(R), float(T)


# ---------------------------------------------------------------------------------------------
# Single scattering of a flat semi-infinite medium

def single_scatter_brdf(wo, wi, albedo: float, g: float, eta: float):
    """f_ss = albedo Ft(wi) Ft(wo) p(ti . to) / (eta^2 (cos ti' + cos to')), 1/sr, cos_i excluded.
    wo, wi: (..., 3) outside directions leaving the surface (normal +z)."""
    wo = np.asarray(wo, dtype=float)
    wi = np.asarray(wi, dtype=float)
    ci, co = wi[..., 2], wo[..., 2]
    ft_i = 1.0 - fresnel_dielectric(ci, eta)
    ft_o = 1.0 - fresnel_dielectric(co, eta)
    cti, cto = refracted_cos(ci, eta), refracted_cos(co, eta)
    cos_phase = -(wi[..., 0] * wo[..., 0] + wi[..., 1] * wo[..., 1]) / eta**2 - cti * cto
    ok = (ci > 0) & (co > 0) & (ft_i > 0) & (ft_o > 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = albedo * ft_i * ft_o * henyey_greenstein(cos_phase, g) / (eta**2 * (cti + cto))
    return np.where(ok, f, 0.0)


def single_scatter_albedo_normal(albedo: float, g: float, eta: float, n: int = 200001) -> float:
    """Fraction of the power ENTERING at normal incidence that leaves after exactly one
    scattering event: albedo int_0^1 Ft(mu'; 1/eta) p(-mu') mu'/(1 + mu') 2 pi dmu'
    (inside directions). eta = 1, g = 0 gives albedo (1 - ln 2) / 2."""
    mu = np.linspace(0.0, 1.0, n)
    f = (1.0 - fresnel_dielectric(mu, 1.0 / eta)) * henyey_greenstein(-mu, g) * mu / (1.0 + mu) * 2 * math.pi
    return float(albedo * np.sum((f[1:] + f[:-1]) * 0.5 * np.diff(mu)))


# ---------------------------------------------------------------------------------------------
# Exact transport: semi-infinite isotropic medium, index-matched boundary (Chandrasekhar 1950)

@functools.lru_cache(maxsize=8)
def _gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes and weights on [-1, 1], made once (scipy's roots_legendre: numpy's leggauss is O(n^3),
    seconds for n = 4000)."""
    from scipy.special import roots_legendre
    x, w = roots_legendre(n)
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


def chandrasekhar_h(mu, albedo: float, n_theta: int = 4000):
    """Chandrasekhar's H-function for isotropic scattering, by its explicit integral form
    ln H(mu) = -(mu/pi) int_0^{pi/2} ln(1 - albedo theta cot theta) / (cos^2 + mu^2 sin^2) dtheta
    (Gauss-Legendre in theta)."""
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    x, w = _gauss_legendre(n_theta)
    th = 0.25 * math.pi * (x + 1.0)
    w = 0.25 * math.pi * w
    tc = th / np.tan(th)
    lg = np.log1p(-albedo * tc)  # albedo < 1: 1 - albedo theta cot theta > 0
    den = np.cos(th)[None, :] ** 2 + (mu[:, None] ** 2) * np.sin(th)[None, :] ** 2
    return np.exp(-(mu / math.pi) * np.sum(w * lg / den, axis=1))


def chandrasekhar_h_iterated(mu, albedo: float, n: int = 128, iterations: int = 5000) -> np.ndarray:
    """The same H-function by another method: fixed-point iteration of Chandrasekhar's integral
    equation 1/H(mu) = sqrt(1 - albedo) + (albedo/2) int_0^1 mu' H(mu') / (mu + mu') dmu'
    (the form that converges for albedo -> 1), Gauss-Legendre in mu', then the equation itself
    evaluated at the requested mu. Used to check :func:`chandrasekhar_h`."""
    x, w = np.polynomial.legendre.leggauss(n)
    x = 0.5 * (x + 1.0)
    w = 0.5 * w
    h = np.ones(n)
    s = math.sqrt(max(0.0, 1.0 - albedo))
    kernel = 0.5 * albedo * (w * x)[None, :] / (x[:, None] + x[None, :])
    for _ in range(iterations):
        new = 1.0 / (s + kernel @ h)
        if np.max(np.abs(new - h)) < 1e-14:
            h = new
            break
        h = new
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    return 1.0 / (s + 0.5 * albedo * np.sum(w * x * h / (mu[:, None] + x[None, :]), axis=1))


def plane_albedo_isotropic(albedo: float, mu0: float = 1.0) -> float:
    """Exact total reflectance of a semi-infinite isotropically scattering medium with no index
    mismatch, collimated incidence at cosine mu0: 1 - H(mu0) sqrt(1 - albedo)."""
    if albedo >= 1.0:
        return 1.0
    return float(1.0 - chandrasekhar_h(mu0, albedo)[0] * math.sqrt(1.0 - albedo))


def plane_radiance_isotropic(albedo: float, mu: float, mu0: float = 1.0) -> float:
    """Exact radiance reflected by a semi-infinite isotropically scattering medium with no index
    mismatch under a collimated beam at cosine mu0, seen at cosine mu (any azimuth), as
    pi L / E with E the irradiance of the surface (Chandrasekhar 1950):
    pi L / E = albedo H(mu) H(mu0) / (4 (mu + mu0)); normal incidence and view: albedo H(1)^2 / 8.
    Single scattering alone is albedo / (4 (mu + mu0))."""
    h = chandrasekhar_h(np.array([mu, mu0]), albedo)
    return float(albedo * h[0] * h[1] / (4.0 * (mu + mu0)))


# ---------------------------------------------------------------------------------------------
# Shadow edge: a half-plane lit, the other dark

def half_plane_exitance(ch: Dipole, d, n: int = 200000) -> np.ndarray:
    """Radiant exitance M(d) of a flat semi-infinite medium whose surface is lit with unit
    transmitted irradiance on x > 0 only, at signed distance d from the edge (d > 0 lit):
    M(d) = int Rd(r) 2 pi r frac(r, d) dr with frac the part of the circle of radius r around
    the point that lies on the lit side (1 - acos(d/r)/pi for |d| < r). Far on the lit side
    M -> Rd_total; far in the shadow M -> 0."""
    d = np.atleast_1d(np.asarray(d, dtype=float))
    if ch.empty:
        return np.zeros_like(d)
    rmax = 60.0 / max(ch.sigma_tr, 1e-3 * ch.sigma_t_prime) + float(np.abs(d).max())
    u = (np.arange(n) + 0.5) / n
    r = rmax * u * u
    dr = 2.0 * rmax * u / n
    w = ch.rd(r) * 2.0 * math.pi * r * dr
    out = np.empty_like(d)
    for k, dk in enumerate(d):
        with np.errstate(invalid="ignore"):
            frac = np.where(dk >= r, 1.0, np.where(dk <= -r, 0.0, 1.0 - np.arccos(np.clip(dk / r, -1, 1)) / math.pi))
        out[k] = float(np.sum(w * frac))
    return out
