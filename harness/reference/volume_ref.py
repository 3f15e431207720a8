"""Exact Monte Carlo volumetric transport in a homogeneous medium inside simple scene geometries:
the independent reference for the fork's random-walk and profile subsurface modes. Written from
the transport equation; it shares no code with the C++ library (shading/) nor with the layer
simulator :mod:`harness.reference.mc_subsurface` (which it is validated against).

Model (everything below is exact; there is no diffusion approximation anywhere):
  * a homogeneous medium with scattering and absorption coefficients sigma_s, sigma_a (1/mm, one
    value per colour channel; each channel is simulated on its own, from its own child of
    ``numpy.random.SeedSequence(seed)``), a Henyey-Greenstein phase function with asymmetry g
    (one g for all channels), relative index eta = n_medium / n_outside;
  * smooth dielectric faces with the exact unpolarised Fresnel reflectance at every crossing, from
    outside (the entering beam) and from inside (relative index 1/eta, total internal reflection
    beyond the critical angle). Inside, a photon reaching a face is reflected with probability F
    and leaves otherwise (full weight either way: unbiased);
  * free paths exponential in sigma_t = sigma_s + sigma_a; absorption by implicit capture (at each
    collision the weight is multiplied by the albedo sigma_s / sigma_t, the absorbed part is
    tallied) and Russian roulette below ``ROULETTE_WEIGHT`` (survival ``ROULETTE_SURVIVAL``, the
    survivor's weight divided by it): unbiased;
  * lighting: one directional light of irradiance E = 1 perpendicular to its beam (a face whose
    normal makes angle theta_i with ``light_dir`` receives cos(theta_i) per unit area), outside
    black. ``light_dir`` is the unit vector TOWARD the light; z is up, the medium lies below its
    top face z = 0;
  * output in POV pixel units: pi L / E, L the radiance leaving the surface toward an orthographic
    camera (``view_dir``: the outward direction from the surface toward the camera). Only light
    that entered the medium is counted; the specular reflection of the beam at the outer face is a
    delta (reported separately as ``specular``, the Fresnel reflectance at the incidence angle).
    Light leaving through a face has radiance (1 - F(mu_inside)) / eta^2 times the inside radiance.

Estimators:
  * planar faces (``sheet``, ``shadow_edge``): the inside direction w' that refracts into the view
    is the same everywhere, so every collision (weight w after absorption, incoming direction u,
    distance a to the exit face along the normal) contributes its next-event (point) estimate
        pi L += pi * w * sum_terms p(u . w_term) F^k exp(-sigma_t V_k / mu') / mu' * (1 - F) / eta^2
    with mu' = |w'_z|. The terms follow the backward ray through the slab's internal reflections:
    emission along w' with vertical travel V = a + 2 k d (k internal reflections, F^(2k)) and
    emission along the mirrored direction with V = 2 d - a + 2 k d (F^(2k+1)); a semi-infinite
    medium has the first term only, eta = 1 has F = 0. The series is summed until its remainder is
    below 1e-13 of an unattenuated direct term (at most 256 terms; the bound reached is reported
    as ``series_rest``). 1/mu' is the Jacobian of uniform illumination: the pencil response
    integrated over the surface;
  * ``shadow_edge``: light enters only at x > 0. Each photon enters at the origin and each term
    above lands at the lateral offset Delta = x_c + w'_x V / mu'; translation invariance gives
    L(x0) = E[sum of the contributions with Delta < x0] (the entry point x0 - Delta is lit), an
    exact estimator at every x0 (no bins) from one set of paths; the plateau is the sum of all.
    Where the pencil response has a line exactly at Delta = x0 (single scattering under normal
    light and normal view lands at Delta = 0) that line counts half: the profile is discontinuous
    there and the value is the mean of its two one-sided limits, so L(0) = plateau / 2 exactly
    at normal light and view;
  * ``sheet``: uniform illumination of a slab, the same estimator summed (view on the top face:
    reflection, on the bottom face: transmission; light from below is the mirror image). The
    unscattered beam (reflected inside or transmitted) is a delta and is never part of the
    radiance, also when ``view_dir`` is exactly aligned with it: the value there is the limit of
    the diffuse radiance (the same expression, continuous in view_dir);
  * ``sphere`` (eta = 1 only: with eta != 1 the point estimator would need the exit point whose
    refraction gives the view and its ray-tube Jacobian; not implemented, a ValueError says so):
    photons enter uniformly over the projected disc (power pi R^2 E), each collision contributes
    w p(u . v) exp(-sigma_t t_exit) toward the view v; projecting along v, the integral over image
    area of the radiance is the volume integral of the emission, so each pixel's value is the
    exact pixel-AREA AVERAGE of pi L (not a point sample at the pixel centre). ``flux`` is the sum
    of pixel values times pixel area = pi times the radiant intensity toward the camera. An energy
    check tallies the escaping power twice: analog (photons leaving) and the point estimator
    toward one uniformly random direction per collision times 4 pi.

  * ``spot``: a half-space lit straight down only inside a disc of radius a, seen straight down:
    the mean of pi L / E over annuli about the disc. With the shadow edge's pencil-response
    estimator, a contribution landing at lateral offset Delta is seen from the annulus's points
    P whose entry P - Delta is in the disc, area(annulus & disc moved by Delta) / area(annulus):
    exact, no bins in Delta. Outside the disc this is the medium's radial profile as a render
    shows it (single scattering under normal light and view stays under the disc).

  * ``sphere_intensity`` (any eta): the radiant intensity toward the view by analog escape.
    Photons enter over the disc the light sees (weight 1 - F), refract in, walk, and refract
    out where they leave. By symmetry about the light's axis the intensity depends only on the
    angle to the light, so every photon leaving within +-band of the view's angle is tallied,
    over the band's solid angle 4 pi sin(theta) sin(band). That is the band's average of I:
    O(band^2) from I (2 degrees: ~1e-4 of a smooth I), and no exit-point solve or ray-tube
    factor is involved.

Exact means: unbiased for the stated model up to float rounding and the series cut above; the only
randomness is Monte Carlo noise, reported as standard errors. Not exact / not modelled: the
sphere's image with eta != 1 (refused; its intensity: sphere_intensity), polarisation, a rough
face, anything outside the medium but the shadow plate (which neither reflects nor blocks the
view).

Standard errors come from independent per-path totals (each photon path is one sample; a path's
contributions to all its tallies are summed before squaring). Paths run in batches (vectorised
over photons with numpy); results repeat bit for bit for the same arguments and numpy version.

Command line:  python -m harness.reference.volume_ref {sheet,edge,sphere} --help
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

__all__ = ["EdgeResult", "SheetResult", "SphereResult", "fresnel", "hg_density", "hg_sample_cos", "deflect",
           "image_axes", "shadow_edge", "sheet", "sphere", "SphereIntensityResult", "sphere_intensity", "SpotResult",
           "spot", "circle_overlap", "SKIN1",
           "main"]

#: Russian roulette: paths whose weight falls below this survive with ROULETTE_SURVIVAL.
ROULETTE_WEIGHT = 0.02
ROULETTE_SURVIVAL = 0.25
#: Relative remainder at which the internal-reflection series of a slab is cut.
SERIES_TOL = 1e-13
SERIES_MAX = 256

#: Jensen et al. 2001 skin 1 (sigma_s' and sigma_a in 1/mm), used with g = 0 (sigma_s = sigma_s').
SKIN1 = {"sigma_s": (0.74, 0.88, 1.01), "sigma_a": (0.032, 0.17, 0.48), "g": 0.0, "eta": 1.3}


# ---------------------------------------------------------------------------------------------
# Optics


def fresnel(cos_i, n_rel):
    """Unpolarised Fresnel reflectance of a smooth interface for light arriving with cosine
    ``cos_i`` (>= 0) to the normal from the side of index n1, n_rel = n2 / n1; 1 under total
    internal reflection. Mean of the s and p amplitude reflectances squared."""
    c = np.abs(np.asarray(cos_i, dtype=float))
    sin2_t = (1.0 - c * c) / (n_rel * n_rel)
    tir = sin2_t >= 1.0
    ct = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    with np.errstate(invalid="ignore", divide="ignore"):
        rs = (c - n_rel * ct) / (c + n_rel * ct)
        rp = (n_rel * c - ct) / (n_rel * c + ct)
        f = 0.5 * (rs * rs + rp * rp)
    f = np.where(tir, 1.0, np.where(c + ct > 0, f, 1.0))
    return f if f.ndim else float(f)


def hg_density(cos_t, g: float):
    """Henyey-Greenstein phase function per steradian: (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^1.5)."""
    q = 1.0 + g * g - 2.0 * g * np.asarray(cos_t, dtype=float)
    return (1.0 - g * g) / (4.0 * math.pi * q * np.sqrt(q))


def hg_sample_cos(g: float, xi: np.ndarray) -> np.ndarray:
    """Cosine of the HG deflection by inverting its cumulative distribution at xi in [0, 1)."""
    if abs(g) < 1e-6:
        return 2.0 * xi - 1.0
    f = (1.0 - g * g) / (1.0 + g * (2.0 * xi - 1.0))
    return np.clip((1.0 + g * g - f * f) / (2.0 * g), -1.0, 1.0)


def deflect(ux, uy, uz, cos_t, phi):
    """Directions at angle acos(cos_t), azimuth phi about (ux, uy, uz), in the orthonormal frame of
    Duff et al. (2017), which is continuous except across uz = 0 where it stays orthonormal."""
    s = np.where(uz >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + uz)
    b = ux * uy * a
    t1x, t1y, t1z = 1.0 + s * ux * ux * a, s * b, -s * ux
    t2x, t2y, t2z = b, s + uy * uy * a, -uy
    st = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    c1, c2 = st * np.cos(phi), st * np.sin(phi)
    nx = c1 * t1x + c2 * t2x + cos_t * ux
    ny = c1 * t1y + c2 * t2y + cos_t * uy
    nz = c1 * t1z + c2 * t2z + cos_t * uz
    r = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz)
    return nx * r, ny * r, nz * r


def _unit(v, name: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.shape[-1] != 3:
        raise ValueError(f"{name}: need 3-vectors, got shape {v.shape}")
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    if not (n > 0).all():
        raise ValueError(f"{name}: zero vector")
    return v / n


def _channels(sigma_s, sigma_a):
    ss = np.atleast_1d(np.asarray(sigma_s, dtype=float))
    sa = np.atleast_1d(np.asarray(sigma_a, dtype=float))
    ss, sa = np.broadcast_arrays(ss, sa)
    if ss.ndim != 1:
        raise ValueError("sigma_s, sigma_a: scalars or 1-D per-channel sequences")
    if not ((ss >= 0).all() and (sa >= 0).all() and (ss + sa > 0).all()):
        raise ValueError(f"need sigma_s, sigma_a >= 0 and sigma_t > 0, got {ss}, {sa}")
    return ss.astype(float), sa.astype(float)


def _check_g_eta(g: float, eta: float) -> None:
    if not (-1.0 < g < 1.0):
        raise ValueError(f"g = {g}: need -1 < g < 1")
    if not eta > 0:
        raise ValueError(f"eta = {eta}: need > 0")


# ---------------------------------------------------------------------------------------------
# The random walk (one channel, one batch of paths)


class _Slab:
    """Medium -d < z < 0 (d = inf: half-space z < 0). Faces: 0 = top, 1 = bottom."""

    def __init__(self, d: float):
        self.d = float(d)

    def distance(self, x, y, z, ux, uy, uz):
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(uz > 0.0, -z / uz, np.inf)
            if math.isfinite(self.d):
                t = np.where(uz < 0.0, (z + self.d) / -uz, t)
        return np.maximum(t, 0.0)

    def face(self, x, y, z, ux, uy, uz):
        """Face index and cosine of incidence (inside) at boundary points."""
        return np.where(uz > 0.0, 0, 1), np.abs(uz)

    def reflect(self, x, y, z, ux, uy, uz):
        return x, y, np.where(uz > 0.0, 0.0, -self.d), ux, uy, -uz


class _Sphere:
    """Medium |r| < R. One face (0)."""

    def __init__(self, radius: float):
        self.r = float(radius)

    def distance(self, x, y, z, ux, uy, uz):
        b = x * ux + y * uy + z * uz
        c = x * x + y * y + z * z - self.r * self.r
        return np.maximum(0.0, -b + np.sqrt(np.maximum(0.0, b * b - c)))

    def face(self, x, y, z, ux, uy, uz):
        return np.zeros(x.shape, dtype=np.int64), np.abs(x * ux + y * uy + z * uz) / self.r

    def reflect(self, x, y, z, ux, uy, uz):
        k = 2.0 * (x * ux + y * uy + z * uz) / (self.r * self.r)
        return x, y, z, ux - k * x, uy - k * y, uz - k * z


def _disc_entry(rng, m: int, R: float, light, e1, e2):
    """m points where parallel light along -light meets a sphere of radius R at the origin,
    uniform over the disc it sees (e1, e2: the disc's axes): (x, y, z, h), h = R cos_i."""
    rho = R * np.sqrt(rng.random(m))
    phi = 2.0 * math.pi * rng.random(m)
    b1, b2 = rho * np.cos(phi), rho * np.sin(phi)
    h = np.sqrt(np.maximum(0.0, R * R - rho * rho))
    return (b1 * e1[0] + b2 * e2[0] + h * light[0], b1 * e1[1] + b2 * e2[1] + h * light[1],
            b1 * e1[2] + b2 * e2[2] + h * light[2], h)


@dataclass
class _Walk:
    """Per-path analog tallies of one batch: weight leaving through each face (order 0 =
    unscattered, >= 1 scattered), weight absorbed, and the number of collisions."""

    exit0: np.ndarray      # (n, faces) unscattered
    exit1: np.ndarray      # (n, faces) scattered at least once
    absorbed: np.ndarray   # (n,)
    collisions: int


def _walk(rng, start, sigma_s: float, sigma_a: float, g: float, eta: float, geom, n_faces: int,
          on_collision=None, max_steps: int = 1_000_000, on_exit=None) -> _Walk:
    """Follow the paths from ``start`` = (x, y, z, ux, uy, uz, w) (inside the medium, moving
    inward) until they leave or die. ``on_collision(pid, x, y, z, ux, uy, uz, w)`` is called at
    each collision with the incoming direction and the weight after absorption (the scattered
    weight), before the new direction is drawn. ``on_exit(pid, x, y, z, ux, uy, uz, w, order)``
    is called for the paths that leave, at the face, with their direction inside."""
    x, y, z, ux, uy, uz, w = (np.array(a, dtype=float) for a in start)
    n = x.size
    pid = np.arange(n)
    order = np.zeros(n, dtype=np.int64)
    sigma_t = sigma_s + sigma_a
    albedo = sigma_s / sigma_t
    exit0 = np.zeros((n, n_faces))
    exit1 = np.zeros((n, n_faces))
    absorbed = np.zeros(n)
    collisions = 0
    steps = 0
    while pid.size and steps < max_steps:
        steps += 1
        m = pid.size
        s = -np.log1p(-rng.random(m)) / sigma_t
        t = geom.distance(x, y, z, ux, uy, uz)
        hit = s >= t
        if hit.any():
            hx, hy, hz = x[hit] + ux[hit] * t[hit], y[hit] + uy[hit] * t[hit], z[hit] + uz[hit] * t[hit]
            hux, huy, huz = ux[hit], uy[hit], uz[hit]
            face, cos_i = geom.face(hx, hy, hz, hux, huy, huz)
            f = fresnel(cos_i, 1.0 / eta) if eta != 1.0 else np.zeros(cos_i.shape)
            refl = rng.random(hx.size) < f
            leave = ~refl
            hp, ho, hw = pid[hit], order[hit], w[hit]
            for tab, sel in ((exit0, leave & (ho == 0)), (exit1, leave & (ho > 0))):
                tab[hp[sel], face[sel]] += hw[sel]      # pids are unique within a step
            if on_exit is not None and leave.any():
                on_exit(hp[leave], hx[leave], hy[leave], hz[leave], hux[leave], huy[leave], huz[leave], hw[leave],
                        ho[leave])
            rx, ry, rz, rux, ruy, ruz = geom.reflect(hx, hy, hz, hux, huy, huz)
            x[hit], y[hit], z[hit], ux[hit], uy[hit], uz[hit] = rx, ry, rz, rux, ruy, ruz
            w[hit] = np.where(refl, hw, 0.0)
        col = ~hit
        if col.any():
            sc = s[col]
            cx, cy, cz = x[col] + ux[col] * sc, y[col] + uy[col] * sc, z[col] + uz[col] * sc
            cux, cuy, cuz = ux[col], uy[col], uz[col]
            cw = w[col]
            cp = pid[col]
            absorbed[cp] += cw * (1.0 - albedo)   # pids are unique within a step
            cw = cw * albedo
            collisions += int(cp.size)
            if on_collision is not None:
                on_collision(cp, cx, cy, cz, cux, cuy, cuz, cw)
            k = cp.size
            nx, ny, nz = deflect(cux, cuy, cuz, hg_sample_cos(g, rng.random(k)), 2.0 * math.pi * rng.random(k))
            x[col], y[col], z[col], ux[col], uy[col], uz[col], w[col] = cx, cy, cz, nx, ny, nz, cw
            order[col] += 1
        low = (w > 0.0) & (w < ROULETTE_WEIGHT)
        if low.any():
            live = rng.random(int(low.sum())) < ROULETTE_SURVIVAL
            w[low] = np.where(live, w[low] / ROULETTE_SURVIVAL, 0.0)
        keep = w > 0.0
        if not keep.all():
            pid, order, x, y, z, ux, uy, uz, w = (a[keep] for a in (pid, order, x, y, z, ux, uy, uz, w))
    if pid.size:
        raise RuntimeError(f"{pid.size} paths still running after {max_steps} steps (their weight would be lost)")
    return _Walk(exit0, exit1, absorbed, collisions)


class _Stats:
    """Running sums of per-path totals (any shape per path) for means and standard errors."""

    def __init__(self, shape=()):
        self.n = 0
        self.s = np.zeros(shape)
        self.s2 = np.zeros(shape)

    def add(self, per_path: np.ndarray) -> None:
        self.n += per_path.shape[0]
        self.s += per_path.sum(axis=0)
        self.s2 += (per_path * per_path).sum(axis=0)

    def add_sums(self, n: int, s, s2) -> None:
        self.n += n
        self.s += s
        self.s2 += s2

    @property
    def mean(self):
        return self.s / max(self.n, 1)

    @property
    def err(self):
        n = self.n
        if n < 2:
            return np.full(np.shape(self.s), np.inf)
        return np.sqrt(np.maximum(0.0, self.s2 - self.s * self.s / n) / (n * (n - 1)))


# ---------------------------------------------------------------------------------------------
# Planar faces: views, entering beam, the point estimator with its internal-reflection series


@dataclass
class _PlaneView:
    """An outside view of a slab face, with what the point estimator needs."""

    face: int          # 0 = top (view z > 0), 1 = bottom (z < 0)
    wx: float          # inside direction toward the face (leaving it): horizontal part
    wy: float
    mu: float          # its cosine with the face normal (> 0); 0: unreachable (eta < 1)
    exit_factor: float  # (1 - F_inside(mu)) / eta^2 / mu (1/mu: uniform-illumination Jacobian)
    f_in: float        # inside Fresnel reflectance at mu (the series ratio)


def _plane_view(v: np.ndarray, eta: float) -> _PlaneView:
    face = 0 if v[2] > 0 else 1
    sx, sy = v[0] / eta, v[1] / eta            # Snell: n_in sin_in = n_out sin_out
    s2 = sx * sx + sy * sy
    if v[2] == 0 or s2 >= 1.0:
        return _PlaneView(face, sx, sy, 0.0, 0.0, 0.0)
    mu = math.sqrt(1.0 - s2)
    f_in = float(fresnel(mu, 1.0 / eta))
    return _PlaneView(face, sx, sy, mu, (1.0 - f_in) / (eta * eta) / mu, f_in)


def _plane_terms(pv: _PlaneView, sigma_t: float, d: float):
    """The series of the point estimator as (mirrored, factor) per term k = 0, 1, 2, ...: F^k,
    emission along w' for even k (vertical travel V = a + k d), along its mirror image for odd k
    (V = (k + 1) d - a), a the distance of the collision to the exit face. Cut when (F t)^k < SERIES_TOL,
    t = exp(-sigma_t d / mu) (every V >= k d); returns the terms and that bound of the remainder
    relative to an unattenuated direct term, (F t)^K / (1 - F t)."""
    if pv.mu == 0.0:
        return [], 0.0
    if not math.isfinite(d) or pv.f_in == 0.0:
        return [(False, 1.0)], 0.0
    q = pv.f_in * math.exp(-sigma_t * d / pv.mu)
    terms = []
    for k in range(SERIES_MAX):
        terms.append((k % 2 == 1, pv.f_in ** k))
        if q ** (k + 1) < SERIES_TOL:
            break
    return terms, float(q ** len(terms) / (1.0 - q))


def _travel(k: int, a, d: float):
    """Vertical travel of term k (see :func:`_plane_terms`)."""
    if k == 0:
        return a                                 # also for d = inf
    return a + k * d if k % 2 == 0 else (k + 1) * d - a


def _plane_entry(light: np.ndarray, eta: float):
    """Refracted direction and the fraction (1 - F) of the beam entering the top face."""
    cos_i = float(light[2])
    dx, dy = -light[0] / eta, -light[1] / eta
    dz = -math.sqrt(max(0.0, 1.0 - dx * dx - dy * dy))
    return (dx, dy, dz), cos_i, 1.0 - float(fresnel(cos_i, eta))


def _contrib(pv, terms, sigma_t, d, g, z, ux, uy, uz, w):
    """Per term: (contribution pi * w * p * F^k exp(-sigma_t V / mu) * exit factor, V)."""
    a = -z if pv.face == 0 else z + d            # distance to the exit face along the normal
    # w' leaves the exit face: up (+z) at the top, down at the bottom; the mirrored one opposite.
    sz = 1.0 if pv.face == 0 else -1.0
    horiz = ux * pv.wx + uy * pv.wy
    p_dir = hg_density(horiz + uz * (sz * pv.mu), g)
    p_mir = hg_density(horiz - uz * (sz * pv.mu), g) if len(terms) > 1 else None
    out = []
    for k, (mirrored, fac) in enumerate(terms):
        v = _travel(k, a, d)
        p = p_mir if mirrored else p_dir
        out.append((math.pi * pv.exit_factor * fac * w * p * np.exp(-sigma_t * v / pv.mu), v))
    return out


class _Collector:
    """(key, value) pairs gathered over a batch, summed per key at its end."""

    def __init__(self):
        self.keys: list[np.ndarray] = []
        self.vals: list[np.ndarray] = []

    def add(self, key, val) -> None:
        self.keys.append(key)
        self.vals.append(val)

    def totals(self, size: int) -> np.ndarray:
        if not self.keys:
            return np.zeros(size)
        return np.bincount(np.concatenate(self.keys), weights=np.concatenate(self.vals), minlength=size)


# ---------------------------------------------------------------------------------------------
# Scene 1: shadow edge


@dataclass
class EdgeResult:
    """pi L / E across a shadow edge, per channel (rows) and position (columns)."""

    xs: np.ndarray
    radiance: np.ndarray        # (channels, len(xs))
    radiance_err: np.ndarray
    plateau: np.ndarray         # (channels,) far on the lit side (uniform illumination)
    plateau_err: np.ndarray
    specular: float             # Fresnel reflectance of the beam at the outer face (not included)
    n_paths: np.ndarray         # per channel
    collisions: np.ndarray
    seconds: np.ndarray         # per channel
    series_rest: float = 0.0    # relative remainder of the internal-reflection series (slab)
    extra: dict = field(default_factory=dict)


def _run_batches(n_paths, batch, target_rel_err, max_paths, one_batch, stop_value):
    """Run ``one_batch(m)`` until n_paths are done, or (target_rel_err) until the relative
    standard error of ``stop_value()`` is below it (at most max_paths)."""
    done = 0
    while True:
        if target_rel_err is None:
            if done >= n_paths:
                break
            m = min(batch, n_paths - done)
        else:
            if done >= max_paths:
                break
            if done >= 2 * batch:
                mean, err = stop_value()
                if mean > 0 and err <= target_rel_err * mean:
                    break
            m = min(batch, max_paths - done)
        one_batch(m)
        done += m
    return done


def shadow_edge(sigma_s, sigma_a, g: float, eta: float, light_dir, xs, *, thickness: float = math.inf,
                view_dir=(0.0, 0.0, 1.0), n_paths: int = 100_000, seed: int = 1, batch: int = 20_000,
                target_rel_err: float | None = None, max_paths: int = 10_000_000) -> EdgeResult:
    """pi L / E at positions ``xs`` (mm) across the edge of a shadow: the surface z = 0 of a
    half-space (or a slab of ``thickness``) is lit by ``light_dir`` (z > 0, toward the light) only
    at x > 0 (a black, infinitely thin plate just above covers x < 0: it blocks light, not the
    view). Camera along ``view_dir`` (default straight down onto the top face). By translation
    invariance in y the value is also the row average. ``target_rel_err``: run batches until the
    plateau's standard error is below that fraction in every channel (``n_paths`` ignored)."""
    ss, sa = _channels(sigma_s, sigma_a)
    _check_g_eta(g, eta)
    light = _unit(light_dir, "light_dir")
    view = _unit(view_dir, "view_dir")
    if not light[2] > 0:
        raise ValueError("light_dir: the light must be above the surface (z > 0)")
    if not view[2] > 0:
        raise ValueError("view_dir: the camera must see the top face (z > 0)")
    if not thickness > 0:
        raise ValueError("thickness must be > 0 (inf: half-space)")
    xs = np.atleast_1d(np.asarray(xs, dtype=float))
    order = np.argsort(xs, kind="stable")
    xs_sorted = xs[order]
    nx = xs.size
    d = float(thickness)
    (dx, dy, dz), cos_i, t_in = _plane_entry(light, eta)
    scale = cos_i * t_in                       # entering power per unit area per unit E
    pv = _plane_view(view, eta)
    geom = _Slab(d)
    seqs = np.random.SeedSequence(seed).spawn(ss.size)
    nch = ss.size
    rad = np.zeros((nch, nx))
    rad_e = np.zeros((nch, nx))
    plat = np.zeros(nch)
    plat_e = np.zeros(nch)
    npaths = np.zeros(nch, dtype=np.int64)
    ncoll = np.zeros(nch, dtype=np.int64)
    secs = np.zeros(nch)
    rest = 0.0
    for c in range(nch):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seqs[c])
        st = ss[c] + sa[c]
        terms, rest = _plane_terms(pv, st, d)
        prof = _Stats((nx,))
        total = _Stats()
        coll = [0]

        def one_batch(m):
            acc = _Collector()

            def on_collision(pid, x, y, z, ux, uy, uz, w):
                for val, v in _contrib(pv, terms, st, d, g, z, ux, uy, uz, w):
                    delta = x + pv.wx * v / pv.mu          # exit point: the entry at x0 - delta
                    # lit entry (x0 - delta > 0) for x0 = xs_sorted[k:]: a suffix, summed below.
                    # delta == x0 exactly (a line in the pencil response, e.g. single scattering
                    # under normal light and view at x0 = 0) counts half: the mean of both limits.
                    kr = np.searchsorted(xs_sorted, delta, side="right")
                    kl = np.searchsorted(xs_sorted, delta, side="left")
                    base = pid * (nx + 1)
                    tie = kl != kr
                    if tie.any():
                        acc.add(base[tie] + kl[tie], 0.5 * val[tie])
                        acc.add(base[tie] + kr[tie], 0.5 * val[tie])
                        acc.add(base[~tie] + kr[~tie], val[~tie])
                    else:
                        acc.add(base + kr, val)

            start = (np.zeros(m), np.zeros(m), np.zeros(m), np.full(m, dx), np.full(m, dy), np.full(m, dz),
                     np.ones(m))
            wk = _walk(rng, start, ss[c], sa[c], g, eta, geom, 2, on_collision)
            coll[0] += wk.collisions
            per = acc.totals(m * (nx + 1)).reshape(m, nx + 1) * scale
            prof.add(np.cumsum(per[:, :nx], axis=1))
            total.add(per.sum(axis=1))

        npaths[c] = _run_batches(n_paths, batch, target_rel_err, max_paths, one_batch,
                                 lambda: (float(total.mean), float(total.err)))
        inv = np.empty_like(order)
        inv[order] = np.arange(nx)
        rad[c] = prof.mean[inv]
        rad_e[c] = prof.err[inv]
        plat[c] = total.mean
        plat_e[c] = total.err
        ncoll[c] = coll[0]
        secs[c] = time.perf_counter() - t0
    return EdgeResult(xs=xs, radiance=rad, radiance_err=rad_e, plateau=plat, plateau_err=plat_e,
                      specular=1.0 - t_in, n_paths=npaths, collisions=ncoll, seconds=secs, series_rest=rest)


# ---------------------------------------------------------------------------------------------
# Scene 2: uniformly lit sheet


@dataclass
class SheetResult:
    """pi L / E of a uniformly lit slab per channel (and per view when several are given), plus
    analog tallies per unit power ENTERING the medium (as in MCML-style layer codes)."""

    radiance: np.ndarray          # (channels,) or (channels, views)
    radiance_err: np.ndarray
    specular: float               # Fresnel reflectance of the beam at the lit face (a delta, not included)
    entering: float               # 1 - specular
    reflectance: np.ndarray       # (channels,) scattered light leaving the lit face / entering power
    reflectance_err: np.ndarray
    transmittance: np.ndarray     # scattered light leaving the other face / entering power
    transmittance_err: np.ndarray
    ballistic_r: np.ndarray       # unscattered, leaving the lit face (after internal reflections)
    ballistic_t: np.ndarray       # unscattered, leaving the other face
    absorbed: np.ndarray
    absorbed_err: np.ndarray
    n_paths: np.ndarray
    collisions: np.ndarray
    seconds: np.ndarray
    series_rest: float = 0.0


def sheet(sigma_s, sigma_a, g: float, eta: float, thickness: float, light_dir, view_dir, *,
          n_paths: int = 100_000, seed: int = 1, batch: int = 20_000, target_rel_err: float | None = None,
          max_paths: int = 10_000_000) -> SheetResult:
    """pi L / E of an infinite slab (faces z = 0 and z = -thickness; ``thickness`` = inf: the
    half-space z < 0) lit uniformly from ``light_dir`` (z > 0 from above, z < 0 from below) and
    seen along ``view_dir`` (z > 0: the top face, z < 0: the bottom face). ``view_dir`` may be
    (n, 3) for several views from the same paths. The unscattered beam (a delta) is excluded, also
    at a view exactly aligned with it."""
    ss, sa = _channels(sigma_s, sigma_a)
    _check_g_eta(g, eta)
    light = _unit(light_dir, "light_dir")
    views = np.atleast_2d(_unit(view_dir, "view_dir"))
    single = np.ndim(view_dir) == 1
    if light[2] == 0 or (views[:, 2] == 0).any():
        raise ValueError("light_dir and view_dir must not be parallel to the faces")
    if not thickness > 0:
        raise ValueError("thickness must be > 0 (inf: half-space)")
    if light[2] < 0:                           # lit from below: the mirror image
        if not math.isfinite(thickness):
            raise ValueError("a half-space cannot be lit from below")
        light = light * np.array([1.0, 1.0, -1.0])
        views = views * np.array([1.0, 1.0, -1.0])
    if not math.isfinite(thickness) and (views[:, 2] < 0).any():
        raise ValueError("a half-space has no bottom face to view")
    d = float(thickness)
    (dx, dy, dz), cos_i, t_in = _plane_entry(light, eta)
    scale = cos_i * t_in
    pvs = [_plane_view(v, eta) for v in views]
    nv = len(pvs)
    geom = _Slab(d)
    seqs = np.random.SeedSequence(seed).spawn(ss.size)
    nch = ss.size
    out = {k: np.zeros((nch, nv)) for k in ("rad", "rad_e")}
    res = {k: np.zeros(nch) for k in ("r", "r_e", "t", "t_e", "br", "bt", "a", "a_e", "s")}
    npaths = np.zeros(nch, dtype=np.int64)
    ncoll = np.zeros(nch, dtype=np.int64)
    rest = 0.0
    for c in range(nch):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seqs[c])
        st = ss[c] + sa[c]
        allterms = [_plane_terms(pv, st, d) for pv in pvs]
        rest = max([rest] + [r for _, r in allterms])
        stats = _Stats((nv + 5,))             # views, R, T, ballistic R, ballistic T, absorbed
        coll = [0]

        def one_batch(m):
            acc = _Collector()

            def on_collision(pid, x, y, z, ux, uy, uz, w):
                for j, pv in enumerate(pvs):
                    for val, _ in _contrib(pv, allterms[j][0], st, d, g, z, ux, uy, uz, w):
                        acc.add(pid * nv + j, val)

            start = (np.zeros(m), np.zeros(m), np.zeros(m), np.full(m, dx), np.full(m, dy), np.full(m, dz),
                     np.ones(m))
            wk = _walk(rng, start, ss[c], sa[c], g, eta, geom, 2, on_collision)
            coll[0] += wk.collisions
            per = np.concatenate([acc.totals(m * nv).reshape(m, nv) * scale, wk.exit1, wk.exit0, wk.absorbed[:, None]], axis=1)
            stats.add(per)

        npaths[c] = _run_batches(n_paths, batch, target_rel_err, max_paths, one_batch,
                                 lambda: (float(stats.mean[:nv].min()), float(stats.err[:nv].max())))
        mean, err = stats.mean, stats.err
        out["rad"][c], out["rad_e"][c] = mean[:nv], err[:nv]
        res["r"][c], res["r_e"][c] = mean[nv], err[nv]
        res["t"][c], res["t_e"][c] = mean[nv + 1], err[nv + 1]
        res["br"][c], res["bt"][c] = mean[nv + 2], mean[nv + 3]
        res["a"][c], res["a_e"][c] = mean[nv + 4], err[nv + 4]
        ncoll[c] = coll[0]
        res["s"][c] = time.perf_counter() - t0
    rad, rad_e = out["rad"], out["rad_e"]
    if single:
        rad, rad_e = rad[:, 0], rad_e[:, 0]
    return SheetResult(radiance=rad, radiance_err=rad_e, specular=1.0 - t_in, entering=t_in,
                       reflectance=res["r"], reflectance_err=res["r_e"], transmittance=res["t"],
                       transmittance_err=res["t_e"], ballistic_r=res["br"], ballistic_t=res["bt"],
                       absorbed=res["a"], absorbed_err=res["a_e"], n_paths=npaths, collisions=ncoll,
                       seconds=res["s"], series_rest=rest)


# ---------------------------------------------------------------------------------------------
# Scene 3: sphere (eta = 1)


def image_axes(view_dir) -> tuple[np.ndarray, np.ndarray]:
    """The camera's image axes for ``view_dir`` (toward the camera): right = unit(h x view) with
    h = +z (or +y when view is within ~8 degrees of the z axis), up = view x right, so (right, up,
    view) is right-handed and the camera, looking along -view, sees right to its right."""
    v = _unit(view_dir, "view_dir")
    h = np.array([0.0, 0.0, 1.0]) if abs(v[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    r = np.cross(h, v)
    r /= np.linalg.norm(r)
    return r, np.cross(v, r)


@dataclass
class SphereResult:
    """Image of pi L / E (pixel-area averages) and its total, per channel."""

    image: np.ndarray            # (channels, npix, npix); row 0 at the top (+up), column 0 at -right
    image_err: np.ndarray
    flux: np.ndarray             # (channels,) sum of pixels times pixel area (mm^2) = pi I / E
    flux_err: np.ndarray
    pixel_size: float            # mm
    right: np.ndarray
    up: np.ndarray
    entering: float              # pi R^2 (power entering per unit E; eta = 1: no reflection)
    escaped: np.ndarray          # analog: power leaving after >= 1 scattering, per unit E
    escaped_err: np.ndarray
    escaped_est: np.ndarray      # 4 pi x point estimate toward a random direction per collision
    escaped_est_err: np.ndarray
    escape_diff_err: np.ndarray  # standard error of escaped_est - escaped (same paths)
    unscattered: np.ndarray      # power crossing without scattering (analog)
    absorbed: np.ndarray
    absorbed_err: np.ndarray
    n_paths: np.ndarray
    collisions: np.ndarray
    seconds: np.ndarray


def sphere(sigma_s, sigma_a, g: float, eta: float, radius: float, light_dir, view_dir, npix: int = 32, *,
           n_paths: int = 100_000, seed: int = 1, batch: int = 20_000) -> SphereResult:
    """Orthographic image of a sphere of ``radius`` (mm) centred at the origin, lit by
    ``light_dir``, seen along ``view_dir``: npix x npix pixels spanning [-1.1 R, 1.1 R]^2 in the
    axes of :func:`image_axes`; pixel (i, j) covers right in [-1.1 R + j s, -1.1 R + (j + 1) s],
    up in [1.1 R - (i + 1) s, 1.1 R - i s] with s = 2.2 R / npix (its centre at half a pixel), and
    holds the AVERAGE of pi L / E over that area (exact; not a point sample). eta = 1 only."""
    ss, sa = _channels(sigma_s, sigma_a)
    _check_g_eta(g, eta)
    if eta != 1.0:
        raise ValueError(f"sphere: eta = {eta} is not supported; the exact point estimator through a curved "
                         "refracting face (exit point and ray-tube Jacobian) is not implemented, only eta = 1")
    if not radius > 0:
        raise ValueError("radius must be > 0")
    npix = int(npix)
    light = _unit(light_dir, "light_dir")
    view = _unit(view_dir, "view_dir")
    right, up = image_axes(view)
    R = float(radius)
    pix = 2.2 * R / npix
    area = pix * pix
    # A frame for the entry disc, perpendicular to the light.
    e1, e2 = image_axes(light)
    geom = _Sphere(R)
    power = math.pi * R * R
    seqs = np.random.SeedSequence(seed).spawn(ss.size)
    nch = ss.size
    npx = npix * npix
    img = np.zeros((nch, npix, npix))
    img_e = np.zeros((nch, npix, npix))
    res = {k: np.zeros(nch) for k in ("f", "f_e", "e", "e_e", "q", "q_e", "dq", "u", "a", "a_e", "s")}
    npaths = np.zeros(nch, dtype=np.int64)
    ncoll = np.zeros(nch, dtype=np.int64)
    for c in range(nch):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seqs[c])
        dirs_rng = np.random.default_rng(seqs[c].spawn(1)[0])
        st = ss[c] + sa[c]
        pix_stats = _Stats((npx,))
        scal = _Stats((6,))                   # flux, escaped, escaped_est, est - analog, unscattered, absorbed
        coll = 0
        done = 0
        while done < n_paths:
            m = min(batch, n_paths - done)
            keys, vals = [], []
            flux = _Collector()
            est = _Collector()

            def on_collision(pid, x, y, z, ux, uy, uz, w):
                p = hg_density(ux * view[0] + uy * view[1] + uz * view[2], g)
                t = geom.distance(x, y, z, np.full(x.shape, view[0]), np.full(x.shape, view[1]),
                                  np.full(x.shape, view[2]))
                val = w * p * np.exp(-st * t)
                a = x * right[0] + y * right[1] + z * right[2]
                b = x * up[0] + y * up[1] + z * up[2]
                j = np.clip(((a + 1.1 * R) / pix).astype(np.int64), 0, npix - 1)
                i = np.clip(((1.1 * R - b) / pix).astype(np.int64), 0, npix - 1)
                keys.append(pid * npx + i * npix + j)
                vals.append(val)
                flux.add(pid, val)
                # Energy check: one uniformly random direction per collision.
                k = x.size
                cz = 2.0 * dirs_rng.random(k) - 1.0
                ph = 2.0 * math.pi * dirs_rng.random(k)
                sz = np.sqrt(np.maximum(0.0, 1.0 - cz * cz))
                rx, ry = sz * np.cos(ph), sz * np.sin(ph)
                tr = geom.distance(x, y, z, rx, ry, cz)
                pr = hg_density(ux * rx + uy * ry + uz * cz, g)
                est.add(pid, 4.0 * math.pi * w * pr * np.exp(-st * tr))

            px, py, pz, h = _disc_entry(rng, m, R, light, e1, e2)
            start = (px, py, pz, np.full(m, -light[0]), np.full(m, -light[1]), np.full(m, -light[2]),
                     np.ones(m))                 # unit weights (roulette is relative); power below
            wk = _walk(rng, start, ss[c], sa[c], g, 1.0, geom, 1, on_collision)
            coll += wk.collisions
            if keys:
                kk = np.concatenate(keys)
                vv = np.concatenate(vals)
                uk, inv = np.unique(kk, return_inverse=True)
                sums = np.bincount(inv, weights=vv) * power
                px_of = uk % npx
                pix_stats.add_sums(m, np.bincount(px_of, weights=sums, minlength=npx),
                                   np.bincount(px_of, weights=sums * sums, minlength=npx))
            else:
                pix_stats.add_sums(m, np.zeros(npx), np.zeros(npx))
            esc = wk.exit1[:, 0]
            fl, es = flux.totals(m), est.totals(m)
            scal.add(power * np.stack([fl, esc, es, es - esc, wk.exit0[:, 0], wk.absorbed], axis=1))
            done += m
        k = math.pi / area
        img[c] = (pix_stats.mean * k).reshape(npix, npix)
        img_e[c] = (pix_stats.err * k).reshape(npix, npix)
        mean, err = scal.mean, scal.err
        res["f"][c], res["f_e"][c] = math.pi * mean[0], math.pi * err[0]
        res["e"][c], res["e_e"][c] = mean[1], err[1]
        res["q"][c], res["q_e"][c] = mean[2], err[2]
        res["dq"][c] = err[3]
        res["u"][c] = mean[4]
        res["a"][c], res["a_e"][c] = mean[5], err[5]
        npaths[c] = done
        ncoll[c] = coll
        res["s"][c] = time.perf_counter() - t0
    return SphereResult(image=img, image_err=img_e, flux=res["f"], flux_err=res["f_e"], pixel_size=pix,
                        right=right, up=up, entering=power, escaped=res["e"], escaped_err=res["e_e"],
                        escaped_est=res["q"], escaped_est_err=res["q_e"], escape_diff_err=res["dq"],
                        unscattered=res["u"], absorbed=res["a"], absorbed_err=res["a_e"], n_paths=npaths,
                        collisions=ncoll, seconds=res["s"])


@dataclass
class SphereIntensityResult:
    """pi I / E toward the view (I the radiant intensity: the image's radiance integrated over
    its area, as ``SphereResult.flux``), per channel, from the photons that leave after at least
    one scattering event, and the band's half-width."""

    flux: np.ndarray             # (channels,)
    flux_err: np.ndarray
    band_deg: float
    entering: np.ndarray         # power entering (after the entry Fresnel loss) per unit E
    n_paths: np.ndarray
    seconds: np.ndarray


def sphere_intensity(sigma_s, sigma_a, g: float, eta: float, radius: float, light_dir, view_dir, *,
                     band_deg: float = 2.0, n_paths: int = 200_000, seed: int = 1,
                     batch: int = 20_000) -> SphereIntensityResult:
    """Radiant intensity of a sphere of ``radius`` (mm) toward ``view_dir`` under ``light_dir``,
    for any eta, by analog escape: photons enter uniformly over the disc the light sees, refract
    in (weight 1 - F from outside), walk, and refract out where they leave. By symmetry about
    the light's axis the intensity depends only on the angle between the view and the light, so
    every photon leaving (after >= 1 scattering) at an angle to the light within +-band_deg of
    the view's is tallied, divided by that band's solid angle 4 pi sin(theta) sin(band): the
    band average of I, which differs from I at the view by O(band^2) (2 degrees: ~1e-4 of a
    smooth I). No point estimator, so no exit-point solve: the check of a renderer's own."""
    ss, sa = _channels(sigma_s, sigma_a)
    _check_g_eta(g, eta)
    if not radius > 0:
        raise ValueError("radius must be > 0")
    light = _unit(light_dir, "light_dir")
    view = _unit(view_dir, "view_dir")
    theta = math.acos(max(-1.0, min(1.0, float(view @ light))))
    band = math.radians(band_deg)
    if not (band > 0 and theta - band > 0 and theta + band < math.pi):
        raise ValueError("sphere_intensity: the band must fit between 0 and 180 degrees from the light")
    ring = 4.0 * math.pi * math.sin(theta) * math.sin(band)
    lo, hi = math.cos(theta + band), math.cos(theta - band)
    R = float(radius)
    e1, e2 = image_axes(light)
    geom = _Sphere(R)
    seqs = np.random.SeedSequence(seed).spawn(ss.size)
    nch = ss.size
    flux = np.zeros(nch)
    flux_e = np.zeros(nch)
    entering = np.zeros(nch)
    npaths = np.zeros(nch, dtype=np.int64)
    secs = np.zeros(nch)
    for c in range(nch):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seqs[c])
        stats = _Stats((2,))  # tallied weight, entering weight (per photon over the disc)
        done = 0
        while done < n_paths:
            m = min(batch, n_paths - done)
            tally = _Collector()

            def on_exit(pid, x, y, z, ux, uy, uz, w, order):
                nx, ny, nz = x / R, y / R, z / R
                ci = ux * nx + uy * ny + uz * nz                      # > 0: leaving
                st2 = eta * eta * np.maximum(0.0, 1.0 - ci * ci)      # sin^2 outside (Snell)
                co = np.sqrt(np.maximum(0.0, 1.0 - st2))
                ox, oy, oz = eta * ux + (co - eta * ci) * nx, eta * uy + (co - eta * ci) * ny, eta * uz + (co - eta * ci) * nz
                cl = (ox * light[0] + oy * light[1] + oz * light[2]) / np.sqrt(ox * ox + oy * oy + oz * oz)
                sel = (order > 0) & (cl >= lo) & (cl <= hi)
                if sel.any():
                    tally.add(pid[sel], w[sel])

            px, py, pz, h = _disc_entry(rng, m, R, light, e1, e2)
            # refraction in: n the outward normal, cos_i = h / R
            nx, ny, nz = px / R, py / R, pz / R
            ci = h / R
            w0 = 1.0 - fresnel(ci, eta) if eta != 1.0 else np.ones(m)
            sin2_t = np.maximum(0.0, 1.0 - ci * ci) / (eta * eta)
            ct = np.sqrt(1.0 - sin2_t)
            k = ci / eta - ct
            dx, dy, dz = -light[0] / eta + k * nx, -light[1] / eta + k * ny, -light[2] / eta + k * nz
            norm = np.sqrt(dx * dx + dy * dy + dz * dz)
            start = (px, py, pz, dx / norm, dy / norm, dz / norm, w0)
            _walk(rng, start, ss[c], sa[c], g, eta, geom, 1, on_exit=on_exit)
            stats.add(np.stack([tally.totals(m), w0], axis=1) * (math.pi * R * R))
            done += m
        mean, err = stats.mean, stats.err
        flux[c], flux_e[c] = math.pi * mean[0] / ring, math.pi * err[0] / ring
        entering[c] = mean[1]
        npaths[c] = done
        secs[c] = time.perf_counter() - t0
    return SphereIntensityResult(flux=flux, flux_err=flux_e, band_deg=float(band_deg), entering=entering,
                                 n_paths=npaths, seconds=secs)


# ---------------------------------------------------------------------------------------------
# Command line


# ---------------------------------------------------------------------------------------------
# Scene 5: a spot (the radial profile as a render sees it)


def circle_overlap(R, a: float, d):
    """Area of the intersection of a circle of radius ``R`` at the origin with one of radius
    ``a`` whose centre is ``d`` away (numpy broadcasting over R and d; R = 0 gives 0)."""
    R, d = np.broadcast_arrays(np.asarray(R, dtype=float), np.asarray(d, dtype=float))
    out = np.zeros(R.shape)
    small = np.minimum(R, a)
    inside = d <= np.abs(R - a)
    out[inside] = math.pi * small[inside] ** 2
    part = ~inside & (d < R + a)
    if part.any():
        Rp, dp = R[part], d[part]
        c1 = np.clip((dp * dp + Rp * Rp - a * a) / (2.0 * dp * Rp), -1.0, 1.0)
        c2 = np.clip((dp * dp + a * a - Rp * Rp) / (2.0 * dp * a), -1.0, 1.0)
        k = (-dp + Rp + a) * (dp + Rp - a) * (dp - Rp + a) * (dp + Rp + a)
        out[part] = Rp * Rp * np.arccos(c1) + a * a * np.arccos(c2) - 0.5 * np.sqrt(np.maximum(k, 0.0))
    return out


@dataclass
class SpotResult:
    """pi L / E averaged over annuli about a lit disc, per channel (rows) and annulus (columns)."""

    r_edges: np.ndarray          # (bins + 1,) mm
    radiance: np.ndarray         # (channels, bins): the annulus's mean of pi L / E
    radiance_err: np.ndarray
    plateau: np.ndarray          # (channels,) pi L / E under uniform light (the whole surface lit)
    plateau_err: np.ndarray
    spot_radius: float
    n_paths: np.ndarray
    collisions: np.ndarray
    seconds: np.ndarray


def spot(sigma_s, sigma_a, g: float, eta: float, spot_radius: float, r_edges, *, n_paths: int = 100_000,
         seed: int = 1, batch: int = 20_000) -> SpotResult:
    """The half-space z < 0 lit straight from above (E = 1) only inside the disc of radius
    ``spot_radius`` (mm) about the origin (a black plate with a round hole just above: it blocks
    light, not the view), seen straight down: pi L / E averaged over each annulus
    r_edges[k] <= |P| < r_edges[k + 1]. Outside the disc this is the radial profile of the
    medium's multiple scattering as a render shows it (single scattering under normal light and
    view leaves where the light entered), convolved with the disc.

    Estimator (exact, as ``shadow_edge``): each photon enters at the origin and each collision's
    point estimate toward the view lands at the lateral offset Delta; a point P sees it when its
    own entry P - Delta is in the disc, so over the annulus the contribution counts
    area(annulus & disc moved by Delta) / area(annulus) (``circle_overlap``), no bins in Delta."""
    ss, sa = _channels(sigma_s, sigma_a)
    _check_g_eta(g, eta)
    if not spot_radius > 0:
        raise ValueError("spot_radius must be > 0")
    edges = np.asarray(r_edges, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or not (np.diff(edges) > 0).all() or edges[0] < 0:
        raise ValueError("r_edges: increasing radii >= 0, at least two")
    nb = edges.size - 1
    ann = math.pi * (edges[1:] ** 2 - edges[:-1] ** 2)
    light = np.array([0.0, 0.0, 1.0])
    (dx, dy, dz), cos_i, t_in = _plane_entry(light, eta)
    scale = cos_i * t_in
    pv = _plane_view(light, eta)
    geom = _Slab(math.inf)
    seqs = np.random.SeedSequence(seed).spawn(ss.size)
    nch = ss.size
    rad, rad_e = np.zeros((nch, nb)), np.zeros((nch, nb))
    plat, plat_e = np.zeros(nch), np.zeros(nch)
    npaths = np.zeros(nch, dtype=np.int64)
    ncoll = np.zeros(nch, dtype=np.int64)
    secs = np.zeros(nch)
    for c in range(nch):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seqs[c])
        st = ss[c] + sa[c]
        terms, _ = _plane_terms(pv, st, math.inf)
        prof = _Stats((nb,))
        total = _Stats()
        coll = [0]

        def one_batch(m):
            acc = _Collector()
            tot = _Collector()

            def on_collision(pid, x, y, z, ux, uy, uz, w):
                for val, v in _contrib(pv, terms, st, math.inf, g, z, ux, uy, uz, w):
                    d = np.hypot(x + pv.wx * v / pv.mu, y + pv.wy * v / pv.mu)
                    tot.add(pid, val)
                    near = d < edges[-1] + spot_radius
                    if not near.any():
                        continue
                    dn, vn, pn = d[near], val[near], pid[near]
                    cover = circle_overlap(edges[None, :], spot_radius, dn[:, None])  # (n, nb + 1)
                    share = (cover[:, 1:] - cover[:, :-1]) / ann[None, :]
                    acc.add((pn[:, None] * nb + np.arange(nb)[None, :]).ravel(), (vn[:, None] * share).ravel())

            start = (np.zeros(m), np.zeros(m), np.zeros(m), np.full(m, dx), np.full(m, dy), np.full(m, dz),
                     np.ones(m))
            wk = _walk(rng, start, ss[c], sa[c], g, eta, geom, 2, on_collision)
            coll[0] += wk.collisions
            prof.add(acc.totals(m * nb).reshape(m, nb) * scale)
            total.add(tot.totals(m) * scale)

        npaths[c] = _run_batches(n_paths, batch, None, n_paths, one_batch, lambda: (0.0, 0.0))
        rad[c], rad_e[c] = prof.mean, prof.err
        plat[c], plat_e[c] = total.mean, total.err
        ncoll[c] = coll[0]
        secs[c] = time.perf_counter() - t0
    return SpotResult(r_edges=edges, radiance=rad, radiance_err=rad_e, plateau=plat, plateau_err=plat_e,
                      spot_radius=float(spot_radius), n_paths=npaths, collisions=ncoll, seconds=secs)


def _dir_from_angle(deg: float, sign: float = 1.0) -> np.ndarray:
    """Unit vector in the xz plane at ``deg`` from +z (toward +x for deg > 0); sign flips z."""
    t = math.radians(deg)
    return np.array([math.sin(t), 0.0, sign * math.cos(t)])


def _fmt(v, e) -> str:
    return "  ".join(f"{a:.5f}+-{b:.5f}" for a, b in zip(np.atleast_1d(v), np.atleast_1d(e)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reference.volume_ref",
                                 description="Exact Monte Carlo volumetric transport (homogeneous medium, HG phase, "
                                 "Fresnel faces) in three scenes; pi L / E per colour channel with standard "
                                 "errors. Without --sigma-s: Jensen's skin 1 at g = 0 (eta 1.3; the sphere: eta 1).")
    sub = ap.add_subparsers(dest="scene")

    def medium(p):
        p.add_argument("--sigma-s", type=lambda s: [float(v) for v in s.split(",")], default=None,
                       help="scattering coefficient(s), 1/mm, comma separated per channel")
        p.add_argument("--sigma-a", type=lambda s: [float(v) for v in s.split(",")], default=None)
        p.add_argument("--g", type=float, default=None)
        p.add_argument("--eta", type=float, default=None)
        p.add_argument("--skin1", action="store_true", help="Jensen's skin 1 with g = 0, eta = 1.3 (defaults)")
        p.add_argument("--light", type=float, default=0.0, help="light angle from the normal, degrees (+: toward +x)")
        p.add_argument("--paths", type=int, default=100_000)
        p.add_argument("--target", type=float, default=None, help="run until this relative standard error")
        p.add_argument("--seed", type=int, default=1)

    pe = sub.add_parser("edge", help="shadow edge profile (half-space lit at x > 0)")
    medium(pe)
    pe.add_argument("--xmin", type=float, default=-5.0)
    pe.add_argument("--xmax", type=float, default=5.0)
    pe.add_argument("--nx", type=int, default=41)
    pe.add_argument("--thickness", type=float, default=math.inf)
    ps = sub.add_parser("sheet", help="uniformly lit slab")
    medium(ps)
    ps.add_argument("--thickness", type=float, default=math.inf)
    ps.add_argument("--view", type=float, default=0.0, help="view angle from the top normal, degrees; "
                    "> 90 sees the bottom face")
    pp = sub.add_parser("sphere", help="sphere image (eta = 1)")
    medium(pp)
    pp.add_argument("--radius", type=float, default=5.0)
    pp.add_argument("--view", type=float, default=0.0)
    pp.add_argument("--npix", type=int, default=16)
    args = ap.parse_args(argv)
    if args.scene is None:
        ap.print_help()
        return 2
    base = dict(SKIN1) if (args.skin1 or args.sigma_s is None) else {"g": 0.0, "eta": 1.0}
    ss = args.sigma_s or base["sigma_s"]
    sa = args.sigma_a or base["sigma_a"]
    g = base["g"] if args.g is None else args.g
    eta = (1.0 if args.scene == "sphere" else base["eta"]) if args.eta is None else args.eta
    light = _dir_from_angle(args.light)
    print(f"sigma_s = {ss} /mm, sigma_a = {sa} /mm, g = {g}, eta = {eta}, light {args.light} deg, seed {args.seed}")
    if args.scene == "edge":
        xs = np.linspace(args.xmin, args.xmax, args.nx)
        r = shadow_edge(ss, sa, g, eta, light, xs, thickness=args.thickness, n_paths=args.paths, seed=args.seed,
                        target_rel_err=args.target)
        print("x [mm]  pi L / E per channel (+- 1 s.e.)")
        for k, x in enumerate(xs):
            print(f"{x:7.3f}  {_fmt(r.radiance[:, k], r.radiance_err[:, k])}")
        print(f"plateau {_fmt(r.plateau, r.plateau_err)}; specular {r.specular:.5f}")
        print(f"paths {r.n_paths.tolist()}, collisions {r.collisions.tolist()}, seconds {r.seconds.round(2).tolist()}")
    elif args.scene == "sheet":
        view = _dir_from_angle(args.view) if args.view <= 90 else _dir_from_angle(180.0 - args.view, -1.0)
        r = sheet(ss, sa, g, eta, args.thickness, light, view, n_paths=args.paths, seed=args.seed,
                  target_rel_err=args.target)
        print(f"pi L / E {_fmt(r.radiance, r.radiance_err)}")
        print(f"per entering power: R {_fmt(r.reflectance, r.reflectance_err)}  T {_fmt(r.transmittance, r.transmittance_err)}")
        print(f"specular {r.specular:.5f}; paths {r.n_paths.tolist()}, seconds {r.seconds.round(2).tolist()}")
    else:
        r = sphere(ss, sa, g, eta, args.radius, light, _dir_from_angle(args.view), args.npix, n_paths=args.paths,
                   seed=args.seed)
        with np.printoptions(precision=4, suppress=True, linewidth=200):
            for c in range(r.image.shape[0]):
                print(f"channel {c}: pi L / E (pixel averages)\n{r.image[c]}")
        print(f"flux {_fmt(r.flux, r.flux_err)} mm^2; escaped {_fmt(r.escaped, r.escaped_err)} "
              f"vs 4 pi estimate {_fmt(r.escaped_est, r.escaped_est_err)}; seconds {r.seconds.round(2).tolist()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
