"""Exact subsurface profiles vs the dipole vs Monte Carlo: the accuracy grid of issue 15.

For a medium (reduced albedo alpha', HG g, index eta; lengths in transport mean free paths) it
compares, against the harness's own photon migration (:mod:`harness.reference.mc_subsurface`,
which shares no code with the library):

* the **exact profile** (the library's tables, ``sstool eval``): total diffuse reflectance =
  tabulated multiple scattering + the exact single-scattering albedo
  (:func:`harness.reference.dipole_ref.single_scatter_albedo_normal`), and the multiple-scattering
  Rd(r) as annulus means over the reference's bins;
* the **dipole** (:class:`harness.reference.dipole_ref.Dipole`, Jensen 2001): its Rd against the
  reference's total (it stands for single and multiple scattering together) and its Rd(r)
  against the reference's all-order profile;
* **renders** of a large slab at default settings (``dipole { ... }``, i.e. ``profile exact``)
  lit at normal incidence, seen at normal and oblique views, against the reference's
  next-event radiance (and, for eta = 1 and g = 0, Chandrasekhar's closed form).

Rd(r) is compared where the reference is statistically reliable: bins of [0.1, 31.6] mfp' (4 per
decade) whose relative standard error is below :data:`RELIABLE`; the rows say which radii that
covers. ``python -m harness.reports.ss_profiles [--quick]`` prints the grid and writes
``out/ss_profiles/ss_profiles.json`` and plots (the report section of ``make report`` runs it too).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from harness.core import plotting, runner
from harness.core import sstool as sst
from harness.core.paths import REPO_ROOT, ss_profiles
from harness.reference import dipole_ref, mc_subsurface

#: The grid of the issue: alpha' x g x eta.
ALPHAS = (0.3, 0.5, 0.7, 0.9, 0.99, 0.999)
GS = (0.0, 0.5, 0.9)
ETAS = (1.0, 1.33, 1.5)

#: Reference radial bins (transport mfp): the disc [0, 0.1), then 4 per decade to 31.6.
EDGES = np.concatenate([[0.0], np.geomspace(0.1, 10 ** 1.5, 11)])
#: A bin's reference value is used when its relative standard error is below this.
RELIABLE = 0.025
#: View cosines for the radiance (normal, and 60 degrees from the normal).
VIEWS = (1.0, 0.5)


@dataclass
class Case:
    g: float
    eta: float
    alpha_prime: float

    @property
    def albedo(self) -> float:
        """Single-scattering albedo: alpha' = alpha (1 - g) / (1 - alpha g)."""
        return self.alpha_prime / (1.0 - self.g + self.alpha_prime * self.g)

    @property
    def sigma_t_prime(self) -> float:
        """sigma_t' in units of sigma_t = 1."""
        return 1.0 - self.albedo * self.g

    def label(self) -> str:
        return f"a'={self.alpha_prime:g} g={self.g:g} eta={self.eta:g}"


def photons_for(case: Case, seconds: float = 45.0, most: int = 4_000_000, least: int = 20_000) -> int:
    """Reference photons for about `seconds` of simulation: the cost per photon measured on a
    pilot run of 2000 (long paths at high albedo and forward scattering cost far more)."""
    a = case.albedo
    t0 = time.perf_counter()
    mc_subsurface.simulate(a, 1.0 - a, g=case.g, eta=case.eta, n_photons=2000, seed=99)
    per = (time.perf_counter() - t0) / 2000
    return int(min(most, max(least, seconds / max(per, 1e-9))))


@dataclass
class Row:
    case: Case
    photons: int
    seconds: float
    mc_total: float
    mc_total_err: float
    mc_single: float
    mc_multiple: float
    exact_total: float
    dipole_total: float
    exact_total_err: float          # relative
    dipole_total_err: float
    rd_radii: list = field(default_factory=list)        # bin centres (mfp') compared
    exact_rd_err: list = field(default_factory=list)    # relative, per compared bin
    dipole_rd_err: list = field(default_factory=list)
    mc_rd: list = field(default_factory=list)           # multiple-scattering annulus means (reference)
    exact_rd: list = field(default_factory=list)
    mc_rd_all: list = field(default_factory=list)       # all orders (the dipole's counterpart)
    dipole_rd: list = field(default_factory=list)
    mc_radiance: list = field(default_factory=list)     # pi L / E_entering at VIEWS (single + multiple)
    mc_radiance_err: list = field(default_factory=list)

    @property
    def exact_rd_max(self) -> float:
        return max((abs(e) for e in self.exact_rd_err), default=math.nan)

    @property
    def dipole_rd_max(self) -> float:
        return max((abs(e) for e in self.dipole_rd_err), default=math.nan)

    @property
    def covered(self) -> tuple[float, float]:
        return (min(self.rd_radii), max(self.rd_radii)) if self.rd_radii else (math.nan, math.nan)


def compare(case: Case, tables: Optional[Path] = None, photons: Optional[int] = None, seed: int = 1) -> Row:
    """The exact profile and the dipole against the reference for one medium."""
    tables = tables or ss_profiles()
    n = photons or photons_for(case)
    a, st = case.albedo, case.sigma_t_prime
    t0 = time.perf_counter()
    ref = mc_subsurface.simulate(a, 1.0 - a, g=case.g, eta=case.eta, n_photons=n, seed=seed,
                                 r_edges=EDGES / st, views=mc_subsurface.view_directions(VIEWS))
    seconds = time.perf_counter() - t0
    # transport units: lengths times sigma_t', exitance per mfp'^2 divided by sigma_t'^2
    mc_m = ref.rd_r_multiple / st**2
    mc_m_err = ref.rd_r_multiple_err / st**2
    mc_all = ref.rd_r / st**2
    mc_all_err = ref.rd_r_err / st**2
    row_t = sst.eval_profile(tables, [case.alpha_prime], g=case.g, eta=case.eta, edges=EDGES, cos=VIEWS)[0]
    single = dipole_ref.single_scatter_albedo_normal(a, case.g, case.eta)
    exact_total = row_t["total"] + single
    dip = dipole_ref.Dipole(case.alpha_prime, 1.0 - case.alpha_prime, case.eta)  # sigma_t' = 1
    dip_means = np.array([dip.rd_annulus_mean(EDGES[i], EDGES[i + 1]) for i in range(len(EDGES) - 1)])
    ex_means = np.array(row_t["annulus_means"])
    r = Row(case=case, photons=n, seconds=seconds, mc_total=ref.total, mc_total_err=ref.total_err,
            mc_single=ref.single, mc_multiple=ref.multiple, exact_total=exact_total,
            dipole_total=dip.rd_total(), exact_total_err=exact_total / ref.total - 1.0,
            dipole_total_err=dip.rd_total() / ref.total - 1.0)
    for i in range(1, len(EDGES) - 1):
        if not (mc_m[i] > 0 and mc_m_err[i] < RELIABLE * mc_m[i]):
            continue
        r.rd_radii.append(float(math.sqrt(EDGES[i] * EDGES[i + 1])))
        r.exact_rd_err.append(float(ex_means[i] / mc_m[i] - 1.0))
        r.mc_rd.append(float(mc_m[i]))
        r.exact_rd.append(float(ex_means[i]))
        ok_all = mc_all[i] > 0 and mc_all_err[i] < RELIABLE * mc_all[i]
        r.dipole_rd_err.append(float(dip_means[i] / mc_all[i] - 1.0) if ok_all else math.nan)
        r.mc_rd_all.append(float(mc_all[i]))
        r.dipole_rd.append(float(dip_means[i]))
    r.mc_radiance = [float(v) for v in ref.radiance_single + ref.radiance_multiple]
    r.mc_radiance_err = [float(v) for v in np.hypot(ref.radiance_single_err, ref.radiance_multiple_err)]
    return r


# ---------------------------------------------------------------- renders of the slab

SLAB = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location {eye} direction {dir} right <4, 0, 0> up {up} }}
light_source {{ <0, 0, 1000> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-400, -400, -400>, <400, 400, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ {dipole} }} }} }} }}
"""


def slab_scene(case: Case, cos_view: float = 1.0, extra: str = "") -> str:
    """A slab 800 x 800 x 400 mfp' (sigma_t' = 1 per mm, 1 unit = 1 mm) at default settings, lit
    straight from above, seen by an orthographic camera at `cos_view` (in the xz plane)."""
    s = math.sqrt(max(0.0, 1.0 - cos_view * cos_view))
    d = (-s, 0.0, -cos_view)  # looking down, from +x
    eye = (50 * s, 0.0, 50 * cos_view)
    up = (-cos_view * 4, 0.0, s * 4) if s > 0 else (0.0, 4.0, 0.0)
    fmt = lambda v: f"<{v[0]:.9g}, {v[1]:.9g}, {v[2]:.9g}>"
    ss = case.alpha_prime / (1.0 - case.g)
    dip = (f"sigma_s {ss!r} anisotropy {case.g!r} sigma_a {1.0 - case.alpha_prime!r} ior {case.eta!r} "
           f"mm_per_unit 1 {extra}")
    return SLAB.format(eye=fmt(eye), dir=fmt(d), up=fmt(up), dipole=dip)


def render_slab(case: Case, cos_view: float = 1.0, extra: str = "", size: int = 8) -> float:
    """Mean pixel (pi x radiance for a light of irradiance 1 at normal incidence) of the slab."""
    r = runner.render(slab_scene(case, cos_view, extra), "fork", width=size, height=size, float_exr=True)
    return float(r.image[..., 0].mean())


def expected_pixel(row: Row, view: int) -> tuple[float, float]:
    """The reference pixel at VIEWS[view] and its standard error: the next-event pi L per unit
    entering irradiance times the entering irradiance Ft(1) (light of irradiance 1, normal)."""
    ft = 1.0 - float(dipole_ref.fresnel_dielectric(1.0, row.case.eta))
    return row.mc_radiance[view] * ft, row.mc_radiance_err[view] * ft


# ---------------------------------------------------------------- the grid

def grid(alphas: Sequence[float] = ALPHAS, gs: Sequence[float] = GS, etas: Sequence[float] = ETAS,
         seconds: float = 45.0, log=print) -> list[Row]:
    """Every case, each reference run sized to about `seconds`."""
    rows = []
    for g in gs:
        for eta in etas:
            for ap in alphas:
                c = Case(g, eta, ap)
                row = compare(c, photons=photons_for(c, seconds))
                rows.append(row)
                lo, hi = row.covered
                log(f"{c.label():26s} total MC {row.mc_total:.4f}+-{row.mc_total_err:.4f} exact {row.exact_total_err:+.4f} "
                    f"dipole {row.dipole_total_err:+.4f} | Rd(r) max |err| exact {row.exact_rd_max:.3f} dipole "
                    f"{row.dipole_rd_max:.3f} over r in [{lo:.2g}, {hi:.2g}] ({len(row.rd_radii)} bins) "
                    f"| {row.photons} photons {row.seconds:.0f} s")
    return rows


def issue_render(case: Case) -> bool:
    """The renders issue 15 asks for: alpha' in {0.5, 0.9, 0.99} with g = 0, eta = 1 (against
    Chandrasekhar) and with g in {0.5, 0.9} at every eta (against the reference's radiance)."""
    return case.alpha_prime in (0.5, 0.9, 0.99) and (case.g in (0.5, 0.9) or (case.g == 0.0 and case.eta == 1.0))


def render_rows(rows: Sequence[Row], log=print, only=None, dipole: bool = True) -> list[dict]:
    """Render the slab of every row (``only(case)``: those it accepts) at default settings (the
    exact profile) and, with ``dipole``, with ``profile dipole`` at each of VIEWS; errors against
    the reference's next-event radiance, and for g = 0, eta = 1 also against Chandrasekhar's
    closed form (``closed``, ``exact_err_closed``)."""
    out = []
    for row in rows:
        if only is not None and not only(row.case):
            continue
        for i, mu in enumerate(VIEWS):
            want, err = expected_pixel(row, i)
            ex = render_slab(row.case, cos_view=mu)
            dp = render_slab(row.case, cos_view=mu, extra="profile dipole") if dipole else math.nan
            d = {"case": row.case.label(), "g": row.case.g, "eta": row.case.eta, "alpha_prime": row.case.alpha_prime,
                 "cos_view": mu, "mc": want, "mc_err": err, "exact": ex, "dipole": dp,
                 "exact_err": ex / want - 1.0, "dipole_err": dp / want - 1.0, "mc_rel_err": err / want}
            if row.case.g == 0.0 and row.case.eta == 1.0:
                d["closed"] = dipole_ref.plane_radiance_isotropic(row.case.alpha_prime, mu)
                d["exact_err_closed"] = ex / d["closed"] - 1.0
                log(f"render {row.case.label():26s} view cos {mu:g}: Chandrasekhar {d['closed']:.5f} exact "
                    f"{100 * d['exact_err_closed']:+.2f} %")
            out.append(d)
            log(f"render {row.case.label():26s} view cos {mu:g}: MC {want:.5f} (+-{100 * err / want:.2f} %) exact "
                f"{100 * d['exact_err']:+.2f} % dipole {100 * d['dipole_err']:+.2f} %")
    return out


def plot_totals(rows: Sequence[Row], path: Path) -> Path:
    plt = plotting.pyplot()
    gs = sorted({r.case.g for r in rows})
    etas = sorted({r.case.eta for r in rows})
    fig, axes = plt.subplots(1, len(gs), figsize=(4.0 * len(gs), 3.4), squeeze=False)
    for ax, g in zip(axes[0], gs):
        for eta, col in zip(etas, ("C0", "C1", "C2", "C3")):
            sub = [r for r in rows if r.case.g == g and r.case.eta == eta]
            x = [1.0 - r.case.alpha_prime for r in sub]
            ax.plot(x, [100 * r.exact_total_err for r in sub], "o-", color=col, label=f"exact, eta {eta:g}")
            ax.plot(x, [100 * r.dipole_total_err for r in sub], "x--", color=col, label=f"dipole, eta {eta:g}")
        ax.axhspan(-2, 2, color="0.9")
        ax.set_xscale("log")
        ax.set_xlabel("1 - alpha'")
        ax.set_ylabel("total reflectance vs Monte Carlo (%)")
        ax.set_title(f"g = {g:g}")
        ax.set_ylim(-40, 70)
    axes[0][0].legend(fontsize=plotting.SMALL_PT)
    fig.tight_layout()
    plotting.save(fig, path)
    return path


def plot_profiles(rows: Sequence[Row], path: Path) -> Path:
    plt = plotting.pyplot()
    pick = [r for r in rows if r.case.eta == 1.33 and r.case.alpha_prime in (0.5, 0.99)] or list(rows[:4])
    # at most three panels a row: the page shows the figure at its natural size (<= 1100 px)
    ncols = min(3, len(pick))
    nrows = -(-len(pick) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, 3.2 * nrows), squeeze=False)
    for ax in axes.flat[len(pick):]:
        ax.set_visible(False)
    for ax, r in zip(axes.flat, pick):
        x = np.array(r.rd_radii)
        ax.loglog(x, r.mc_rd, "k.", label="MC, multiple")
        ax.loglog(x, r.exact_rd, "C0-", label="exact (tables)")
        ax.loglog(x, r.mc_rd_all, "k+", label="MC, all orders")
        ax.loglog(x, r.dipole_rd, "C3--", label="dipole")
        ax.set_title(r.case.label(), fontsize=8)
        ax.set_xlabel("r (mfp')")
    for row in axes:
        row[0].set_ylabel("Rd(r) per mfp'^2")
    axes[0][0].legend(fontsize=plotting.SMALL_PT)
    fig.tight_layout()
    plotting.save(fig, path)
    return path


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.ss_profiles", description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="alpha' in {0.5, 0.99}, 4 s of simulation per case")
    ap.add_argument("--seconds", type=float, default=45.0, help="simulation time per case (sizes the photon count)")
    ap.add_argument("--out", type=Path, default=REPO_ROOT / "out" / "ss_profiles")
    ap.add_argument("--renders", choices=("all", "issue"), default="all",
                    help="all: every case, exact and dipole; issue: issue 15's cases (issue_render), exact only")
    args = ap.parse_args(argv)
    alphas = (0.5, 0.99) if args.quick else ALPHAS
    rows = grid(alphas, seconds=4.0 if args.quick else args.seconds)
    renders = (render_rows(rows) if args.renders == "all" else render_rows(rows, only=issue_render, dipole=False))
    args.out.mkdir(parents=True, exist_ok=True)
    plot_totals(rows, args.out / "totals.png")
    plot_profiles(rows, args.out / "profiles.png")
    (args.out / "ss_profiles.json").write_text(json.dumps({"rows": [asdict(r) for r in rows], "renders": renders},
                                                          indent=1, default=float))
    worst = max(abs(r.exact_total_err) for r in rows)
    worst_rd = max(r.exact_rd_max for r in rows)
    worst_px = max(abs(d.get("exact_err_closed", d["exact_err"])) for d in renders)
    print(f"exact profile: worst total error {100 * worst:.2f} %, worst Rd(r) error {100 * worst_rd:.1f} %, worst "
          f"rendered radiance error {100 * worst_px:.2f} %; written to {args.out}")
    print(markdown(rows, renders))
    return 0


def markdown(rows: Sequence[Row], renders: Sequence[dict] = ()) -> str:
    """The accuracy grid as Markdown tables (shading/DIPOLE.md section 10.6 carries one)."""
    lines = ["| alpha' | g | eta | MC total +- se | exact total | dipole total | exact max Rd(r) | dipole max Rd(r) | r compared (mfp') |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lo, hi = r.covered
        lines.append(f"| {r.case.alpha_prime:g} | {r.case.g:g} | {r.case.eta:g} | {r.mc_total:.4f} +- {r.mc_total_err:.4f} | "
                     f"{100 * r.exact_total_err:+.2f} % | {100 * r.dipole_total_err:+.1f} % | {100 * r.exact_rd_max:.1f} % | "
                     f"{100 * r.dipole_rd_max:.0f} % | {lo:.2g}-{hi:.2g} ({len(r.rd_radii)} bins) |")
    if renders:
        lines += ["", "| alpha' | g | eta | view cos | MC pixel (se) | exact vs MC | exact vs Chandrasekhar | dipole vs MC |",
                  "|---|---|---|---|---|---|---|---|"]
        for d in renders:
            closed = f"{100 * d['exact_err_closed']:+.2f} %" if "exact_err_closed" in d else "–"
            dip = f"{100 * d['dipole_err']:+.1f} %" if math.isfinite(d["dipole_err"]) else "–"
            lines.append(f"| {d['alpha_prime']:g} | {d['g']:g} | {d['eta']:g} | {d['cos_view']:g} | {d['mc']:.5f} "
                         f"({100 * d['mc_rel_err']:.2f} %) | {100 * d['exact_err']:+.2f} % | {closed} | {dip} |")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
