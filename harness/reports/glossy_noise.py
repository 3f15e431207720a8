"""Glossy reflection (``samples N``) of a table against the same BRDF as a model: noise and bias.

Issue 16's white furnace: a unit sphere, orthographic camera, a uniform sky of radiance 1,
no lights, ambient 0, so every pixel's expected value is the directional albedo of the finish at
the pixel's viewing angle theta_o. The BRDF is Beckmann with height-correlated Smith masking and
F = 1 (``microfacet d=beckmann m=M``), in three forms:

* **model**: ``brdf_model``; expectation: the model's glossy albedo from ``brdftool albedo
  --glossy`` (the library's quadrature, which ``tests/test_analytic_finishes.py`` checks);
* **table**: the same BRDF as a 1 deg reciprocity-folded table (``brdf_table``), sampled from its
  own data (``TableSampler``); expectation: the table's albedo integrated in numpy from the file
  (:func:`harness.reference.table_albedo.table_albedo`);
* **halfdiff**: the same BRDF as a half/difference table (the default 256 x 128 x 32 nodes);
  expectation: its albedo integrated in numpy over the half vector
  (:func:`harness.reference.table_albedo.halfdiff_albedo`);
* **measured**: a simulated 1 deg measurement of it (2 % noise per value, 0.1 % of the cells
  missing and filled: :func:`measured_path`), expectation as the table's;
* **merl**: a synthetic MERL file of it with 2 % noise per bin, converted to a half/difference
  table on MERL's grid (:func:`merl_path`), expectation as the half/difference table's.

Noise is measured against the *local mean*, not the expectation: the per-pixel rms of
r / (mean of r over its 1 deg theta_o bin) - 1, r = pixel / expectation, over the pixels with
theta_o < 80 deg (the rim mixes a steep albedo slope into single pixels), so a small error in a
form's expectation does not count as its noise, nor does the albedo's shape inside a bin (a 1 deg
table of a narrow lobe changes its albedo between theta_o nodes). Bias is the mean of (pixel - expectation) / expectation per band of
cos theta_o (``BANDS``; the worst band is printed). Issue 32 measured, before the half-vector
sampler, at m = 0.1: model 0.77 % / 0.27 % at 16 / 64 samples, 1 deg table 1.64 % / 0.80 %,
half/difference 1.82 % / 0.88 %; the half/difference table +0.18...+0.22 % at cos theta_o 0.15-0.3.

The *floor* column (noisy forms): a table whose channels carry independent measurement noise
has channels of different shapes, and one ray serves all three, so some spread stays whatever
the sampler: :func:`harness.reference.table_albedo.channel_floor` gives the least per-sample
spread of the green channel over every density (0.86-0.92 % per sample for 2 % noise, at any
roughness), printed per pixel for independent rays (over sqrt(samples)). The stratified rays go
below it only where a stratum holds few table cells (the 1 deg measurement of a narrow lobe);
a MERL table's narrow lobe covers hundreds of its bins, so at m = 0.02 its floor (0.22 % / 0.11 %
at 16 / 64 rays) is above the model's own noise (0.17 % / 0.06 %) and no sampler of that table
can match the model there.

    python -m harness.reports.glossy_noise [--size 96] [--samples 16,64] [--m 0.02,0.05,0.1,0.3,0.5]
    python -m harness.reports.glossy_noise --bias [--size 128] [--samples 256]

Numbers are printed, never asserted (``tests/test_table_sampling.py`` asserts a small version).
"""

from __future__ import annotations

import argparse
import os
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
from harness.reference.table_albedo import channel_floor, halfdiff_albedo, table_albedo

SPEC = "microfacet d=beckmann m=0.3"
FURNACE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 max_trace_level 5 ambient_light 0 }}
camera {{ orthographic location <0, 0, -10> direction z right x*2 up y*2 }}
sky_sphere {{ pigment {{ rgb 1 }} }}
sphere {{ 0, 1 texture {{ pigment {{ rgb 0.5 }} finish {{ ambient 0 diffuse 0 {finish} }} }} }}
"""
#: Pixels whose viewing angle is below this enter the noise statistics.
THETA_MAX = 80.0
#: Albedo nodes the per-pixel expectation interpolates (every half degree).
GRID = np.linspace(0.0, 90.0, 181)
#: Bands of cos(theta_o) for the bias (issue 32: within 0.1 % in every band, both layouts).
BANDS = (0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
#: Roughness values of the report (issue 32's list).
ROUGHNESS = (0.02, 0.05, 0.1, 0.3, 0.5)
KINDS = ("model", "table", "halfdiff", "measured", "merl")
#: Relative measurement noise of the "measured" and "merl" forms (per value, Gaussian).
MEASUREMENT_NOISE = 0.02


def spec_for(m: float) -> str:
    return f"microfacet d=beckmann m={m:g}"


def table_path(step: float = 1.0, spec: str = SPEC) -> Path:
    return tables.tabulated(spec, step=step, fold=True)


def merl_path(spec: str) -> Path:
    """The BRDF of ``spec`` (Beckmann m, F = 1) as a MERL measurement with its noise: a synthetic
    ``.binary`` (:mod:`harness.tools.merl_synth`, Schlick f0 = 1 so F = 1, no Lambertian part)
    with every bin times (1 + MEASUREMENT_NOISE N(0, 1)), seed 1, converted by ``brdftool convert``
    to a half/difference table on MERL's own 90 x 90 x 180 grid."""
    from harness.tools import merl_synth

    m = float(spec.split("m=")[1].split()[0])
    out = tables.CACHE_DIR / f"merl-m{m:g}-n{MEASUREMENT_NOISE:g}.brdf"
    if out.is_file():
        return out
    f = merl_synth.synthetic_brdf([0.0, 0.0, 0.0], 1.0, m, 1.0)
    rng = np.random.default_rng(1)
    f = f * np.maximum(0.0, 1.0 + MEASUREMENT_NOISE * rng.standard_normal(f.shape))
    binary = out.with_suffix(f".binary.tmp{os.getpid()}")
    tmp = out.with_suffix(f".tmp{os.getpid()}")
    try:
        merl_synth.write_merl(binary, f)
        subprocess.run([str(brdftool()), "convert", str(binary), "-o", str(tmp), "--layout", "halfdiff"],
                       capture_output=True, text=True, check=True)
        tmp.replace(out)
    finally:
        binary.unlink(missing_ok=True)
        tmp.unlink(missing_ok=True)
    return out


def measured_path(spec: str) -> Path:
    """``spec`` as a simulated 1 deg gonioreflectometer measurement (MEASUREMENT_NOISE per value,
    0.1 % of the cells missing and filled)."""
    return tables.measured_like(spec, step=1.0, noise=MEASUREMENT_NOISE, missing=0.001)


def finish_text(kind: str, samples: int, step: float = 1.0, spec: str = SPEC) -> tuple[str, dict[str, Path]]:
    files = {"table": lambda: table_path(step, spec), "halfdiff": lambda: tables.tabulated_halfdiff(spec),
             "measured": lambda: measured_path(spec), "merl": lambda: merl_path(spec)}
    if kind in files:
        return f'brdf_table {{ "t.brdf" samples {samples} }}', {"t.brdf": files[kind]()}
    return f'brdf_model {{ "{spec}" samples {samples} }}', {}


@lru_cache(maxsize=None)
def expectation(kind: str, step: float = 1.0, spec: str = SPEC) -> np.ndarray:
    """Albedo (green channel) at :data:`GRID`: numpy's integral of the table or of the model."""
    if kind == "table":
        f, _ = brdf_io.read_brdf(table_path(step, spec), verify=False)
        return table_albedo(f, GRID)[:, 1]
    if kind == "measured":
        f, _ = brdf_io.read_brdf(measured_path(spec), verify=False)
        return table_albedo(f, GRID)[:, 1]
    if kind in ("halfdiff", "merl"):
        f, _ = brdf_io.read_brdf(tables.tabulated_halfdiff(spec) if kind == "halfdiff" else merl_path(spec), verify=False)
        return halfdiff_albedo(f, GRID)[:, 1]
    out = subprocess.run([str(brdftool()), "albedo", *spec.split(), "--glossy",
                          "--theta", ",".join(f"{t:.6f}" for t in GRID)],
                         capture_output=True, text=True, check=True).stdout
    rows = [[float(x) for x in line.split()] for line in out.splitlines() if not line.startswith("#")]
    return np.array(rows)[:, 2]


#: Viewing angles (deg) at which :func:`floor` evaluates the channels' floor (their mean is used).
FLOOR_THETA = (20.0, 50.0)
#: Forms whose channels carry independent noise (the others have one shape: floor 0).
NOISY = ("measured", "merl")


@lru_cache(maxsize=None)
def floor_per_sample(kind: str, spec: str = SPEC) -> float:
    """The green channel's per-sample spread that the best sampler drawing one direction for all
    channels leaves (:func:`harness.reference.table_albedo.channel_floor`), mean over
    :data:`FLOOR_THETA`: the measurement noise that differs between the channels, which no such
    sampler removes. 0 for forms whose channels share one shape."""
    if kind not in NOISY:
        return 0.0
    path = measured_path(spec) if kind == "measured" else merl_path(spec)
    f, _ = brdf_io.read_brdf(path, verify=False)
    return float(channel_floor(f, np.array(FLOOR_THETA), halfdiff=kind == "merl")[:, 1].mean())


def floor(kind: str, samples: int, spec: str = SPEC) -> float:
    """:func:`floor_per_sample` for a pixel of ``samples`` independent rays (over sqrt(samples));
    stratified rays fall below it only where a stratum holds few of the table's cells."""
    return floor_per_sample(kind, spec) / np.sqrt(samples)


@dataclass
class Noise:
    kind: str
    samples: int
    rms: float     # per-pixel rms of (pixel - local mean) / local mean, theta_o < THETA_MAX
    mean: float    # mean of (pixel - expected) / expected over the same pixels: the bias
    pixels: int
    trace_s: Optional[float]
    spec: str = SPEC
    band_bias: tuple[float, ...] = ()  # mean relative error per BANDS interval (NaN: no pixel)

    @property
    def worst_band(self) -> float:
        b = [x for x in self.band_bias if np.isfinite(x)]
        return max(b, key=abs) if b else float("nan")


def measure(kind: str, samples: int, size: int = 96, step: float = 1.0, spec: str = SPEC) -> Noise:
    finish, files = finish_text(kind, samples, step, spec)
    res = runner.render(FURNACE.format(finish=finish), "fork", width=size, height=size, float_exr=True, files=files)
    s = surface_samples(SphereScene(width=size, height=size))
    cos_o = np.clip(-s.normal[s.mask][:, 2], 0.0, 1.0)
    theta = np.degrees(np.arccos(cos_o))
    want = np.interp(theta, GRID, expectation(kind, step, spec))
    got = res.image[s.mask][:, 1].astype(np.float64)
    inner = theta < THETA_MAX
    rel = (got - want) / want
    # The local mean: of pixel / expectation in every pixel's 1 deg bin of theta_o (the ratio
    # takes out the albedo's shape inside a bin, the bin's mean any error of the expectation).
    bins = np.floor(theta[inner]).astype(int)
    ratio = got[inner] / want[inner]
    local = np.bincount(bins, weights=ratio, minlength=91)[bins] / np.bincount(bins, minlength=91)[bins]
    noise = ratio / local - 1.0
    band_bias = []
    for lo, hi in zip(BANDS[:-1], BANDS[1:]):
        sel = (cos_o >= lo) & (cos_o < hi)
        band_bias.append(float(np.mean(rel[sel])) if sel.any() else float("nan"))
    return Noise(kind, samples, float(np.sqrt(np.mean(noise ** 2))), float(np.mean(rel[inner])),
                 int(inner.sum()), res.trace_seconds, spec, tuple(band_bias))


def format_table(rows: Sequence[Noise]) -> str:
    lines = [f"{'finish':<9} {'m':>5} {'samples':>7} {'rms rel':>9} {'/ model':>8} {'floor':>7} {'mean rel':>9} "
             f"{'worst band':>10} {'pixels':>7} {'trace s':>8}", "-" * 92]
    model = {(r.spec, r.samples): r.rms for r in rows if r.kind == "model"}
    for r in rows:
        t = f"{r.trace_s:8.2f}" if r.trace_s is not None else "       -"
        ratio = model.get((r.spec, r.samples))
        rt = f"{r.rms / ratio:8.2f}" if ratio else "       -"
        m = r.spec.split("m=")[-1].split()[0] if "m=" in r.spec else "-"
        wb = f"{100 * r.worst_band:+9.3f}%" if r.band_bias else "         -"
        fl = f"{100 * floor(r.kind, r.samples, r.spec):6.2f}%" if r.kind in NOISY else "      -"
        lines.append(f"{r.kind:<9} {m:>5} {r.samples:>7d} {100 * r.rms:8.2f}% {rt} {fl} {100 * r.mean:+8.3f}% {wb} "
                     f"{r.pixels:>7d} {t}")
    lines.append("floor: the least rms that rays shared by the three channels can have where the channels' "
                 "noise differs (independent rays; table_albedo.channel_floor)")
    return "\n".join(lines)


def format_bands(rows: Sequence[Noise]) -> str:
    head = " ".join(f"{lo:.2f}-{hi:.2f}".rjust(9) for lo, hi in zip(BANDS[:-1], BANDS[1:]))
    lines = [f"{'finish':<9} {'m':>5} {'spp':>5}  bias per band of cos theta_o, %", f"{'':<21} {head}"]
    for r in rows:
        m = r.spec.split("m=")[-1].split()[0]
        vals = " ".join(f"{100 * b:+9.3f}" for b in r.band_bias)
        lines.append(f"{r.kind:<9} {m:>5} {r.samples:>5} {vals}")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.glossy_noise", description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=None, help="image width and height (default 96; 128 with --bias)")
    ap.add_argument("--samples", default=None, help="comma-separated sample counts (default 16,64; 256 with --bias)")
    ap.add_argument("--m", default=",".join(f"{m:g}" for m in ROUGHNESS), help="comma-separated Beckmann roughness")
    ap.add_argument("--kinds", default=",".join(KINDS), help="model, table, halfdiff (comma-separated)")
    ap.add_argument("--bias", action="store_true", help="print the bias per band of cos theta_o (tables only)")
    args = ap.parse_args(argv)
    size = args.size or (128 if args.bias else 96)
    counts = [int(x) for x in (args.samples or ("256" if args.bias else "16,64")).split(",")]
    kinds = [k for k in args.kinds.split(",") if k]
    if args.bias:
        kinds = [k for k in kinds if k != "model"]
    rows = [measure(kind, n, size, spec=spec_for(float(m)))
            for m in args.m.split(",") for n in counts for kind in kinds]
    print(f"white furnace, Beckmann + Smith, F = 1: model, 1 deg folded table, half/difference table "
          f"(256 x 128 x 32), 1 deg measurement and MERL file with {100 * MEASUREMENT_NOISE:g} % noise; "
          f"{size}x{size}, noise against the local mean over pixels with theta_o < {THETA_MAX:g} deg")
    print(format_bands(rows) if args.bias else format_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
