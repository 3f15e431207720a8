"""Stability suite: the hard cases of every finish, rendered by the fork.

Each case renders a small scene with the fork and returns one :class:`CaseResult`: NaN, Inf
and negative sample counts over the whole image (all must be 0), and where the case has a
limit, its error against that limit. The cases:

* **grazing light**: a sphere lit from 89.9 deg off the view (the terminator pixels see the
  light at grazing incidence), and a flat sample lit at theta_i = 89.9 deg, against the
  models re-derived in numpy (:mod:`harness.reference.models`);
* **grazing view**: the rim pixels of a sphere (cos theta_o < 0.15, where Ward's 1/sqrt(cos)
  and the microfacet 1/(4 cos cos) blow up) and a flat sample seen at theta_r = 89.9 deg;
* **roughness -> 1e-4**: microfacet m = 0.0001: on a sphere no pixel sees the mirror
  direction (Beckmann: the Lambertian base alone; GGX keeps its long tail), a flat sample
  at the exact mirror geometry (D ~ 3e7) and 1 deg off it (base only), against numpy;
* **eta -> 1**: a dielectric with eta = 1.0001 (F ~ 2.5e-9) against its base alone;
* **albedo -> 1**: a white furnace (uniform sky, ``samples 64``) of a microfacet with
  kd + rho_s = 1 against the glossy albedo of the library's quadrature (``brdftool albedo
  --glossy``), and the dipole with sigma_a = 0 (alpha' = 1, Rd = 1, a power-law tail) on the
  half-lit slab, against the closed-form exitance of the finite lit rectangle;
* **r -> 0**: the dipole slab of ``tests/test_dipole_finish.py`` framed so that every pixel
  centre lies exactly on a surface sample (80 x 10 pixels, spacing 0.25 mm);
* **tables**: an all-zero table renders black; a truncated file, a flipped payload byte and
  an empty file are parse errors that name the file.

Errors are normalised so one limit reads the same on every scene: ``max |a - b| / peak``
(peak = max of the reference over the pixels compared), per-sample relative errors for flat
samples (every pixel sees one direction pair), errors relative to the lit level for the
slab profiles (edge pixels excluded, as in ``tests/test_dipole_finish.py``).

    python -m harness.reports.stability          # every case, a markdown table on stdout
    python -m harness.reports.stability -k dipole

``tests/test_stability.py`` asserts each row; ``harness.reports.report`` shows the same table.
"""

from __future__ import annotations

import argparse
import itertools
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional, Sequence

import numpy as np

from harness.core import brdf_io, runner, tables
from harness.reference import dipole_ref
from harness.core.compare import max_rel_error, nonfinite_counts
from harness.reference.expect import expected_image, surface_samples
from harness.core.paths import brdftool
from harness.core.scenes import DistantLight, FlatSampleScene, SphereScene


@dataclass
class CaseResult:
    """One row of the stability table. ``error``/``limit`` are None where the case has none."""

    case: str
    metric: str
    error: Optional[float]
    limit: Optional[float]
    n_nan: Optional[int]
    n_inf: Optional[int]
    n_negative: Optional[int]
    ok: bool
    note: str = ""
    seconds: float = 0.0

    def row(self) -> dict:
        """A dict for reports (``None`` shown as an en dash)."""
        dash = "–"
        return {"case": self.case, "metric": self.metric,
                "error": dash if self.error is None else self.error,
                "limit": dash if self.limit is None else self.limit,
                "NaN": dash if self.n_nan is None else self.n_nan,
                "Inf": dash if self.n_inf is None else self.n_inf,
                "negative": dash if self.n_negative is None else self.n_negative,
                "ok": self.ok, "note": self.note}


@dataclass
class _Acc:
    """Accumulates NaN/Inf/negative counts and the worst error over the renders of a case."""

    n_nan: int = 0
    n_inf: int = 0
    n_negative: int = 0
    error: float = 0.0
    notes: list[str] = field(default_factory=list)

    def image(self, img: np.ndarray) -> np.ndarray:
        c = nonfinite_counts(img)
        self.n_nan += c["n_nan"]
        self.n_inf += c["n_inf"]
        self.n_negative += c["n_negative"]
        return img

    def err(self, e: float, note: str = "") -> None:
        self.error = max(self.error, float(e)) if math.isfinite(e) else float("inf")
        if note:
            self.notes.append(note)

    def result(self, case: str, metric: str, limit: Optional[float], extra_ok: bool = True,
               note: str = "") -> CaseResult:
        clean = self.n_nan == 0 and self.n_inf == 0 and self.n_negative == 0
        ok = clean and extra_ok and (limit is None or self.error <= limit)
        return CaseResult(case, metric, self.error, limit, self.n_nan, self.n_inf, self.n_negative,
                          ok, note or "; ".join(self.notes))


def _fork(scene, **kw) -> np.ndarray:
    return runner.render(scene, "fork", float_exr=True, **kw).image


def _fork_all(scenes: Sequence) -> list[np.ndarray]:
    """Render scenes with the fork, two at a time (float EXR), images in order."""
    res = runner.render_many(list(scenes), binary="fork", float_exr=True, max_workers=2, progress=False)
    return [r.image for r in res]


def _peak_error(img: np.ndarray, want: np.ndarray, mask: np.ndarray) -> float:
    """``max |img - want| / max |want|`` over the masked pixels."""
    d = np.abs(img.astype(np.float64) - want)[mask]
    peak = float(np.abs(want[mask]).max())
    return float(d.max() / peak) if peak > 0 else float(d.max())


def _flat_rel_error(img: np.ndarray, scene: FlatSampleScene) -> float:
    """Largest per-sample relative error of a flat-sample render against numpy."""
    want = expected_image(scene)
    return max_rel_error(img, want, surface_samples(scene).mask, rel_floor=1e-30)


CONDUCTOR = "f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8"
#: Models whose grazing behaviour differs most: the Beckmann Smith Lambda (erfc), the V-cavity
#: min(), Ward 1992's 1/sqrt(cos cos), POV's specular divided by cos_i, Oren-Nayar's
#: tan(beta), Lafortune's cosine lobes. (Blinn/Gaussian Smith need 8 s of numpy tables.)
GRAZING_SPECS = (
    f"microfacet d=beckmann m=0.25 g=smith {CONDUCTOR}",
    "microfacet d=tr m=0.15 g=vcavity f=dielectric eta=1.5 kd=0.6 rho_s=0.4",
    "ward variant=original rho_d=0.3 rho_s=0.2 ax=0.1 ay=0.3",
    "blinn_pov specular=0.6 roughness=0.05 diffuse=0.2",
    "oren_nayar rho=0.6 sigma=0.5",
    "lafortune kd=0.2 lobe=-1,-1,1,20,0.5 lobe=0.9,0.9,0.8,5,0.2",
)
#: Float32 pixels against float64 numpy: measured max |d|/peak <= 1e-7 on spheres and rims;
#: a float ulp of a direction (6e-8) over the smallest rim cosine (0.07) allows ~1e-6.
MODEL_LIMIT = 1.0e-5
#: At 89.9 deg the cosine is 1.7e-3: float32 rounding of a direction (6e-8 / 1.7e-3 = 3.5e-5)
#: may move a value that much relative; measured 4e-8.
GRAZING_FLAT_LIMIT = 5.0e-5


def _model_finish(spec: str) -> dict:
    return {"brdf_model": {"spec": spec, "direction": (0.3, 1.0, 0.2)}}


def case_grazing_light_sphere() -> CaseResult:
    acc = _Acc()
    scenes = [SphereScene(lights=(DistantLight(89.9, 30.0),), finish=_model_finish(spec), width=64, height=64)
              for spec in GRAZING_SPECS]
    for s, img in zip(scenes, _fork_all(scenes)):
        acc.err(_peak_error(acc.image(img), expected_image(s), surface_samples(s).mask))
    return acc.result("grazing light: sphere, light 89.9° from the view (6 models)", "max |Δ| / peak vs numpy",
                      MODEL_LIMIT)


def case_grazing_light_flat() -> CaseResult:
    acc = _Acc()
    scenes = [FlatSampleScene(theta_i_deg=89.9, theta_r_deg=tr, phi_deg=phi, finish=_model_finish(spec),
                              width=2, height=2)
              for spec, (tr, phi) in zip(GRAZING_SPECS, itertools.cycle(((30.0, 180.0), (75.0, 60.0))))]
    for s, img in zip(scenes, _fork_all(scenes)):
        acc.err(_flat_rel_error(acc.image(img), s))
    return acc.result("grazing light: flat sample, θi = 89.9° (6 models)", "max rel. error vs numpy",
                      GRAZING_FLAT_LIMIT)


def case_grazing_view_rim() -> CaseResult:
    acc = _Acc()
    lights = (DistantLight(0.0, 0.0, (0.4,) * 3), DistantLight(45.0, 30.0, (0.3,) * 3),
              DistantLight(80.0, 150.0, (0.5,) * 3))
    n_rim, cos_min = 0, 1.0
    scenes = [SphereScene(lights=lights, finish=_model_finish(spec), width=80, height=80) for spec in GRAZING_SPECS]
    for s, img in zip(scenes, _fork_all(scenes)):
        acc.image(img)
        ss = surface_samples(s)
        rim = ss.mask & (-ss.normal[..., 2] < 0.15)
        n_rim = int(rim.sum())
        cos_min = float((-ss.normal[..., 2])[rim].min())
        acc.err(_peak_error(img, expected_image(s), rim))
    return acc.result("grazing view: sphere rim pixels, cos θo < 0.15 (6 models)", "max |Δ| / rim peak vs numpy",
                      MODEL_LIMIT, note=f"{n_rim} rim pixels per model, cos θo down to {cos_min:.3f}")


def case_grazing_view_flat() -> CaseResult:
    acc = _Acc()
    scenes = [FlatSampleScene(theta_i_deg=ti, theta_r_deg=89.9, phi_deg=phi, finish=_model_finish(spec),
                              width=2, height=2)
              for spec, (ti, phi) in zip(GRAZING_SPECS, itertools.cycle(((30.0, 180.0), (89.9, 120.0))))]
    for s, img in zip(scenes, _fork_all(scenes)):
        acc.err(_flat_rel_error(acc.image(img), s))
    return acc.result("grazing view: flat sample, θr = 89.9° (6 models)", "max rel. error vs numpy",
                      GRAZING_FLAT_LIMIT)


SHARP = "microfacet d={d} m=0.0001 f=dielectric eta=1.5 kd=0.5 rho_s=0.5"


def case_sharp_sphere() -> CaseResult:
    acc = _Acc()
    lights = (DistantLight(0.0), DistantLight(45.0, 30.0))
    kinds = ("beckmann", "tr")
    scenes = [SphereScene(lights=lights, finish=_model_finish(SHARP.format(d=d)), width=64, height=64) for d in kinds]
    for d, s, img in zip(kinds, scenes, _fork_all(scenes)):
        acc.image(img)
        mask = surface_samples(s).mask
        acc.err(_peak_error(img, expected_image(s), mask))
        if d == "beckmann":  # no pixel within ~1e-3 rad of the mirror direction: the base alone
            base = SphereScene(lights=lights, finish=_model_finish("lambert rho=0.5"), width=64, height=64)
            acc.err(_peak_error(img, expected_image(base), mask))
    return acc.result("roughness → 1e-4: sphere (Beckmann = base alone, GGX tail)", "max |Δ| / peak vs numpy",
                      MODEL_LIMIT)


def case_sharp_mirror() -> CaseResult:
    acc = _Acc()
    notes = []
    geo = [(d, ti, tr) for d in ("beckmann", "tr") for ti, tr in ((45.0, 45.0), (20.0, 20.0), (45.0, 46.0))]
    scenes = [FlatSampleScene(theta_i_deg=ti, theta_r_deg=tr, phi_deg=180.0,
                              finish=_model_finish(SHARP.format(d=d)), width=2, height=2) for d, ti, tr in geo]
    for (d, ti, tr), s, img in zip(geo, scenes, _fork_all(scenes)):
        acc.err(_flat_rel_error(acc.image(img), s))
        if d == "beckmann" and ti == tr == 45.0:
            notes.append(f"mirror pixel {float(img[0, 0, 0]):.3g} (base alone {0.5 * math.cos(math.radians(45)):.3g})")
    return acc.result("roughness → 1e-4: flat sample at the mirror geometry and 1° off", "max rel. error vs numpy",
                      1.0e-4, note="; ".join(notes))


def case_eta_one() -> CaseResult:
    acc = _Acc()
    lights = (DistantLight(0.0), DistantLight(45.0, 30.0), DistantLight(80.0, 150.0))
    spec = "microfacet d=beckmann m=0.2 f=dielectric eta=1.0001 kd=0.5 rho_s=0.5"
    s = SphereScene(lights=lights, finish=_model_finish(spec), width=64, height=64)
    img = acc.image(_fork(s))
    mask = surface_samples(s).mask
    base = SphereScene(lights=lights, finish=_model_finish("lambert rho=0.5"), width=64, height=64)
    acc.err(_peak_error(img, expected_image(base), mask))
    full = _peak_error(img, expected_image(s), mask)
    return acc.result("eta → 1: dielectric eta = 1.0001 vs its base kd alone", "max |Δ| / peak vs kd only",
                      1.0e-6, extra_ok=full <= MODEL_LIMIT, note=f"vs the full model in numpy: {full:.1e}")


# ---------------------------------------------------------------- white furnace

FURNACE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 max_trace_level 5 ambient_light 0 }}
camera {{ orthographic location <0, 0, -10> direction z right x*2 up y*2 }}
sky_sphere {{ pigment {{ rgb 1 }} }}
sphere {{ 0, 1 texture {{ pigment {{ rgb 0.5 }} finish {{ ambient 0 diffuse 0
  brdf_model {{ "{spec}" samples {samples} }} }} }} }}
"""


def glossy_albedo(spec: str, thetas: np.ndarray) -> np.ndarray:
    """Glossy part of the directional albedo (RGB per theta) from ``brdftool albedo --glossy``."""
    out = subprocess.run([str(brdftool()), "albedo", *spec.split(), "--glossy",
                          "--theta", ",".join(f"{t:.6f}" for t in thetas)],
                         capture_output=True, text=True, check=True).stdout
    rows = np.array([[float(x) for x in line.split()] for line in out.splitlines() if not line.startswith("#")])
    return rows[:, 1:]


def case_furnace() -> CaseResult:
    acc = _Acc()
    kd, spec, size, samples = 0.5, "microfacet d=beckmann m=0.2 kd=0.5 rho_s=0.5", 40, 64
    img = acc.image(runner.render(FURNACE.format(spec=spec, samples=samples), "fork", width=size, height=size,
                                  float_exr=True).image)
    s = surface_samples(SphereScene(width=size, height=size))
    theta = np.degrees(np.arccos(np.clip(-s.normal[s.mask][:, 2], 0.0, 1.0)))
    grid = np.linspace(0.0, 90.0, 91)
    a = glossy_albedo(spec, grid)
    want = np.stack([np.interp(theta, grid, a[:, c]) for c in range(3)], -1)
    got = img[s.mask].astype(np.float64)
    inner = theta < 80.0
    rel = (got - want) / want
    acc.err(abs(float(rel[inner].mean())))
    top = float(got.max()) + kd
    return acc.result("albedo → 1: white furnace, kd + rho_s = 1 (samples 64)",
                      "|mean rel. error| vs glossy albedo, θ < 80°", 5e-3, extra_ok=top <= 1.0 + 0.1,
                      note=f"rms rel {np.sqrt((rel[inner] ** 2).mean()):.1e}; max pixel + kd = {top:.3f}")


# ---------------------------------------------------------------- dipole slab

SLAB = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 0, 20> direction <0, 0, -1> right <20, 0, 0> up <0, {up}, 0> }}
light_source {{ <0, 0, 1000> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-25, -25, -15>, <25, 25, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ sigma_s_prime {ssp} sigma_a {sa} ior {eta}
    mm_per_unit 1 sample_spacing 0.25 profile dipole single_scatter on {thin} }} }} }} }}
box {{ <-100, -100, 5>, <0, 100, 5.01> no_image texture {{ pigment {{ rgb 0 }} }} }}
"""
SLAB_HALF = 25.0  # the slab's lit rectangle is x in [0, 25], y in [-25, 25] (mm)


def rectangle_exitance(ch: dipole_ref.Dipole, x: np.ndarray, half: float = SLAB_HALF) -> np.ndarray:
    """Exitance at (x, 0) of a surface lit (unit transmitted irradiance) on the rectangle
    [0, half] x [-half, half] only: the strip 0 <= x' <= half (two half-planes) minus its two
    corners |y'| > half (integrated numerically; r >= half there, so Rd is smooth)."""
    x = np.asarray(x, dtype=float)
    strip = dipole_ref.half_plane_exitance(ch, x) - dipole_ref.half_plane_exitance(ch, x - half)
    nx, nu = 500, 400
    xp = (np.arange(nx) + 0.5) / nx * half
    u = (np.arange(nu) + 0.5) / nu
    yp = half / u  # y' = half / u maps (0, 1] onto [half, inf)
    wy = half / u ** 2 / nu
    corners = np.empty_like(x)
    for k, xk in enumerate(x):
        r = np.hypot((xk - xp)[:, None], yp[None, :])
        corners[k] = 2.0 * float((ch.rd(r) * wy[None, :]).sum()) * half / nx
    return strip - corners


def slab_profile(ssp: float, sa: float, eta: float, width: int, finite: bool) -> tuple[np.ndarray, np.ndarray]:
    """(x, expected pixel) across the shadow edge: Ft(1)^2 M(x) + single scattering on the lit side."""
    x = ((np.arange(width) + 0.5) / width - 0.5) * 20.0
    ch = dipole_ref.Dipole(ssp, sa, eta)
    ft = 1.0 - dipole_ref.fresnel_dielectric(1.0, eta)
    up = np.array([[0.0, 0.0, 1.0]])
    ss = math.pi * dipole_ref.single_scatter_brdf(up, up, ssp / (ssp + sa), 0.0, eta)[0]
    m = rectangle_exitance(ch, x) if finite else dipole_ref.half_plane_exitance(ch, x)
    return x, ft * ft * m + np.where(x > 0, ss, 0.0)


def _slab_case(acc: _Acc, ssp: float, sa: float, eta: float, width: int, height: int, finite: bool,
               thin: str = ""):
    up = 20.0 * height / width  # square pixels
    img = acc.image(runner.render(SLAB.format(up=up, ssp=ssp, sa=sa, eta=eta, thin=thin), "fork", width=width,
                                  height=height, float_exr=True).image)
    x, want = slab_profile(ssp, sa, eta, width, finite)
    prof = img[..., 0].astype(np.float64).mean(axis=0)
    err = (prof - want) / want[-1]
    keep = np.abs(x) >= 0.5  # the near-field radius R0 = 2h around the edge (as the dipole test)
    return img, x, want, err, keep


def case_dipole_sigma_a_zero() -> CaseResult:
    acc = _Acc()
    # Without absorption a 15 mm slab is thin (its slab threshold is far beyond: T falls only as
    # 1/d) and rightly transmits ~10 %; the reference is the half-space, so the half-space dipole
    # is what this case checks (thin geometry: tests/test_dipole_thin.py).
    _, _, want, err, keep = _slab_case(acc, 1.0, 0.0, 1.3, 160, 20, finite=True, thin="thin_geometry off")
    acc.err(float(np.abs(err[keep]).max()))
    rms = float(np.sqrt(np.mean(err[keep] ** 2)))
    return acc.result("albedo → 1: dipole sigma_a = 0 (half-lit slab, finite lit rectangle)",
                      "max |Δ| / lit level, |x| ≥ 0.5 mm", 5e-3,
                      note=f"rms {rms:.1e}; lit level {want[-1]:.3f}; at the edge {np.abs(err[~keep]).max():.1e}")


def case_dipole_on_sample() -> CaseResult:
    acc = _Acc()
    # 80 x 10 pixels over 20 x 2.5 mm: pixel centres at x, y = 0.125 mod 0.25, exactly where the
    # z lines (lo + (i + 0.5) h, lo = -25, h = 0.25) meet the top face: r = 0 for every pixel.
    _, _, want, err, keep = _slab_case(acc, 1.0, 0.05, 1.3, 80, 10, finite=False)
    acc.err(float(np.abs(err[keep]).max()))
    rms = float(np.sqrt(np.mean(err[keep] ** 2)))
    return acc.result("r → 0: dipole, every pixel exactly on a surface sample (slab 80 × 10)",
                      "max |Δ| / lit level, |x| ≥ 0.5 mm", 5e-3,
                      note=f"rms {rms:.1e}; at the edge {np.abs(err[~keep]).max():.1e}")


# ---------------------------------------------------------------- tables

TABLE_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0,0,-10> direction z right 2*x up 2*y }}
light_source {{ <0,0,-1000> rgb 1 parallel point_at 0 }}
light_source {{ <700,0,-700> rgb 1 parallel point_at 0 }}
sphere {{ 0, 1 pigment {{ rgb 1 }}
  finish {{ ambient 0 brdf_table {{ "{name}" }} }} }}
"""
TABLE_LINE = 7  # the line of brdf_table in TABLE_SCENE


def case_zero_table() -> CaseResult:
    acc = _Acc()
    with tempfile.TemporaryDirectory(prefix="stab-") as d:
        path = brdf_io.write_brdf(Path(d) / "zero.brdf", np.zeros((19, 19, 37, 3)), "all zero")
        r = runner.render(TABLE_SCENE.format(name="zero.brdf"), "fork", width=32, height=32, float_exr=True,
                          files={"zero.brdf": path})
    acc.image(r.image)
    acc.err(float(np.abs(r.image).max()))
    loaded = "BRDF tables:" in r.stderr
    return acc.result("empty table: every value 0 (5° grid) renders black", "max |pixel|", 0.0,
                      extra_ok=loaded, note="table loaded" if loaded else "no 'BRDF tables:' statistics")


def _broken(name: str, data: bytes) -> tuple[bool, str]:
    """Render a scene naming a broken table: (clean error naming the file at the line, message)."""
    with tempfile.TemporaryDirectory(prefix="stab-") as d:
        p = Path(d) / name
        p.write_bytes(data)
        try:
            runner.render(TABLE_SCENE.format(name=name), "fork", width=8, height=8, files={name: p})
        except runner.RenderError as e:
            clean = (e.line == TABLE_LINE and name in e.message and e.returncode is not None
                     and 0 < e.returncode < 128)
            return clean, e.message.replace("Parse Error: ", "")
    return False, "rendered without an error"


def _broken_case(label: str, name: str, make: Callable[[bytes], bytes]) -> CaseResult:
    good = tables.tabulated("lambert rho=0.5", step=5.0).read_bytes()
    clean, msg = _broken(name, make(good))
    return CaseResult(label, "parse error at the line, naming the file", None, None, None, None, None, clean, msg)


def case_truncated_table() -> CaseResult:
    return _broken_case("broken table: truncated after 5000 bytes", "short.brdf", lambda b: b[:5000])


def case_checksum_table() -> CaseResult:
    def flip(b: bytes) -> bytes:
        off = len(b) - 100
        return b[:off] + bytes([b[off] ^ 1]) + b[off + 1:]
    return _broken_case("broken table: one payload bit flipped", "flip.brdf", flip)


def case_empty_file() -> CaseResult:
    return _broken_case("broken table: empty file (0 bytes)", "nil.brdf", lambda b: b"")


CASES: dict[str, Callable[[], CaseResult]] = {
    "grazing_light_sphere": case_grazing_light_sphere,
    "grazing_light_flat": case_grazing_light_flat,
    "grazing_view_rim": case_grazing_view_rim,
    "grazing_view_flat": case_grazing_view_flat,
    "roughness_sphere": case_sharp_sphere,
    "roughness_mirror": case_sharp_mirror,
    "eta_one": case_eta_one,
    "furnace_albedo_one": case_furnace,
    "dipole_sigma_a_zero": case_dipole_sigma_a_zero,
    "dipole_r_zero": case_dipole_on_sample,
    "table_all_zero": case_zero_table,
    "table_truncated": case_truncated_table,
    "table_bit_flip": case_checksum_table,
    "table_empty_file": case_empty_file,
}


def run_case(key: str) -> CaseResult:
    """Run one case of :data:`CASES` and time it."""
    t0 = time.perf_counter()
    r = CASES[key]()
    r.seconds = time.perf_counter() - t0
    return r


def run(keys: Optional[Sequence[str]] = None, log: Optional[Callable[[str], None]] = None,
        progress: bool = False) -> list[CaseResult]:
    """Every case (or ``keys``), in order: the single source of the stability numbers
    (``progress``: a bar of the cases on stderr)."""
    from harness.core.progress import bar

    out = []
    keys = list(keys or CASES)
    with bar(len(keys), "stability", unit="case", enabled=progress) as b:
        for k in keys:
            r = run_case(k)
            if log:
                log(f"{k}: {'ok' if r.ok else 'FAIL'} ({r.seconds:.1f} s)")
            out.append(r)
            b.update(1)
    return out


def _num(v: Optional[float]) -> str:
    return "–" if v is None else ("0" if v == 0 else f"{v:.1e}")


def markdown(results: Sequence[CaseResult]) -> str:
    """The stability table: case, metric, error vs limit, NaN/Inf/negative counts, verdict."""
    lines = ["| case | metric | error | limit | NaN | Inf | neg | ok | note |", "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        cnt = ["–" if v is None else str(v) for v in (r.n_nan, r.n_inf, r.n_negative)]
        lines.append(f"| {r.case} | {r.metric} | {_num(r.error)} | {_num(r.limit)} | {' | '.join(cnt)} | "
                     f"{'ok' if r.ok else 'FAIL'} | {r.note} |")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.stability", description=__doc__.split("\n\n")[0])
    ap.add_argument("-k", dest="pattern", default="", help="only cases whose key contains this text")
    args = ap.parse_args(argv)
    keys = [k for k in CASES if args.pattern in k]
    if not keys:
        print(f"no case matches {args.pattern!r}; cases: {', '.join(CASES)}", file=sys.stderr)
        return 2
    results = run(keys, log=lambda s: print(s, file=sys.stderr, flush=True))
    print(markdown(results))
    return 0 if all(r.ok for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
