"""Image error of tabulated BRDFs against the same model evaluated directly.

A sphere under three distant lights (head-on, 45 deg, and a grazing 80 deg light) is
rendered by the fork twice: with ``brdf_model { "spec" }`` (the reference: the model
evaluated per shading point) and with ``brdf_table`` of that model at several steps, with
nearest and trilinear lookups. Printed: rel-RMSE over the sphere, max relative error of
pixels above 5 % of the peak, and the table's memory.

``--layouts`` prints the error-vs-memory study of both layouts instead (:func:`layout_study`):
narrow Beckmann lobes (:data:`NARROW`) tabulated in the isotropic layout at several steps and
in the half/difference layout at several node counts (:data:`LAYOUTS`), each sphere against the
independent numpy model (:mod:`harness.reference.models`); ``make report`` plots it.

    python -m harness.reports.table_error            # default materials and steps
    python -m harness.reports.table_error --steps 1,2
    python -m harness.reports.table_error --layouts  # both layouts, error vs bytes
"""

from __future__ import annotations

import argparse
import sys
from typing import Optional, Sequence

import numpy as np

from harness.core import runner, tables
from harness.core.compare import rel_rmse
from harness.reference.expect import expected_image, surface_samples
from harness.core.scenes import DistantLight, SphereScene

MATERIALS = {
    "rough dielectric (beckmann m=0.3)": "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.7",
    "glossy plastic (tr m=0.15)": "microfacet d=tr m=0.15 f=dielectric eta=1.5 kd=0.5 rho_s=0.5",
    "narrow gold (beckmann m=0.05)": "microfacet d=beckmann m=0.05 f=conductor n=0.143,0.374,1.442 k=3.983,2.385,1.603",
}
LIGHTS = (DistantLight(0.0), DistantLight(45.0, 30.0), DistantLight(80.0, 200.0))


def scene(finish: dict, size: int) -> SphereScene:
    return SphereScene(lights=LIGHTS, finish=finish, width=size, height=size)


def study(spec: str, steps: Sequence[float], size: int = 160) -> list[dict]:
    mask = surface_samples(scene({}, size)).mask
    ref = runner.render(scene({"brdf_model": {"spec": spec}}, size), "fork", float_exr=True).image
    peak = float(ref[mask].max())
    bright = mask & (ref.max(axis=-1) > 0.05 * peak)
    rows = []
    for step in steps:
        path = tables.tabulated(spec, step=step, fold=True)
        for interp, name in ((0, "nearest"), (1, "trilinear")):
            res = runner.render(scene({"brdf_table": {"file": "t.brdf", "interpolate": interp}}, size), "fork",
                                float_exr=True, files={"t.brdf": path})
            img = res.image
            rel = np.abs(img - ref)[bright] / np.maximum(ref[bright], 1e-6)
            rows.append({"step": step, "interp": name, "rel_rmse": rel_rmse(img, ref, mask),
                         "max_rel_bright": float(rel.max()), "bytes": path.stat().st_size})
    return rows


#: The narrow lobes of issue 16: Beckmann m = 0.02, 0.05, 0.1, a dielectric on a Lambertian
#: base and gold (conductor, n and k as in :data:`MATERIALS`).
NARROW = {f"beckmann m={m} {name}": f"microfacet d=beckmann m={m} {tail}"
          for m in (0.02, 0.05, 0.1)
          for name, tail in (("dielectric", "f=dielectric eta=1.5 kd=0.3 rho_s=0.7"),
                             ("gold", "f=conductor n=0.143,0.374,1.442 k=3.983,2.385,1.603"))}
#: (layout, resolution): isotropic steps in degrees (reciprocity-folded tables, as
#: :func:`study`), half/difference (theta_h, theta_d, phi_d) node counts; 90 x 90 x 180 is
#: MERL's grid, 256 x 128 x 32 ``brdftool``'s default.
LAYOUTS: tuple[tuple[str, object], ...] = (
    ("isotropic", 5.0), ("isotropic", 2.0), ("isotropic", 1.0), ("isotropic", 0.5),
    ("halfdiff", (64, 32, 16)), ("halfdiff", (128, 64, 32)), ("halfdiff", (90, 90, 180)),
    ("halfdiff", (256, 128, 32)), ("halfdiff", (360, 128, 32)))
#: The issue's goal: rel-RMSE against the model at no more than this many bytes per RGB table.
GOAL_REL_RMSE, GOAL_BYTES = 3e-3, 18_000_000


def layout_label(layout: str, res: object) -> str:
    return f"{res:g}°" if layout == "isotropic" else "×".join(str(n) for n in res)  # type: ignore[union-attr]


def layout_table(spec: str, layout: str, res: object):
    """The cached table of ``spec`` in ``layout`` at resolution ``res`` (see :data:`LAYOUTS`)."""
    if layout == "isotropic":
        return tables.tabulated(spec, step=float(res), fold=True)  # type: ignore[arg-type]
    return tables.tabulated_halfdiff(spec, tuple(res))  # type: ignore[arg-type]


def layout_study(spec: str, layouts: Sequence[tuple[str, object]] = LAYOUTS, size: int = 160) -> list[dict]:
    """rel-RMSE of the fork's sphere with a trilinear table of ``spec`` in each layout, against
    the numpy model's sphere (:func:`harness.reference.expect.expected_image`), and the file's bytes."""
    ref = expected_image(scene({"brdf_model": {"spec": spec}}, size))
    mask = surface_samples(scene({}, size)).mask
    rows = []
    for layout, res in layouts:
        path = layout_table(spec, layout, res)
        img = runner.render(scene({"brdf_table": {"file": "t.brdf"}}, size), "fork", float_exr=True,
                            files={"t.brdf": path}).image
        rows.append({"layout": layout, "resolution": layout_label(layout, res), "bytes": path.stat().st_size,
                     "rel_rmse": rel_rmse(img, ref, mask)})
    return rows


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.table_error", description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", default="0.5,1,2,5", help="table steps in degrees (default 0.5,1,2,5)")
    ap.add_argument("--size", type=int, default=160, help="image size in pixels (default 160)")
    ap.add_argument("--layouts", action="store_true",
                    help="error vs memory of the isotropic and half/difference layouts for narrow lobes")
    args = ap.parse_args(argv)
    if args.layouts:
        print(f"{'material':<28} {'layout':<10} {'resolution':>12} {'MB':>7} {'rel-RMSE':>10}  goal")
        for label, spec in NARROW.items():
            for r in layout_study(spec, size=args.size):
                ok = r["rel_rmse"] <= GOAL_REL_RMSE and r["bytes"] <= GOAL_BYTES
                print(f"{label:<28} {r['layout']:<10} {r['resolution']:>12} {r['bytes'] / 1e6:>7.2f} "
                      f"{r['rel_rmse']:>10.2e}  {'yes' if ok else ''}", flush=True)
        return 0
    steps = [float(s) for s in args.steps.split(",")]
    print(f"{'material':<36} {'step':>5} {'lookup':>9} {'rel-RMSE':>10} {'max rel (>5% peak)':>19} {'file MB':>8}")
    for label, spec in MATERIALS.items():
        for r in study(spec, steps, args.size):
            print(f"{label:<36} {r['step']:>5g} {r['interp']:>9} {r['rel_rmse']:>10.2e} "
                  f"{r['max_rel_bright']:>19.2e} {r['bytes'] / 1e6:>8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
