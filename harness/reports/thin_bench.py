"""Thin geometry of the dipole finish (issue 15; shading/DIPOLE.md section 6a): numbers for the note.

* **slab totals**: the multipole's diffuse reflectance and transmittance of a slab
  (:func:`harness.reference.dipole_ref.slab_totals`, the diffusion theory the finish uses) against
  the harness Monte Carlo with slabs (``mc_subsurface.simulate(thickness=...)``; all scattering
  orders, isotropic, per unit entering power), d x alpha' x eta; skipped with a note where the
  Monte Carlo has no slabs;
* **exact slab tables**: the shipped ``subsurface_slabs.ssp`` (``profile exact``), R and T of all
  scattering orders per entering power, against the same Monte Carlo over the same grid;
* **back-lit sheet**: a 50 mm wide sheet of sigma_s' = 1/mm, sigma_a = 0.05/mm, eta = 1.3 lit from
  behind at normal incidence, default sampling: centre pixel vs Ft(1)^2 T(d), and vs
  ``thin_geometry off`` (the half-space dipole);
* **cost**: trace time of a thick object (the 15 mm slab of dipole_bench, above its slab
  threshold) and of the 1 mfp sheet, thin geometry on vs off, interleaved runs, medians.

    python -m harness.reports.thin_bench [--photons 20000] [--repeat 5] [--no-mc]
"""

from __future__ import annotations

import argparse
import inspect
import math
import statistics
import sys

import numpy as np

from harness.core import runner
from harness.reference import dipole_ref, mc_subsurface

SIGMA_S_PRIME, SIGMA_A, ETA = 1.0, 0.05, 1.3
MFP = 1.0 / (SIGMA_S_PRIME + SIGMA_A)
DIPOLE = f"sigma_s_prime {SIGMA_S_PRIME} sigma_a {SIGMA_A} ior {ETA} mm_per_unit 1 profile dipole"
SHEET = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 0, 20> direction <0, 0, -1> right <{view}, 0, 0> up <0, {view}, 0> }}
light_source {{ <0, 0, {light}> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-25, -25, {bottom}>, <25, 25, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ {dipole} }} }} }} }}
"""


def sheet_scene(d: float, light_z: float, extra: str = "", view: float = 4.0) -> str:
    return SHEET.format(light=light_z, bottom=-d, dipole=DIPOLE + extra, view=view)


def mc_table(photons: int) -> list[tuple]:
    if "thickness" not in inspect.signature(mc_subsurface.simulate).parameters:
        print("slab totals: this harness Monte Carlo has no slabs (it comes with the exact profiles); skipped")
        return []
    rows = []
    print("slab totals, multipole (diffusion) vs Monte Carlo (all orders, isotropic), per entering power")
    print("alpha'  eta  d/mfp |   MC R     T    | multipole R  T | error R %  T %")
    for ap in (0.5, 0.9, 0.99):
        for eta in (1.0, 1.33, 1.5):
            for t in (0.25, 1.0, 4.0, 16.0):
                r = mc_subsurface.simulate(ap, 1.0 - ap, 0.0, eta, n_photons=photons, seed=7, thickness=t)
                R, T = dipole_ref.slab_totals(dipole_ref.Dipole(ap, 1.0 - ap, eta), t)
                eR, eT = R / r.total - 1.0, (T / r.t_total - 1.0) if r.t_total > 0 else float("nan")
                rows.append((ap, eta, t, r.total, r.t_total, R, T, eR, eT))
                print(f"{ap:6.2f} {eta:5.2f} {t:5.2f} | {r.total:.4f} {r.t_total:.4f} | {R:.4f} {T:.4f} | "
                      f"{100 * eR:+6.1f} {100 * eT:+6.1f}", flush=True)
    return rows


def exact_table(photons: int) -> list[tuple]:
    """The shipped exact slab tables (multiple + single scattering) against the Monte Carlo."""
    from harness.core import sstool as sst
    from harness.core.paths import ss_slabs
    try:
        path = ss_slabs()
    except FileNotFoundError as e:
        print(f"exact slab tables: {e}; skipped")
        return []
    rows, worst = [], [0.0, 0.0]
    print(f"exact slab tables ({path.name}) vs Monte Carlo (all orders, isotropic), per entering power")
    print("alpha'  eta  d/mfp |   MC R     T    | tables R  T    | error R %  T %")
    for ap in (0.5, 0.9, 0.99):
        for eta in (1.0, 1.33, 1.5):
            for t in (0.25, 1.0, 4.0, 16.0):
                r = mc_subsurface.simulate(ap, 1.0 - ap, 0.0, eta, n_photons=photons, seed=7, thickness=t)
                fr = sst.eval_profile(path, [ap], eta=eta, thickness=t, face="r")[0]
                ft = sst.eval_profile(path, [ap], eta=eta, thickness=t, face="t")[0]
                R, T = fr["total"] + fr["single"], ft["total"] + ft["single"]
                eR, eT = R / r.total - 1.0, (T / r.t_total - 1.0) if r.t_total > 0 else float("nan")
                worst[0] = max(worst[0], abs(eR))
                if r.t_total > 1e-3:
                    worst[1] = max(worst[1], abs(eT))
                rows.append((ap, eta, t, r.total, r.t_total, R, T, eR, eT))
                print(f"{ap:6.2f} {eta:5.2f} {t:5.2f} | {r.total:.4f} {r.t_total:.4f} | {R:.4f} {T:.4f} | "
                      f"{100 * eR:+6.2f} {100 * eT:+6.2f}", flush=True)
    print(f"  worst |R| {100 * worst[0]:.2f} %, |T| {100 * worst[1]:.2f} % (where T_MC > 1e-3)")
    return rows


def centre(res) -> float:
    img = res.image[..., 0].astype(np.float64)
    h, w = img.shape
    return float(img[h // 4: 3 * h // 4, w // 4: 3 * w // 4].mean())


def sheets() -> None:
    ch = dipole_ref.Dipole(SIGMA_S_PRIME, SIGMA_A, ETA)
    ft2 = (1.0 - float(dipole_ref.fresnel_dielectric(1.0, ETA))) ** 2
    print("back-lit sheet (default sampling): centre pixel vs Ft(1)^2 T(d); thin_geometry off")
    for t in (0.25, 1.0, 4.0):
        d = t * MFP
        on = centre(runner.render(sheet_scene(d, -1000), "fork", width=16, height=16, float_exr=True, threads=2))
        off = centre(runner.render(sheet_scene(d, -1000, " thin_geometry off"), "fork", width=16, height=16,
                                   float_exr=True, threads=2))
        want = ft2 * dipole_ref.slab_totals(ch, d)[1]
        print(f"  d = {t:4.2f} mfp: pixel {on:.5f}, diffusion {want:.5f} ({100 * (on / want - 1):+.2f} %); off {off:.5f}")
        # the exact profile (its slab: the exact slab tables, subsurface_slabs.ssp) against the
        # Monte Carlo's diffuse transmittance in the same convention, Ft(1)^2 T_MC
        if "thickness" in inspect.signature(mc_subsurface.simulate).parameters:
            try:
                ex = centre(runner.render(sheet_scene(d, -1000).replace(" profile dipole", " profile exact"), "fork",
                                          width=16, height=16, float_exr=True, threads=2))
            except runner.RenderError as e:
                print(f"    profile exact: not available ({str(e).splitlines()[0]})")
                continue
            mc = mc_subsurface.simulate(SIGMA_S_PRIME, SIGMA_A, 0.0, ETA, n_photons=400000, seed=3, thickness=d)
            mc_want = ft2 * mc.t_total
            rad = math.sqrt(ft2) * mc.extra.get("t_radiance_normal", float("nan"))
            print(f"    profile exact: pixel {ex:.5f}; MC transmitted radiance Ft(1) pi L_t {rad:.5f} "
                  f"({100 * (ex / rad - 1):+.2f} %); Ft(1)^2 T_MC {mc_want:.5f} ({100 * (ex / mc_want - 1):+.2f} %); "
                  f"multipole vs Ft(1)^2 T_MC {100 * (want / mc_want - 1):+.2f} %")


def cost(repeat: int) -> None:
    print(f"trace time, thin geometry on / off, 1 thread, 128 x 128, medians of {repeat} interleaved runs")
    for name, d in (("thick 15 mm slab", 15.0), ("1 mfp sheet", MFP)):
        times = {"on": [], "off": []}
        for _ in range(repeat):
            for key, extra in (("on", ""), ("off", " thin_geometry off")):
                res = runner.render(sheet_scene(d, 1000, extra, view=40.0), "fork", width=128, height=128, threads=1)
                times[key].append(res.trace_seconds or float("nan"))
        on, off = statistics.median(times["on"]), statistics.median(times["off"])
        print(f"  {name}: on {on:.3f} s, off {off:.3f} s, ratio {on / off:.3f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photons", type=int, default=20000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-mc", action="store_true")
    args = ap.parse_args(argv)
    if not args.no_mc:
        mc_table(args.photons)
        exact_table(max(args.photons, 200000))
    sheets()
    cost(args.repeat)
    return 0


if __name__ == "__main__":
    sys.exit(main())
