"""Every analytic finish: error against its closed form, and render cost against stock ``phong``.

For each model (one spec per family, equal roughness m = 0.25 where the model has one):

* **error**: a sphere (orthographic, pixel centres, float EXR) under one distant light at
  0, 45, 80 and 89.9 deg from the view, rendered by the fork with ``brdf_model``, against the
  model re-derived in numpy (:mod:`harness.reference.models`); rel-RMSE over the sphere per angle;
* **cost**: the trace-time ratio of the bench reference scene (:data:`harness.reports.bench.REFERENCE_SCENE`,
  9 spheres and a reflective plane) with every sphere's finish replaced by the model, rendered
  by the fork, against the unchanged scene (``diffuse 0.6 phong 0.6 phong_size 30 specular 0.2``)
  rendered by stock POV-Ray: median of ``--repeat`` alternating pairs after a warm-up pair.

    python -m harness.reports.model_bench                # table on stdout (markdown)
    python -m harness.reports.model_bench -k microfacet  # models whose spec contains the text
    python -m harness.reports.model_bench --no-time      # errors only (fast)

Numbers are printed, never asserted (the tests assert the errors with a tolerance).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from typing import Optional, Sequence

from harness.reports import bench
from harness.core import runner
from harness.core.compare import rel_rmse
from harness.reference.expect import expected_image, surface_samples
from harness.core.scenes import DistantLight, SphereScene

CONDUCTOR = "f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8"
#: (label, spec): one per family; microfacet at m = 0.25 with each D and G.
MODELS: list[tuple[str, str]] = [
    ("lambert", "lambert rho=0.6"),
    ("phong_pov (POV phong as a model)", "phong_pov phong=0.6 phong_size=30 diffuse=0.6"),
    ("blinn_pov (POV specular as a model)", "blinn_pov specular=0.2 roughness=0.02 diffuse=0.6"),
    ("phong_normalized", "phong_normalized kd=0.5 ks=0.4 n=30"),
    *[(f"microfacet {d} / {g}", f"microfacet d={d} m=0.25 g={g} {CONDUCTOR}")
      for d in ("blinn", "gaussian", "tr", "beckmann") for g in ("vcavity", "smith")],
    ("microfacet survey form, Beckmann / V-cavity", "microfacet form=survey d=beckmann m=0.25 g=vcavity rho_s=0.3 kd=0.5"),
    ("microfacet dielectric on a base (plastic)", "microfacet d=tr m=0.15 f=dielectric eta=1.5 kd=0.6 rho_s=0.4"),
    ("microfacet Schlick", "microfacet d=beckmann m=0.25 f=schlick f0=0.9,0.6,0.3"),
    ("ward isotropic", "ward rho_d=0.4 rho_s=0.3 alpha=0.25"),
    ("ward anisotropic", "ward rho_d=0.4 rho_s=0.3 ax=0.1 ay=0.4"),
    ("ward original (1992)", "ward variant=original rho_d=0.4 rho_s=0.3 ax=0.1 ay=0.4"),
    ("oren_nayar", "oren_nayar rho=0.6 sigma=0.4"),
    ("lafortune (2 lobes)", "lafortune kd=0.3 lobe=-1,-1,1,30,0.4 lobe=0.8,0.8,0.9,4,0.1"),
]
ANGLES = (0.0, 45.0, 80.0, 89.9)


@dataclass
class ModelResult:
    label: str
    spec: str
    errors: list[float]
    timing: Optional[bench.Result] = None  # stock/fork trace times (ratio, spread derive from it)


def closed_form_errors(spec: str, size: int = 128) -> list[float]:
    """rel-RMSE of the fork's sphere against numpy, one light per entry of :data:`ANGLES`."""
    out = []
    for th in ANGLES:
        scene = SphereScene(lights=(DistantLight(th, 30.0),), finish={"brdf_model": {"spec": spec, "direction": (0.3, 1.0, 0.2)}},
                            width=size, height=size)
        img = runner.render(scene, "fork", float_exr=True).image
        out.append(rel_rmse(img, expected_image(scene), surface_samples(scene).mask))
    return out


def cost_row(spec: str) -> bench.Row:
    cand = bench.REFERENCE_SCENE.replace(bench.STOCK_FINISH, f'finish {{ brdf_model {{ "{spec}" }} }}')
    assert cand != bench.REFERENCE_SCENE
    return bench.Row(spec, bench.Side("stock", bench.REFERENCE_SCENE), bench.Side("fork", cand),
                     width=1280, height=960)


def run(models: Sequence[tuple[str, str]], repeat: int = 3, timing: bool = True,
        log=None) -> list[ModelResult]:
    results = []
    for label, spec in models:
        r = ModelResult(label, spec, closed_form_errors(spec))
        if timing:
            r.timing = bench.measure(cost_row(spec), repeat, log)
        if log:
            log(f"{label}: errors {', '.join(f'{e:.1e}' for e in r.errors)}"
                + (f", ratio {r.timing.ratio:.3f}" if r.timing else ""))
        results.append(r)
    return results


def markdown(results: Sequence[ModelResult]) -> str:
    head = "| model | " + " | ".join(f"rel-RMSE {a:g}°" for a in ANGLES) + " | trace / stock phong | spread |"
    lines = [head, "|" + "---|" * (len(ANGLES) + 3)]
    for r in results:
        ratio = f"{r.timing.ratio:.3f}" if r.timing else "–"
        spread = f"{min(r.timing.ratios):.2f}..{max(r.timing.ratios):.2f}" if r.timing else "–"
        lines.append(f"| {r.label} | " + " | ".join(f"{e:.1e}" for e in r.errors) + f" | {ratio} | {spread} |")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.model_bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("-k", dest="pattern", default="", help="only models whose label or spec contains this text")
    ap.add_argument("--repeat", type=int, default=3, help="stock/fork pairs per model (default 3)")
    ap.add_argument("--no-time", action="store_true", help="closed-form errors only")
    ap.add_argument("-q", "--quiet", action="store_true")
    args = ap.parse_args(argv)
    models = [m for m in MODELS if args.pattern in m[0] or args.pattern in m[1]]
    if not models:
        print(f"no model matches {args.pattern!r}", file=sys.stderr)
        return 2
    log = None if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    print(markdown(run(models, max(1, args.repeat), not args.no_time, log)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
