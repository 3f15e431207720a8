"""Glossy reflection (``samples N``) of a table against the same BRDF as a model: noise and bias.

Issue 16's white furnace: a unit sphere, orthographic camera, a uniform sky of radiance 1, no
lights, ambient 0, so every pixel's expected value is the directional albedo of the finish at
the pixel's viewing angle theta_o. The BRDF is Beckmann m = 0.3 with height-correlated Smith
masking and F = 1 (``microfacet d=beckmann m=0.3``):

* **model**: ``brdf_model``; expectation: the model's glossy albedo from ``brdftool albedo
  --glossy`` (the library's quadrature, which ``tests/test_analytic_finishes.py`` checks);
* **table**: the same BRDF as a 1 deg reciprocity-folded table (``brdf_table``), sampled from its
  own data (``TableSampler``); expectation: the table's albedo integrated in numpy from the file
  (:func:`harness.reference.table_albedo.table_albedo`).

For each ``samples`` N the report prints the per-pixel rms of the relative error and its mean
(the bias) over the sphere's pixels with theta_o < 80 deg (the rim mixes a steep albedo slope
into single pixels). Issue 16 measured, before the table sampler: table 28.5 % / 8.6 % at 16 / 64
samples, model 2.75 % / 0.93 %.

    python -m harness.reports.glossy_noise [--size 96] [--samples 16,64]

Numbers are printed, never asserted (``tests/test_table_sampling.py`` asserts a small version).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from harness.core import brdf_io, runner, tables
from harness.core.paths import brdftool
from harness.core.scenes import SphereScene
from harness.reference.expect import surface_samples
from harness.reference.table_albedo import table_albedo

SPEC = "microfacet d=beckmann m=0.3"
FURNACE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 max_trace_level 5 ambient_light 0 }}
camera {{ orthographic location <0, 0, -10> direction z right x*2 up y*2 }}
sky_sphere {{ pigment {{ rgb 1 }} }}
sphere {{ 0, 1 texture {{ pigment {{ rgb 0.5 }} finish {{ ambient 0 diffuse 0 {finish} }} }} }}
"""
#: Pixels whose viewing angle is below this enter the statistics.
THETA_MAX = 80.0
#: Albedo nodes the per-pixel expectation interpolates (every degree).
GRID = np.linspace(0.0, 90.0, 91)


def table_path(step: float = 1.0) -> Path:
    return tables.tabulated(SPEC, step=step, fold=True)


def finish_text(kind: str, samples: int, step: float = 1.0) -> tuple[str, dict[str, Path]]:
    if kind == "table":
        return f'brdf_table {{ "t.brdf" samples {samples} }}', {"t.brdf": table_path(step)}
    return f'brdf_model {{ "{SPEC}" samples {samples} }}', {}


@lru_cache(maxsize=None)
def expectation(kind: str, step: float = 1.0) -> np.ndarray:
    """Albedo (green channel) at :data:`GRID`: numpy's integral of the table or of the model."""
    if kind == "table":
        f, _ = brdf_io.read_brdf(table_path(step), verify=False)
        return table_albedo(f, GRID)[:, 1]
    out = subprocess.run([str(brdftool()), "albedo", *SPEC.split(), "--glossy",
                          "--theta", ",".join(f"{t:.6f}" for t in GRID)],
                         capture_output=True, text=True, check=True).stdout
    rows = [[float(x) for x in line.split()] for line in out.splitlines() if not line.startswith("#")]
    return np.array(rows)[:, 2]


@dataclass
class Noise:
    kind: str
    samples: int
    rms: float     # per-pixel rms of (pixel - expected) / expected, theta_o < THETA_MAX
    mean: float    # their mean: the bias
    pixels: int
    trace_s: Optional[float]


def measure(kind: str, samples: int, size: int = 96, step: float = 1.0) -> Noise:
    finish, files = finish_text(kind, samples, step)
    res = runner.render(FURNACE.format(finish=finish), "fork", width=size, height=size, float_exr=True, files=files)
    s = surface_samples(SphereScene(width=size, height=size))
    theta = np.degrees(np.arccos(np.clip(-s.normal[s.mask][:, 2], 0.0, 1.0)))
    want = np.interp(theta, GRID, expectation(kind, step))
    got = res.image[s.mask][:, 1].astype(np.float64)
    inner = theta < THETA_MAX
    rel = (got[inner] - want[inner]) / want[inner]
    return Noise(kind, samples, float(np.sqrt(np.mean(rel ** 2))), float(np.mean(rel)), int(inner.sum()),
                 res.trace_seconds)


def format_table(rows: Sequence[Noise]) -> str:
    lines = [f"{'finish':<8} {'samples':>7} {'rms rel':>9} {'mean rel':>9} {'pixels':>7} {'trace s':>8}", "-" * 54]
    for r in rows:
        t = f"{r.trace_s:8.2f}" if r.trace_s is not None else "       -"
        lines.append(f"{r.kind:<8} {r.samples:>7d} {100 * r.rms:8.2f}% {100 * r.mean:+8.3f}% {r.pixels:>7d} {t}")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.glossy_noise", description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=96, help="image width and height (default 96)")
    ap.add_argument("--samples", default="16,64", help="comma-separated sample counts (default 16,64)")
    args = ap.parse_args(argv)
    counts = [int(x) for x in args.samples.split(",")]
    rows = [measure(kind, n, args.size) for n in counts for kind in ("model", "table")]
    print(f"white furnace, {SPEC} (1 deg folded table vs model), {args.size}x{args.size}, "
          f"pixels with theta_o < {THETA_MAX:g} deg")
    print(format_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
