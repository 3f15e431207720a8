"""Image error of tabulated BRDFs against the same model evaluated directly.

A sphere under three distant lights (head-on, 45 deg, and a grazing 80 deg light) is
rendered by the fork twice: with ``brdf_model { "spec" }`` (the reference: the model
evaluated per shading point) and with ``brdf_table`` of that model at several steps, with
nearest and trilinear lookups. Printed: rel-RMSE over the sphere, max relative error of
pixels above 5 % of the peak, and the table's memory.

    python -m harness.reports.table_error            # default materials and steps
    python -m harness.reports.table_error --steps 1,2
"""

from __future__ import annotations

import argparse
import sys
from typing import Optional, Sequence

import numpy as np

from harness.core import runner, tables
from harness.core.compare import rel_rmse
from harness.reference.expect import surface_samples
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


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.table_error", description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", default="0.5,1,2,5", help="table steps in degrees (default 0.5,1,2,5)")
    ap.add_argument("--size", type=int, default=160, help="image size in pixels (default 160)")
    args = ap.parse_args(argv)
    steps = [float(s) for s in args.steps.split(",")]
    print(f"{'material':<36} {'step':>5} {'lookup':>9} {'rel-RMSE':>10} {'max rel (>5% peak)':>19} {'file MB':>8}")
    for label, spec in MATERIALS.items():
        for r in study(spec, steps, args.size):
            print(f"{label:<36} {r['step']:>5g} {r['interp']:>9} {r['rel_rmse']:>10.2e} "
                  f"{r['max_rel_bright']:>19.2e} {r['bytes'] / 1e6:>8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
