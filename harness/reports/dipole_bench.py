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

    python -m harness.reports.dipole_bench [--repeat 3] [--width 160]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
from typing import Optional, Sequence

import numpy as np

from harness.reference import dipole_ref
from harness.core import runner

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


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.dipole_bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--width", type=int, default=160)
    args = ap.parse_args(argv)
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
