"""The dipole finish against stock POV-Ray's subsurface, and its speed-vs-error curve.

Scene: the half-lit slab of ``tests/test_dipole_finish.py`` (a 50 x 50 x 15 mm block of a
medium with sigma_s' = 1/mm, sigma_a = 0.05/mm, eta = 1.3, lit from straight above, shadowed
for x < 0 by an invisible blade), orthographic view of 20 x 2.5 mm across the edge. The
reference is the closed-form half-plane exitance of the dipole
(:func:`harness.reference.dipole_ref.half_plane_exitance`) plus single scattering on the lit side.

* **fork**: ``finish { dipole { sigma_s_prime 1 sigma_a 0.05 ior 1.3 ... profile dipole
  single_scatter on } }`` (the dipole profile, whose closed form is the reference) at several
  ``error_bound`` values (nodes per lookup, trace time, error);
* **stock**: POV-Ray 3.7's own subsurface on the same medium, configured the way its
  documentation asks (``translucency`` = 1/sigma_s' in mm, the pigment is the diffuse
  reflectance that POV's own Rd(alpha') turns back into alpha' = sigma_s'/sigma_t', the
  interior's ior, ``mm_per_unit 1``) at several sample counts.

Error: rms and max over the profile of |render - reference| / lit level, pixels within 1 mm
of the edge excluded (the near-field resolution 2h of the fork at the automatic spacing). Time: POV's
trace time, one thread, median of ``--repeat`` runs.

**The shadow-edge scene** (issue 15, :func:`edge_fork_scene`, :func:`edge_stock_scene`): a 200 x 200
x 50 mm marble slab (Jensen 2001: sigma_s' = (2.19, 2.62, 3.00)/mm, sigma_a = (0.0021, 0.0041,
0.0071)/mm, eta 1.5; ``mm_per_unit 1``) under a parallel light from normalize(1, 0, 1), a black
plate (x in [16.5, 300], z in [16, 16.5]) casting a sharp shadow edge along x = 0 (shadow for
x > 0), an orthographic camera looking down at [-16, 16]^2 mm, 256^2 pixels, no anti-aliasing.
The row-averaged profile is compared with the closed-form half-plane dipole plus single
scattering on the lit side (:func:`edge_reference`), as a fraction of the lit plateau, every
pixel included; the fork at default settings and a few others against stock subsurface at
several sample counts, trace times from one interleaved run (medians), and 1- vs 2-thread
scaling of both.

    python -m harness.reports.dipole_bench [--repeat 3] [--width 160] [--edge-repeat 3] [--no-slab]
"""

from __future__ import annotations

import argparse
import functools
import math
import statistics
import sys
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np

from harness.reference import dipole_ref
from harness.core import runner
from harness.core import sstool as sst
from harness.core.paths import ss_profiles

SIGMA_S_PRIME, SIGMA_A, ETA = 1.0, 0.05, 1.3

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 {globals} }}
camera {{ orthographic location <0, 0, 20> direction <0, 0, -1> right <20, 0, 0> up <0, 2.5, 0> }}
light_source {{ <0, 0, 1000> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-25, -25, -15>, <25, 25, 0>
  texture {{ pigment {{ rgb {pigment} }} finish {{ ambient 0 {finish} }} }} {interior} }}
box {{ <-100, -100, 5>, <0, 100, 5.01> no_image texture {{ pigment {{ rgb 0 }} }} }}
"""


def fork_scene(error_bound: float, spacing: float = 0.0) -> str:
    """spacing 0: the automatic sample spacing (here max(mfp/2, extent/200) = 0.48 mm)."""
    finish = (f"dipole {{ sigma_s_prime {SIGMA_S_PRIME} sigma_a {SIGMA_A} ior {ETA} mm_per_unit 1 "
              f"sample_spacing {spacing} error_bound {error_bound} profile dipole single_scatter on }}")
    return SCENE.format(globals="", pigment=1, finish=finish, interior="")


def pov_rd(alpha_prime: float, eta: float) -> float:
    """Stock POV's total diffuse reflectance for alpha' (its own Fdr approximation,
    source/backend/lighting/subsurface.h, in Jensen's closed form): the pigment to give it."""
    fdr = ((1.0 - 1.0 / eta) + 3.0 * (1.0 - 1.0 / eta) ** 4.5) / 4.0 if eta >= 1.0 else eta ** 2 - eta ** 2.25
    a = (1.0 + fdr) / (1.0 - fdr)
    root = math.sqrt(3.0 * (1.0 - alpha_prime))
    return alpha_prime / 2.0 * (1.0 + math.exp(-4.0 / 3.0 * a * root)) * math.exp(-root)


def stock_scene(diffuse_samples: int, single_samples: int) -> str:
    alpha = SIGMA_S_PRIME / (SIGMA_S_PRIME + SIGMA_A)
    return SCENE.format(globals=f"mm_per_unit 1 subsurface {{ samples {diffuse_samples}, {single_samples} }}",
                        pigment=f"{pov_rd(alpha, ETA):.6f}",
                        finish=f"diffuse 1 subsurface {{ translucency {1.0 / SIGMA_S_PRIME:g} }}",
                        interior=f"interior {{ ior {ETA} }}")


def reference(width: int) -> tuple[np.ndarray, np.ndarray]:
    x = ((np.arange(width) + 0.5) / width - 0.5) * 20.0
    ch = dipole_ref.Dipole(SIGMA_S_PRIME, SIGMA_A, ETA)
    ft = 1.0 - dipole_ref.fresnel_dielectric(1.0, ETA)
    up = np.array([[0.0, 0.0, 1.0]])
    ss = math.pi * dipole_ref.single_scatter_brdf(up, up, SIGMA_S_PRIME / (SIGMA_S_PRIME + SIGMA_A), 0.0, ETA)[0]
    return x, ft * ft * dipole_ref.half_plane_exitance(ch, x) + np.where(x > 0, ss, 0.0)


def measure(text: str, binary: str, width: int, repeat: int) -> tuple[float, float, float, str]:
    """(median trace seconds, rms error, max error, stderr of the last run)."""
    x, want = reference(width)
    times, res = [], None
    for _ in range(repeat):
        res = runner.render(text, binary, width=width, height=20, float_exr=(binary == "fork"), threads=1)
        times.append(res.trace_seconds or float("nan"))
    prof = res.image[..., 0].astype(np.float64).mean(axis=0)
    err = (prof - want) / want[-1]
    keep = np.abs(x) >= 1.0
    return statistics.median(times), float(np.sqrt(np.mean(err[keep] ** 2))), float(np.abs(err[keep]).max()), res.stderr


def nodes_per_lookup(stderr: str) -> float:
    for line in stderr.splitlines():
        if "Nodes/lookup" in line:
            return float(line.split()[-1])
    return float("nan")


# ---------------------------------------------------------------- the shadow-edge scene

EDGE_SIGMA_S_PRIME = (2.19, 2.62, 3.00)     # Jensen 2001 marble, 1/mm
EDGE_SIGMA_A = (0.0021, 0.0041, 0.0071)
EDGE_ETA = 1.5
EDGE_HALF = 16.0                            # the camera sees [-EDGE_HALF, EDGE_HALF]^2 mm
EDGE_WIDTH = 256

EDGE_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 {globals} }}
camera {{ orthographic location <0, 0, 100> direction <0, 0, -1> right <{size}, 0, 0> up <0, {size}, 0> }}
light_source {{ <1000, 0, 1000> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-100, -100, -50>, <100, 100, 0>
  texture {{ pigment {{ rgb {pigment} }} finish {{ ambient 0 {finish} }} }} {interior} }}
box {{ <16.5, -300, 16>, <300, 300, 16.5> texture {{ pigment {{ rgb 0 }} finish {{ ambient 0 diffuse 0 }} }} }}
"""


def _rgb(v: Sequence[float], fmt: str = "{:g}") -> str:
    return "<" + ", ".join(fmt.format(c) for c in v) + ">"


def edge_fork_scene(extra: str = "", half: float = EDGE_HALF) -> str:
    """The edge scene with the fork's dipole (``extra``: more keywords of the dipole block).

    ``profile dipole single_scatter on``: the closed-form half-plane dipole plus single
    scattering is the reference (issue 15 judges the edge with the dipole profile; the exact
    profile, the finish's default, has no closed form at an edge)."""
    finish = (f"dipole {{ sigma_s_prime {_rgb(EDGE_SIGMA_S_PRIME)} sigma_a {_rgb(EDGE_SIGMA_A)} ior {EDGE_ETA:g} "
              f"mm_per_unit 1 profile dipole single_scatter on {extra} }}")
    return EDGE_SCENE.format(globals="", size=f"{2 * half:g}", pigment=1, finish=finish, interior="")


def edge_stock_scene(diffuse_samples: int = 50, single_samples: int = 50, half: float = EDGE_HALF) -> str:
    """The edge scene with stock POV-Ray's subsurface, set up as :func:`stock_scene` documents."""
    alpha = [s / (s + a) for s, a in zip(EDGE_SIGMA_S_PRIME, EDGE_SIGMA_A)]
    return EDGE_SCENE.format(globals=f"mm_per_unit 1 subsurface {{ samples {diffuse_samples}, {single_samples} }}",
                             size=f"{2 * half:g}", pigment=_rgb([pov_rd(a, EDGE_ETA) for a in alpha], "{:.6f}"),
                             finish=f"diffuse 1 subsurface {{ translucency {_rgb([1 / s for s in EDGE_SIGMA_S_PRIME])} }}",
                             interior=f"interior {{ ior {EDGE_ETA:g} }}")


@functools.lru_cache(maxsize=8)
def edge_reference(width: int = EDGE_WIDTH, half: float = EDGE_HALF) -> tuple[np.ndarray, np.ndarray]:
    """(x of the pixel columns in mm, expected row-averaged pixel per channel: shape (3, width)).

    Light from normalize(1, 0, 1) transmits Ft(cos 45) cos 45 (unit light colour) on x < 0;
    the camera looks straight down, so a pixel is Ft(1) Ft(45) cos 45 M(-x) + the single
    scattering BRDF's pi f cos 45 on the lit side, M the dipole's half-plane exitance."""
    x = ((np.arange(width) + 0.5) / width - 0.5) * 2 * half
    c = 1 / math.sqrt(2)
    ft_view = 1 - dipole_ref.fresnel_dielectric(1.0, EDGE_ETA)
    ft_light = 1 - dipole_ref.fresnel_dielectric(c, EDGE_ETA)
    up, light = np.array([[0.0, 0.0, 1.0]]), np.array([[c, 0.0, c]])
    out = np.empty((3, width))
    for k, (s, a) in enumerate(zip(EDGE_SIGMA_S_PRIME, EDGE_SIGMA_A)):
        ch = dipole_ref.Dipole(s, a, EDGE_ETA)
        ss = math.pi * dipole_ref.single_scatter_brdf(up, light, s / (s + a), 0.0, EDGE_ETA)[0] * c
        out[k] = ft_view * ft_light * c * dipole_ref.half_plane_exitance(ch, -x) + np.where(x < 0, ss, 0.0)
    out.setflags(write=False)
    return x, out


def edge_exact_scene(extra: str = "", half: float = EDGE_HALF) -> str:
    """The edge scene with the finish's defaults: the exact profile, single scattering on."""
    text = edge_fork_scene(extra, half=half).replace("profile dipole single_scatter on ", "")
    assert "profile" not in text
    return text


@functools.lru_cache(maxsize=8)
def edge_reference_exact(width: int = EDGE_WIDTH, half: float = EDGE_HALF, n: int = 6000) -> tuple[np.ndarray, np.ndarray]:
    """:func:`edge_reference` for the exact profile: the half-plane integral of the exact
    profile's own Rd (``sstool eval``: the library's tables, so this checks the renderer's
    sampling, refinement and octree at an edge, not the profile; tests/test_ss_profiles.py and
    :mod:`harness.reports.ss_profiles` check the profile against the Monte Carlo), times its
    exit factor at the normal view and the transmitted irradiance Ft(45) entry(45) cos 45, plus
    the single-scattering BRDF on the lit side. Quadrature: r = r_max u^2, n nodes, r_max 1500
    transport mfp (the profile holds all but ~1e-6 of its total within it)."""
    x = ((np.arange(width) + 0.5) / width - 0.5) * 2 * half
    c = 1 / math.sqrt(2)
    up, light = np.array([[0.0, 0.0, 1.0]]), np.array([[c, 0.0, c]])
    u = (np.arange(n) + 0.5) / n
    r_tr = 1500.0 * u * u
    w_r = 2 * math.pi * r_tr * 2 * 1500.0 * u / n
    out = np.empty((3, width))
    for k, (s, a) in enumerate(zip(EDGE_SIGMA_S_PRIME, EDGE_SIGMA_A)):
        st, ap = s + a, s / (s + a)
        rd = []
        for chunk in np.array_split(r_tr, max(1, n // 1000)):  # a command line holds ~1000 radii
            row = sst.eval_profile(ss_profiles(), [ap], g=0.0, eta=EDGE_ETA, cos=(1.0, c),
                                   radii=[float(v) for v in chunk])[0]
            rd += row["rd"]
        w = np.asarray(rd) * w_r  # dimensionless, transport units
        et = (1 - dipole_ref.fresnel_dielectric(c, EDGE_ETA)) * row["entry_factor"][1] * c
        m = np.empty(width)
        for i, dk in enumerate(-x * st):  # signed distance into the lit side (x < 0), transport mfp
            with np.errstate(invalid="ignore"):
                frac = np.where(dk >= r_tr, 1.0, np.where(dk <= -r_tr, 0.0,
                                                          1.0 - np.arccos(np.clip(dk / r_tr, -1, 1)) / math.pi))
            m[i] = float(np.sum(w * frac))
        ss = math.pi * dipole_ref.single_scatter_brdf(up, light, ap, 0.0, EDGE_ETA)[0] * c
        out[k] = row["exit_factor"][0] * et * m + np.where(x < 0, ss, 0.0)
    out.setflags(write=False)
    return x, out


def edge_errors(image: np.ndarray, half: float = EDGE_HALF, exact: bool = False) -> tuple[float, float, np.ndarray]:
    """(max, rms, signed profile error per channel) of a render's row-averaged profile against
    :func:`edge_reference` (``exact``: :func:`edge_reference_exact`), as fractions of each
    channel's lit plateau; every column counts."""
    x, want = (edge_reference_exact if exact else edge_reference)(image.shape[1], half)
    prof = image.astype(np.float64).mean(axis=0).T
    err = (prof - want) / want[:, :1]
    return float(np.abs(err).max()), float(np.sqrt(np.mean(err ** 2))), err


@dataclass
class EdgeCase:
    label: str
    binary: str
    text: str
    threads: int = 1
    times: list = field(default_factory=list)
    cpu: list = field(default_factory=list)
    max_err: float = float("nan")
    rms_err: float = float("nan")
    profile: Optional[np.ndarray] = None  # signed error per channel and column (first run)
    stderr: str = ""

    @property
    def trace(self) -> float:
        return statistics.median(self.times)


def edge_cases() -> list[EdgeCase]:
    """The bench's configurations: the fork at default settings and others, stock at several samples."""
    cases = [EdgeCase("fork, default", "fork", edge_fork_scene()),
             EdgeCase("fork, refine_levels 0 (one spacing, as before refinement)", "fork", edge_fork_scene("refine_levels 0")),
             EdgeCase("fork, refine_levels 2", "fork", edge_fork_scene("refine_levels 2")),
             EdgeCase("fork, refine_levels 6", "fork", edge_fork_scene("refine_levels 6")),
             EdgeCase("fork, error_bound 0.35", "fork", edge_fork_scene("error_bound 0.35")),
             EdgeCase("fork, error_bound 1.2", "fork", edge_fork_scene("error_bound 1.2"))]
    cases += [EdgeCase(f"stock, samples {d}, {s}" + (" (stock default)" if (d, s) == (50, 50) else ""), "stock",
                       edge_stock_scene(d, s)) for d, s in ((10, 10), (25, 5), (50, 50), (200, 50))]
    return cases


def thread_cases() -> list[EdgeCase]:
    """Fork default and stock samples 50, 50 at one and at two render threads."""
    return [EdgeCase("fork, default, 1 thread", "fork", edge_fork_scene(), 1),
            EdgeCase("fork, default, 2 threads", "fork", edge_fork_scene(), 2),
            EdgeCase("stock, samples 50, 50, 1 thread", "stock", edge_stock_scene(50, 50), 1),
            EdgeCase("stock, samples 50, 50, 2 threads", "stock", edge_stock_scene(50, 50), 2)]


def run_edge(cases: Sequence[EdgeCase], repeat: int, width: int = EDGE_WIDTH,
             log=lambda s: None) -> Sequence[EdgeCase]:
    """Render every case `repeat` times, interleaved (case 1, 2, ..., n, then again): POV's trace
    time (wall) and trace CPU seconds per run; errors from the first run."""
    for rnd in range(repeat):
        for c in cases:
            res = runner.render(c.text, c.binary, width=width, height=width, float_exr=(c.binary == "fork"),
                                threads=c.threads)
            c.times.append(res.trace_seconds or float("nan"))
            c.cpu.append(res.stats.get("trace_cpu_time", float("nan")))
            if rnd == 0:
                c.max_err, c.rms_err, c.profile = edge_errors(res.image)
                c.stderr = res.stderr
            log(f"[edge] {c.label}: {c.times[-1]:.3f} s")
    return cases


def edge_markdown(cases: Sequence[EdgeCase], threads: Sequence[EdgeCase], width: int) -> str:
    ref = next(c for c in cases if "stock default" in c.label)
    lines = [f"Shadow-edge scene (issue 15), {width}^2 pixels, one thread unless noted; trace time = POV's own "
             f"(precompute included), median of {len(ref.times)} interleaved runs; errors of the row-averaged profile "
             "against the closed-form half-plane dipole, / lit plateau, every pixel, worst channel.", "",
             "| renderer | trace s | CPU s | stock default / this | max error | rms error | points | nodes/lookup |",
             "|---|---|---|---|---|---|---|---|"]
    for c in cases:
        pts = next((l.split()[-1] for l in c.stderr.splitlines() if l.startswith("Dipole objects")), "")
        nodes = nodes_per_lookup(c.stderr) if c.binary == "fork" else float("nan")
        lines.append(f"| {c.label} | {c.trace:.3f} | {statistics.median(c.cpu):.3f} | {ref.trace / c.trace:.1f}x | "
                     f"{c.max_err:.2%} | {c.rms_err:.2%} | {pts} | {'' if math.isnan(nodes) else f'{nodes:.0f}'} |")
    if threads:
        by = {c.label: c for c in threads}
        f1, f2 = by["fork, default, 1 thread"], by["fork, default, 2 threads"]
        s1, s2 = by["stock, samples 50, 50, 1 thread"], by["stock, samples 50, 50, 2 threads"]
        lines += ["", "| renderer | 1 thread s | 2 threads s | 1-thread / 2-thread |", "|---|---|---|---|",
                  f"| fork, default | {f1.trace:.3f} | {f2.trace:.3f} | {f1.trace / f2.trace:.2f} |",
                  f"| stock, samples 50, 50 | {s1.trace:.3f} | {s2.trace:.3f} | {s1.trace / s2.trace:.2f} |"]
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.dipole_bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--edge-repeat", type=int, default=3)
    ap.add_argument("--no-slab", action="store_true", help="only the shadow-edge scene")
    ap.add_argument("--no-edge", action="store_true", help="only the half-lit slab")
    args = ap.parse_args(argv)
    if not args.no_slab:
        slab_main(args)
    if not args.no_edge:
        cases = run_edge(edge_cases(), args.edge_repeat)
        threads = run_edge(thread_cases(), args.edge_repeat)
        print("\n" + edge_markdown(cases, threads, EDGE_WIDTH))
    return 0


def slab_main(args) -> None:
    rows = []
    for eb in (0.1, 0.3, 0.5, 0.7, 1.0, 1.5):
        t, rms, mx, err = measure(fork_scene(eb), "fork", args.width, args.repeat)
        rows.append((f"fork dipole, error_bound {eb:g}" + (" (default)" if eb == 0.7 else ""), t, rms, mx,
                     f"{nodes_per_lookup(err):.0f} nodes/lookup"))
    for d, s in ((25, 5), (100, 20), (400, 40)):
        t, rms, mx, _ = measure(stock_scene(d, s), "stock", args.width, args.repeat)
        rows.append((f"stock subsurface, samples {d}, {s}", t, rms, mx, ""))
    default = next(r for r in rows if "(default)" in r[0])
    print(f"Half-lit slab, {args.width} x 20 pixels, one thread, median of {args.repeat}; errors relative to "
          "the lit level, 1 mm around the edge excluded.\n")
    print("| renderer | trace s | stock time / this | rms error | max error | note |")
    print("|---|---|---|---|---|---|")
    for name, t, rms, mx, note in rows:
        print(f"| {name} | {t:.3f} | {t / default[1]:.1f}x of default fork | {rms:.2e} | {mx:.2e} | {note} |")


if __name__ == "__main__":
    sys.exit(main())
