"""Cost of the exact subsurface profile: building its tables and rendering with it.

* **Table build**: ``sstool build`` of one g node (one Monte Carlo run serving all ten etas of the
  shipped grid, plus its five oblique runs) at g = 0, 0.5 and 0.9, with 1 and with 2 threads,
  interleaved (1, 2, 1, 2, ...), medians; the whole shipped grid's time is printed by ``make
  brdf-data``.
* **Render**: the same scenes with ``profile exact`` and ``profile dipole`` (single scattering off,
  each's default), interleaved, median trace time of one thread: the half-lit slab of
  :mod:`harness.reports.dipole_bench` and a marble sphere (``dipole_media.inc``'s preset, 2 cm).

Ratios come from one run with the two variants interleaved; the machine is shared, so single
times move by 10-20 % (the medians and ratios less).

    python -m harness.reports.ss_bench [--repeat 3] [--no-build]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Optional, Sequence

from harness.core import runner
from harness.core import sstool as sst
from harness.reports import dipole_bench

SPHERE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
#declare Dipole_MM_Per_Unit = 10;
#include "dipole_media.inc"
camera {{ orthographic location <0, 0, -10> direction <0, 0, 1> right <2.4, 0, 0> up <0, 2.4, 0> }}
light_source {{ <-3, 4, -5> rgb 1 }}
sphere {{ 0, 1 finish {{ dipole {{ "Marble" mm_per_unit Dipole_MM_Per_Unit {profile} }} }} }}
"""


def slab_scene(profile: str) -> str:
    text = dipole_bench.fork_scene(0.7)
    return text.replace("profile dipole single_scatter on", profile)


def time_build(g: float, threads: int) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        sst.build(Path(tmp) / "one.ssp", g=[g], eta=[1.0, 1.1, 1.2, 1.3, 1.33, 1.4, 1.5, 1.6, 1.8, 2.0], threads=threads)
        return time.perf_counter() - t0


def time_render(text: str, width: int, height: int) -> float:
    r = runner.render(text, "fork", width=width, height=height, float_exr=True, threads=1)
    return r.trace_seconds or float("nan")


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.ss_bench", description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-build", action="store_true", help="skip the table build timings")
    args = ap.parse_args(argv)

    if not args.no_build:
        print("Table build, one g node of the shipped grid (10 etas, 80 000 + 800 000 paths, 5 oblique runs); "
              f"wall seconds, median of {max(1, args.repeat - 1)} interleaved runs:\n")
        print("| g | 1 thread s | 2 threads s | speed-up |")
        print("|---|---|---|---|")
        for g in (0.0, 0.5, 0.9):
            t1, t2 = [], []
            for _ in range(max(1, args.repeat - 1)):
                t1.append(time_build(g, 1))
                t2.append(time_build(g, 2))
            a, b = statistics.median(t1), statistics.median(t2)
            print(f"| {g:g} | {a:.1f} | {b:.1f} | {a / b:.2f} |")
        print()

    print(f"Render, trace seconds of one thread, median of {args.repeat} interleaved runs:\n")
    print("| scene | profile exact s | profile dipole s | exact / dipole |")
    print("|---|---|---|---|")
    cases = [("half-lit slab 160 x 20 (dipole_bench)", slab_scene, 160, 20),
             ("marble sphere 2 cm, 192 x 192", lambda p: SPHERE.format(profile=p), 192, 192)]
    for name, make, w, h in cases:
        te, td = [], []
        time_render(make("profile exact"), w, h)  # warm the page cache and the table file
        for _ in range(args.repeat):
            te.append(time_render(make("profile exact"), w, h))
            td.append(time_render(make("profile dipole"), w, h))
        a, b = statistics.median(te), statistics.median(td)
        print(f"| {name} | {a:.3f} | {b:.3f} | {a / b:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
