"""Monte Carlo photon migration in a homogeneous layer (semi-infinite or a slab): the independent
reference for the dipole (shading/include/shading/subsurface/dipole.h, harness/reference/dipole_ref.py) and for
the exact profiles of the library (shading/include/shading/subsurface/ss_profile.h), sharing no code with either.

Model (the assumptions of both, and nothing of their mathematics):
  * medium 0 <= z <= thickness (z is depth; thickness = inf: semi-infinite), flat faces, the same
    relative index eta = n_medium / n_outside at both;
  * a pencil beam enters at the origin; its outside direction makes cos_incidence with the normal
    (in the xz plane) and is refracted by Snell's law. The incident Fresnel reflection is NOT part
    of the tallies: results are per unit power ENTERING the medium, which is how the dipole's Rd and
    Jensen's S_d = (1/pi) Ft Rd Ft are normalised (Ft(wi) is applied outside Rd). The specular part
    ((eta-1)/(eta+1))^2 (normal incidence) is reported separately in MCResult.specular;
  * exponential free paths with sigma_t = sigma_s + sigma_a, Henyey-Greenstein scattering at any g;
  * absorption by weight (implicit capture: w *= albedo at each interaction, one albedo per run) and
    Russian roulette below `roulette_weight` (survival probability `roulette_survival`), which
    keeps the estimator unbiased and bounds path lengths for albedo up to 0.9999;
  * at a face, exact unpolarised Fresnel from inside (relative index 1/eta, total internal
    reflection beyond the critical angle). The photon is split deterministically: the
    transmitted fraction of its weight is tallied as exitance at the crossing point, the
    reflected fraction continues along the mirrored direction (no extra random numbers);
  * tallies, per unit entering power: reflectance through the top face and transmittance through
    the bottom face, each split into unscattered (ballistic), single scattering (exactly one
    interaction) and multiple scattering (two or more), and radial profiles per unit area in
    annular bins. Standard errors come from per-photon sums (each photon is one independent sample);
  * radiance (optional `views`): for each outside direction leaving the top face, the radiance of
    the surface under UNIFORM illumination (by translation invariance the pencil beam's response
    integrated over the surface) per unit entering flux density, by the next-event (point)
    estimator: every interaction of weight w at depth z adds w p(u . w') exp(-sigma_t z/mu') / mu'
    toward the inside direction w' that refracts into the view (in a slab, plus the far face's
    reflections of that direction: F p(u . w'_mirrored) exp(-sigma_t (2d - z)/mu'), all over
    1 - F^2 exp(-2 sigma_t d/mu')), times Ft(mu') / eta^2 on the way out. Exact
    in expectation and of low variance, at exact directions (no angular bins). pi L / E_entering is
    then `radiance_*`; for eta = 1, isotropic scattering and normal incidence the total is
    Chandrasekhar's omega H(mu) H(1) / (4 (mu + 1)) (dipole_ref.plane_radiance_isotropic).

Vectorised over photons with numpy, seeded with numpy's PCG64 (`numpy.random.default_rng`), so a
given (parameters, seed, n_photons) gives bit-identical results on the same numpy version; the
radiance estimator and the slab draw no extra random numbers (a semi-infinite run without views is
the same sequence as before they existed).

Command line:  python -m harness.reference.mc_subsurface --table   (dipole vs MC over albedo and eta)
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from harness.core.progress import bar as progress_bar
from harness.reference import dipole_ref

__all__ = ["MCResult", "simulate", "default_r_edges", "view_directions", "table", "main"]


@dataclass
class MCResult:
    n_photons: int
    sigma_s: float
    sigma_a: float
    g: float
    eta: float
    total: float            # Rd: exiting power / entering power (top face, all orders >= 1)
    total_err: float        # one standard error
    single: float           # part of `total` after exactly one scattering event
    single_err: float
    multiple: float         # part after two or more events
    multiple_err: float
    specular: float         # normal-incidence Fresnel reflection of the beam (not in `total`)
    r_edges: np.ndarray     # radial bin edges (length units of 1/sigma)
    rd_r: np.ndarray        # Rd per unit area in each annulus, all orders
    rd_r_err: np.ndarray
    rd_r_multiple: np.ndarray
    interactions: int       # photon-interaction events simulated (cost measure)
    seconds: float
    extra: dict = field(default_factory=dict)
    # Slabs (thickness < inf) and oblique incidence; zeros for a semi-infinite medium.
    thickness: float = math.inf
    cos_incidence: float = 1.0
    r_ballistic: float = 0.0          # left through the top without scattering (bounced off the bottom)
    t_ballistic: float = 0.0          # through the bottom without scattering
    t_single: float = 0.0
    t_single_err: float = 0.0
    t_multiple: float = 0.0
    t_multiple_err: float = 0.0
    rd_r_multiple_err: np.ndarray | None = None
    td_r: np.ndarray | None = None    # transmitted exitance per unit area (bottom face), all orders >= 1
    td_r_err: np.ndarray | None = None
    td_r_multiple: np.ndarray | None = None
    td_r_multiple_err: np.ndarray | None = None
    # Radiance at `views` (outside unit vectors, z > 0), pi L / E_entering, uniform illumination.
    views: np.ndarray | None = None
    radiance_single: np.ndarray | None = None
    radiance_single_err: np.ndarray | None = None
    radiance_multiple: np.ndarray | None = None
    radiance_multiple_err: np.ndarray | None = None

    @property
    def t_total(self) -> float:
        """Diffuse transmittance (orders >= 1)."""
        return self.t_single + self.t_multiple


def default_r_edges(sigma_t_prime: float) -> np.ndarray:
    """Log-spaced bins from 0.01 to 100 reduced mean free paths (plus the disc r < 0.01)."""
    mfp = 1.0 / sigma_t_prime
    return np.concatenate([[0.0], np.geomspace(0.01, 100.0, 61)]) * mfp


def view_directions(cos_o, phi_deg=0.0) -> np.ndarray:
    """Outside view directions (n, 3) from cosines with the normal and azimuths (degrees, 0 = the
    plane of incidence on the side the beam travels to)."""
    c = np.atleast_1d(np.asarray(cos_o, dtype=float))
    p = np.radians(np.broadcast_to(np.asarray(phi_deg, dtype=float), c.shape))
    s = np.sqrt(np.maximum(0.0, 1.0 - c * c))
    return np.stack([s * np.cos(p), s * np.sin(p), c], axis=-1)


def _fresnel_out(cos_i: np.ndarray, inv_eta: float) -> np.ndarray:
    """Reflectance for light inside hitting the boundary (relative index 1/eta)."""
    return dipole_ref.fresnel_dielectric(cos_i, inv_eta)


def _hg(cos_t: np.ndarray, g: float) -> np.ndarray:
    """Henyey-Greenstein density per steradian (written out here, not shared)."""
    return (1.0 - g * g) / (4.0 * math.pi * np.power(1.0 + g * g - 2.0 * g * cos_t, 1.5))


def _scatter(ux, uy, uz, g, rng):
    """New directions after Henyey-Greenstein scattering (deflection about the old direction)."""
    n = ux.size
    xi = rng.random(n)
    if g == 0.0:
        ct = 2.0 * xi - 1.0
    else:
        t = (1.0 - g * g) / (1.0 - g + 2.0 * g * xi)
        ct = np.clip((1.0 + g * g - t * t) / (2.0 * g), -1.0, 1.0)
    st = np.sqrt(np.maximum(0.0, 1.0 - ct * ct))
    phi = 2.0 * math.pi * rng.random(n)
    cp, sp = np.cos(phi), np.sin(phi)
    # Rotate (st cp, st sp, ct) from the frame of u to world; near the poles use the fixed frame.
    pole = np.abs(uz) > 0.99999
    den = np.sqrt(np.maximum(1e-300, 1.0 - uz * uz))
    nx = st * (ux * uz * cp - uy * sp) / den + ux * ct
    ny = st * (uy * uz * cp + ux * sp) / den + uy * ct
    nz = -st * cp * den + uz * ct
    nx = np.where(pole, st * cp, nx)
    ny = np.where(pole, st * sp, ny)
    nz = np.where(pole, np.sign(uz) * ct, nz)
    inv = 1.0 / np.sqrt(nx * nx + ny * ny + nz * nz)  # keep unit length over long paths
    return nx * inv, ny * inv, nz * inv


#: Outside cosine bounding the cone of the transmitted-radiance tally (``extra["t_radiance_normal"]``).
T_CONE_COS = 0.95


def simulate(sigma_s: float, sigma_a: float, g: float = 0.0, eta: float = 1.0,
             n_photons: int = 100_000, seed: int = 1, r_edges: np.ndarray | None = None,
             roulette_weight: float = 1e-3, roulette_survival: float = 0.1,
             max_iterations: int = 10_000_000, thickness: float = math.inf,
             cos_incidence: float = 1.0, views: np.ndarray | None = None, progress: bool = False) -> MCResult:
    """Simulate `n_photons` photons entering at the origin; see module doc. `views`: outside
    directions (n, 3) for the radiance estimator (:func:`view_directions`).

    ``progress``: a bar of the photons finished (absorbed or escaped), with the time left,
    on stderr (:mod:`harness.core.progress`)."""
    if not (sigma_s >= 0 and sigma_a >= 0 and sigma_s + sigma_a > 0):
        raise ValueError(f"need sigma_s, sigma_a >= 0 and sigma_t > 0, got {sigma_s}, {sigma_a}")
    if not (-1.0 < g < 1.0):
        raise ValueError(f"g = {g}: need -1 < g < 1")
    if not eta > 0:
        raise ValueError(f"eta = {eta}: need > 0")
    if not thickness > 0:
        raise ValueError(f"thickness = {thickness}: need > 0 (inf: semi-infinite)")
    if not (0.0 < cos_incidence <= 1.0):
        raise ValueError(f"cos_incidence = {cos_incidence}: need (0, 1]")
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    sigma_t = sigma_s + sigma_a
    albedo = sigma_s / sigma_t
    if r_edges is None:
        r_edges = default_r_edges(sigma_s * (1.0 - g) + sigma_a)
    r_edges = np.asarray(r_edges, dtype=float)
    nb = r_edges.size - 1
    inv_eta = 1.0 / eta
    slab = math.isfinite(thickness)
    d = float(thickness)

    # Radiance: the inside directions (MC frame, z = depth, moving up: uz < 0) that refract into
    # the views, their inside cosines and the exit factor Ft / eta^2.
    nv = 0
    if views is not None:
        views = np.atleast_2d(np.asarray(views, dtype=float))
        if views.shape[1] != 3 or not (views[:, 2] > 0).all():
            raise ValueError("views: need (n, 3) outside directions with z > 0")
        views = views / np.linalg.norm(views, axis=1)[:, None]
        nv = views.shape[0]
        mu_in = dipole_ref.refracted_cos(views[:, 2], eta)  # outside -> inside: relative index eta
        win = np.stack([views[:, 0] / eta, views[:, 1] / eta, -mu_in], axis=1)
        exit_w = (1.0 - dipole_ref.fresnel_dielectric(views[:, 2], eta)) / eta**2
        if slab:
            f_back = _fresnel_out(mu_in, inv_eta)  # inside reflection at either face
            round_trip = 1.0 - f_back**2 * np.exp(-2.0 * sigma_t * d / mu_in)

    n = int(n_photons)
    ids = np.arange(n)
    x = np.zeros(n)
    y = np.zeros(n)
    z = np.zeros(n)
    sin_t = math.sqrt(max(0.0, 1.0 - cos_incidence * cos_incidence)) / eta
    ux = np.full(n, sin_t)
    uy = np.zeros(n)
    uz = np.full(n, math.sqrt(max(0.0, 1.0 - sin_t * sin_t)))
    w = np.ones(n)
    order = np.zeros(n, dtype=np.int64)  # interactions so far

    per = {k: np.zeros(n) for k in ("rs", "rm", "ts", "tm")}  # per-photon exiting weight
    r_ball = 0.0
    t_ball = 0.0
    bins = {k: np.zeros(nb) for k in ("r", "r2", "rm", "rm2", "t", "t2", "tm", "tm2")}
    # Slabs: weight leaving the bottom face within 18.2 degrees of its normal (outside cosine >=
    # T_CONE_COS), after >= 1 interaction: pi L_t(near normal) / E = that / (n (1 - T_CONE_COS^2)).
    t_cone = 0.0
    rad_s = np.zeros((n, nv))
    rad_m = np.zeros((n, nv))
    interactions = 0

    def tally(face, hx, hy, wo_, o, hid):
        nonlocal r_ball, t_ball, t_cone
        ball = o == 0
        if ball.any():
            if face == "r":
                r_ball += float(wo_[ball].sum())
            else:
                t_ball += float(wo_[ball].sum())
        r = np.hypot(hx, hy)
        b = np.searchsorted(r_edges, r, side="right") - 1
        ok = (b >= 0) & (b < nb) & ~ball
        bins[face] += np.bincount(b[ok], weights=wo_[ok], minlength=nb)
        bins[face + "2"] += np.bincount(b[ok], weights=wo_[ok] ** 2, minlength=nb)
        mo = ok & (o >= 2)
        bins[face + "m"] += np.bincount(b[mo], weights=wo_[mo], minlength=nb)
        bins[face + "m2"] += np.bincount(b[mo], weights=wo_[mo] ** 2, minlength=nb)
        one = o == 1
        many = o >= 2
        per[face + "s"][hid[one]] += wo_[one]    # ids are unique within one step
        per[face + "m"][hid[many]] += wo_[many]

    it = 0
    bar = progress_bar(n, "Monte Carlo", unit="photon", enabled=progress)
    while ids.size and it < max_iterations:
        it += 1
        bar.update(n - ids.size - bar.n)
        s = -np.log1p(-rng.random(ids.size)) / sigma_t  # free path; 1 - U in (0, 1]
        up = uz < 0.0
        with np.errstate(divide="ignore"):
            d_b = np.where(up, z / np.where(up, -uz, 1.0), np.inf)  # distance to the top face
            if slab:
                down = uz > 0.0
                d_b = np.where(down, (d - z) / np.where(down, uz, 1.0), d_b)
        hit = s >= d_b

        # Photons reaching a face: move there, split by Fresnel.
        if hit.any():
            hx = x[hit] + ux[hit] * d_b[hit]
            hy = y[hit] + uy[hit] * d_b[hit]
            top = uz[hit] < 0.0
            fr = _fresnel_out(np.abs(uz[hit]), inv_eta)
            w_out = w[hit] * (1.0 - fr)
            o = order[hit]
            hid = ids[hit]
            out = w_out > 0.0
            for face, sel in (("r", out & top), ("t", out & ~top)):
                if sel.any():
                    tally(face, hx[sel], hy[sel], w_out[sel], o[sel], hid[sel])
            tsel = out & ~top & (o >= 1)
            if tsel.any():
                mu_out = np.sqrt(np.maximum(0.0, 1.0 - eta * eta * (1.0 - uz[hit][tsel] ** 2)))
                t_cone += float(w_out[tsel][mu_out >= T_CONE_COS].sum())
            x[hit] = hx
            y[hit] = hy
            z[hit] = np.where(top, 0.0, d)
            uz[hit] = -uz[hit]
            w[hit] = w[hit] * fr

        # The others interact at the end of their free path.
        m = ~hit
        if m.any():
            sm = s[m]
            x[m] += ux[m] * sm
            y[m] += uy[m] * sm
            z[m] += uz[m] * sm
            w[m] *= albedo
            order[m] += 1
            interactions += int(m.sum())
            if nv:
                # Next-event estimate of the radiance toward each view: scattered into the inside
                # direction that refracts into it, attenuated by exp(-sigma_t z / mu') on the way
                # up. In a slab the view's ray, followed back from the eye, also reflects off the
                # far face (Fresnel F at mu', the same at both faces) and returns: the source
                # scattering DOWN into the mirrored direction counts with F exp(-sigma_t (2d - z) /
                # mu'), and every further round trip multiplies both by F^2 exp(-2 sigma_t d / mu').
                zm = z[m][:, None]
                ax, ay, az = ux[m][:, None], uy[m][:, None], uz[m][:, None]
                cosp = ax * win[None, :, 0] + ay * win[None, :, 1] + az * win[None, :, 2]
                c = _hg(np.clip(cosp, -1.0, 1.0), g) * np.exp(-sigma_t * zm / mu_in[None, :])
                if slab:
                    cosd = ax * win[None, :, 0] + ay * win[None, :, 1] - az * win[None, :, 2]
                    c = c + f_back[None, :] * _hg(np.clip(cosd, -1.0, 1.0), g) * \
                        np.exp(-sigma_t * (2.0 * d - zm) / mu_in[None, :])
                    c = c / round_trip[None, :]
                c = w[m][:, None] * c / mu_in[None, :]
                c = c * exit_w[None, :] * math.pi
                first = order[m] == 1
                mid = ids[m]
                rad_s[mid[first]] += c[first]          # ids are unique within one step
                rad_m[mid[~first]] += c[~first]
            ux[m], uy[m], uz[m] = _scatter(ux[m], uy[m], uz[m], g, rng)

        # Russian roulette on light photons; drop dead ones.
        low = (w < roulette_weight) & (w > 0.0)
        if low.any():
            survive = rng.random(int(low.sum())) < roulette_survival
            wl = w[low]
            w[low] = np.where(survive, wl / roulette_survival, 0.0)
        alive = w > 0.0
        if not alive.all():
            ids, x, y, z, ux, uy, uz, w, order = (
                a[alive] for a in (ids, x, y, z, ux, uy, uz, w, order))

    bar.update(n - ids.size - bar.n)
    bar.close()
    sq = math.sqrt(n)
    area = math.pi * (r_edges[1:] ** 2 - r_edges[:-1] ** 2)

    def mean_err(v):
        return float(v.mean()), float(v.std(ddof=1) / sq) if n > 1 else 0.0

    def bin_err(total, sqsum):
        # Exits treated as independent: a slight underestimate where one photon exits twice.
        return np.sqrt(np.maximum(0.0, sqsum / n - (total / n) ** 2 / np.maximum(1, n)) / n) / area

    rs, rs_e = mean_err(per["rs"])
    rm, rm_e = mean_err(per["rm"])
    rt, rt_e = mean_err(per["rs"] + per["rm"])
    ts, ts_e = mean_err(per["ts"])
    tm, tm_e = mean_err(per["tm"])
    res = MCResult(
        n_photons=n, sigma_s=sigma_s, sigma_a=sigma_a, g=g, eta=eta,
        total=rt, total_err=rt_e, single=rs, single_err=rs_e, multiple=rm, multiple_err=rm_e,
        specular=float(((eta - 1.0) / (eta + 1.0)) ** 2),
        r_edges=r_edges, rd_r=bins["r"] / (n * area), rd_r_err=bin_err(bins["r"], bins["r2"]),
        rd_r_multiple=bins["rm"] / (n * area),
        interactions=interactions, seconds=0.0,
        extra={"iterations": it, "unfinished": int(ids.size),
               # pi L / E_entering of the light transmitted through a slab, averaged over the
               # outside cone within 18.2 degrees of the normal, all orders >= 1 (0: semi-infinite)
               "t_radiance_normal": t_cone / (n * (1.0 - T_CONE_COS ** 2))},
        thickness=float(thickness), cos_incidence=float(cos_incidence),
        r_ballistic=r_ball / n, t_ballistic=t_ball / n, t_single=ts, t_single_err=ts_e,
        t_multiple=tm, t_multiple_err=tm_e,
        rd_r_multiple_err=bin_err(bins["rm"], bins["rm2"]),
        td_r=bins["t"] / (n * area), td_r_err=bin_err(bins["t"], bins["t2"]),
        td_r_multiple=bins["tm"] / (n * area), td_r_multiple_err=bin_err(bins["tm"], bins["tm2"]),
    )
    if nv:
        res.views = views
        res.radiance_single = rad_s.mean(axis=0)
        res.radiance_single_err = rad_s.std(axis=0, ddof=1) / sq
        res.radiance_multiple = rad_m.mean(axis=0)
        res.radiance_multiple_err = rad_m.std(axis=0, ddof=1) / sq
    res.seconds = time.perf_counter() - t0
    return res


def write_profile_csv(res: MCResult, path, units: str = "mm") -> None:
    """The radial profile of ``res`` as a CSV file that ``brdf-scatter-fit`` reads: a comment
    saying what was simulated, a header with units, then one annulus per line
    (``r_inner, r_outer, Rd, Rd_err``). Lengths are in ``units`` (the unit the coefficients
    were given in: sigma in 1/``units``), Rd per unit entering power and area."""
    lines = [f"# Monte Carlo radial profile (harness.reference.mc_subsurface): sigma_s = {res.sigma_s:g} 1/{units}, "
             f"sigma_a = {res.sigma_a:g} 1/{units}, g = {res.g:g}, eta = {res.eta:g}, {res.n_photons} photons",
             "# Rd: exitance per unit entering power and area, mean over each annulus; Rd_err: one standard error",
             f"r_inner [{units}], r_outer [{units}], Rd [1/{units}^2], Rd_err [1/{units}^2]"]
    for lo, hi, v, e in zip(res.r_edges[:-1], res.r_edges[1:], res.rd_r, res.rd_r_err):
        lines.append(f"{lo:.9g}, {hi:.9g}, {v:.9g}, {e:.9g}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


# ---------------------------------------------------------------------------------------------
# Dipole vs MC table

TABLE_R = (0.5, 1.0, 2.0, 4.0, 8.0)  # radii in reduced mean free paths for the Rd(r) columns


def _bin_mean(res: MCResult, r: float):
    """MC annulus mean around r (the bin containing r) and its edges."""
    b = int(np.searchsorted(res.r_edges, r, side="right") - 1)
    return res.rd_r[b], res.rd_r_err[b], res.r_edges[b], res.r_edges[b + 1]


def table(albedos=(0.5, 0.8, 0.9, 0.95, 0.99, 0.999), etas=(1.0, 1.3, 1.5), g: float = 0.0,
          n_photons: int = 100_000, seed: int = 1, out=sys.stdout, progress: bool = False) -> list[dict]:
    """Print dipole vs MC totals and radial profiles; sigma_t' = 1 (lengths in reduced mfp).
    ``progress``: a bar of the rows (media) and one of each row's photons on stderr."""
    rows = []
    hdr = ("alpha'  eta  | Rd dipole  Rd MC (+-1se)      MC single MC multi | dip/MC-1 "
           "| exact(eta=1) | Rd(r) dipole/MC at r = " + ", ".join(f"{r:g}" for r in TABLE_R)
           + " mfp' | s")
    print(hdr, file=out)
    print("-" * len(hdr), file=out)
    t_all = time.perf_counter()
    rows_bar = progress_bar(len(etas) * len(albedos), "media", unit="medium", enabled=progress)
    for eta in etas:
        for a in albedos:
            ssp, sa = a, 1.0 - a           # sigma_t' = 1
            ss = ssp / (1.0 - g)
            res = simulate(ss, sa, g=g, eta=eta, n_photons=n_photons, seed=seed, progress=progress)
            rows_bar.update(1)
            dip = dipole_ref.Dipole(ssp, sa, eta)
            rd = dip.rd_total()
            exact = dipole_ref.plane_albedo_isotropic(a) if (eta == 1.0 and g == 0.0) else float("nan")
            ratios = []
            for r in TABLE_R:
                mc, err, r1, r2 = _bin_mean(res, r)
                ratios.append(float(dip.rd_annulus_mean(r1, r2)) / mc if mc > 0 else float("nan"))
            row = dict(alpha_prime=a, eta=eta, g=g, rd_dipole=rd, rd_mc=res.total, rd_mc_err=res.total_err,
                       single=res.single, multiple=res.multiple, exact=exact, ratios=ratios,
                       seconds=res.seconds, interactions=res.interactions)
            rows.append(row)
            ex = f"{exact:12.4f}" if exact == exact else " " * 12
            print(f"{a:6.3f} {eta:5.2f} | {rd:9.4f}  {res.total:.4f} (+-{res.total_err:.4f})  "
                  f"{res.single:9.4f} {res.multiple:8.4f} | {rd / res.total - 1.0:+8.3f} | {ex} | "
                  + "  ".join(f"{q:5.2f}" for q in ratios) + f" | {res.seconds:5.1f}", file=out)
    rows_bar.close()
    print(f"total {time.perf_counter() - t_all:.1f} s, {n_photons} photons per row, seed {seed}, "
          f"g = {g}, numpy {np.__version__}", file=out)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reference.mc_subsurface", description=__doc__.splitlines()[0])
    ap.add_argument("--table", action="store_true", help="print dipole vs Monte Carlo table")
    ap.add_argument("--photons", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--g", type=float, default=0.0, help="HG g of the MC medium (dipole uses sigma_s')")
    ap.add_argument("--albedos", type=lambda s: [float(v) for v in s.split(",")],
                    default=[0.5, 0.8, 0.9, 0.95, 0.99, 0.999])
    ap.add_argument("--etas", type=lambda s: [float(v) for v in s.split(",")], default=[1.0, 1.3, 1.5])
    ap.add_argument("--profile", nargs=2, type=float, metavar=("SIGMA_S_PRIME", "SIGMA_A"),
                    help="simulate one medium (coefficients in 1/UNITS; sigma_s = sigma_s' / (1 - g)) and write its "
                         "radial profile to -o as CSV (what brdf-scatter-fit reads)")
    ap.add_argument("--eta", type=float, default=1.3, help="relative index of --profile (default 1.3)")
    ap.add_argument("--units", default="mm", help="length unit of --profile (default mm)")
    ap.add_argument("-o", "--output", help="the CSV file of --profile")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress bars on stderr")
    args = ap.parse_args(argv)
    if args.profile:
        if not args.output:
            ap.error("--profile needs -o PROFILE.csv")
        ssp, sa = args.profile
        st = ssp + sa
        edges = np.concatenate([[0.0], np.geomspace(0.05, 60.0, 51)]) / st
        res = simulate(ssp / (1.0 - args.g), sa, g=args.g, eta=args.eta, n_photons=args.photons, seed=args.seed,
                       r_edges=edges, progress=not args.quiet)
        write_profile_csv(res, args.output, args.units)
        print(f"{args.output}: {edges.size - 1} annuli 0 .. {edges[-1]:.4g} {args.units}, Rd = {res.total:.4f} "
              f"+- {res.total_err:.4f} ({res.n_photons} photons, {res.seconds:.1f} s)")
        return 0
    if not args.table:
        ap.print_help()
        return 2
    table(args.albedos, args.etas, g=args.g, n_photons=args.photons, seed=args.seed, progress=not args.quiet)
    return 0


if __name__ == "__main__":
    sys.exit(main())
