"""Benchmarks: trace-time ratios measured in one run, never asserted by tests.

Each row renders a scene with a baseline (usually stock POV-Ray) and a candidate (the
fork, often with one of our finishes) and reports the ratio of POV's own *trace* times
(start-up and parsing excluded). Renders alternate baseline/candidate and each ratio is the
median over ``--repeat`` pairs, so machine noise hits both sides alike. Rows of one *group*
share their baseline and are measured in interleaved rounds (baseline, then every candidate,
in a rotating order): each round's ratios divide by that round's baseline. Two ratios are
printed: of POV's trace time (wall clock, the goals' measure) and of its trace CPU-seconds
(summed over render threads), which other work on a shared machine inflates far less; on a
quiet machine the two agree for one thread.

The speed goals of issue 16 are the ``grid`` rows: 25 spheres (5 x 5, radius 1, spacing 2.2)
over a plane, one parallel and one point light, orthographic camera, 1536 x 1536, no AA,
against stock POV-Ray's ``diffuse 0.6 phong 0.5 phong_size 40``; the ``grid 2 threads`` rows
render the same scenes with ``+WT2``.

Wall time on a shared or virtual machine drifts by more than the few per cent those goals
are about, so the one-thread ``grid`` rows also print an ``instr ratio``: the instructions
the trace executes, counted by valgrind (callgrind) where it is installed. A count is the
difference between renders at 1/4 and 1/8 of the row's size, so start-up, parsing and
table loading cancel and a stripped binary (Debian's) is counted like ours; it hardly
varies between runs (0.003 % for the stock grid). It does not see memory stalls, cache
misses or instruction latencies (a sqrt costs one instruction; builds with fewer
instructions have traced slower, shading/MODELS.md), so the wall ratio stays the goal's
measure and the count its steady companion.

The grid rows render each round's image as ``GRID_BANDS`` bands of rows (POV's +SR/+ER),
every side rendering a band back to back before the next band (``Row.bands``): a round's
time for a side is the sum over its bands, so the ratio is still the whole image's, but the
sides are compared within a fraction of a second of each other instead of across a round of
whole renders, and this machine's drifts (seconds long) fall on both alike. On the grid
(2026-12-02, 11 rounds of 12 bands) the per-round ratios of stock against itself spread
0.86..1.14 (one thread) and 0.92..1.06 (two), the 95 % intervals of their medians 0.94..1.08
and 0.96..1.03; whole-image rounds on the same machine that day spread the fork's phong
(1.003 x the instructions) over 0.77..1.38. Each band adds POV's fixed per-render trace cost
(about 1 ms, ~1 % of the grid's trace over 12 bands), which pulls a ratio R toward 1 by
about (R - 1) / 100: below the third decimal for the goals here. The ``stock phong / stock
phong`` rows measure the method's own noise in the same rounds.

A row with a ``goal`` also prints the interval that holds its true median wall ratio with
95 % probability (order statistics: distribution-free, as the rounds' ratios are skewed by the
machine's bursts) and a verdict read from it: ``met`` when all of the interval is at or
under the goal, ``missed`` when all of it is above, ``not shown`` when it holds the goal. On
a machine whose rounds spread by +-10..30 % (whole images here, shading/MODELS.md) a goal a
few per cent from the ratio stays ``not shown`` at any practical ``--repeat``: the
instruction ratio is then the evidence the table can give, and the verdict says that it is
not the goal's own measure. ``--instructions all`` counts every selected row, ``none`` none.

    python -m harness.reports.bench                 # every row
    python -m harness.reports.bench -k unmodified   # rows whose name contains the text
    python -m harness.reports.bench --list
    python -m harness.reports.bench -k grid: --repeat 9 --instructions all

Later issues add rows with :func:`row`.
"""

from __future__ import annotations

import argparse
import math
import re
import shutil
import statistics
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence, Union

from harness.core import runner, shapes, tables
from harness.reports import walk_bench

#: The reference scene of the pipeline issue: diffuse, phong, specular, reflection and
#: a few lights, no new keywords. Its trace time is about 0.6 s at 1280x960 on one thread.
REFERENCE_SCENE = """#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 5 }
camera { location <0, 2.2, -7> look_at <0, 0.7, 0> angle 45 }
light_source { <-4, 6, -5> rgb 1 }
light_source { <5, 3, -2> rgb <0.3, 0.35, 0.4> }
plane { y, 0 pigment { checker rgb 0.8 rgb 0.2 scale 0.5 } finish { diffuse 0.7 reflection 0.15 } }
#declare I = 0;
#while (I < 9)
  sphere { <mod(I, 3) * 1.6 - 1.6, 0.6, div(I, 3) * 1.6 - 0.8> 0.6
    pigment { rgb <0.2 + 0.08 * I, 0.5, 0.9 - 0.08 * I> }
    finish { diffuse 0.6 phong 0.6 phong_size 30 specular 0.2 roughness 0.02 } }
  #declare I = I + 1;
#end
"""


@dataclass
class Side:
    """One side of a comparison: a binary and the scene text it renders."""

    binary: str
    scene: str
    #: name in the job directory -> path, or a callable making the file (tables), run once
    files: Mapping[str, Union[str, Path, Callable[[], Path]]] = field(default_factory=dict)

    def resolved_files(self) -> dict[str, Path]:
        return {k: Path(v() if callable(v) else v) for k, v in self.files.items()}


@dataclass
class Row:
    name: str
    baseline: Side
    candidate: Side
    width: int = 1280
    height: int = 960
    note: str = ""
    threads: int = 1
    #: rows with the same group share the baseline and are measured in interleaved rounds
    group: str = ""
    #: count the trace's instructions too (``--instructions auto``; needs valgrind)
    count_instructions: bool = False
    #: the ratio the row must not exceed (its ``verdict``), if it has a goal
    goal: Optional[float] = None
    #: a round renders the image as this many bands of rows (POV's +SR/+ER), every side of
    #: the group rendering a band back to back before the next band; 1: whole images
    bands: int = 1

    @property
    def label(self) -> str:
        """The table's note column: the goal, when the row has one, before the note."""
        if self.goal is None:
            return self.note
        return f"goal <= {self.goal:.2f}" + (f" {self.note}" if self.note else "")


ROWS: list[Row] = []


def row(name: str, baseline: Side, candidate: Side, **kw) -> Row:
    """Register a benchmark row (module import time)."""
    r = Row(name, baseline, candidate, **kw)
    ROWS.append(r)
    return r


row("unmodified scene: fork / stock",
    Side("stock", REFERENCE_SCENE), Side("fork", REFERENCE_SCENE),
    note="same scene, no new keywords; expected ~1.0")

#: The reference scene with every sphere's finish replaced by a 1 deg table of a
#: comparable material (a Lambert base under a rough dielectric lobe).
TABLE_SPEC = "microfacet d=tr m=0.15 f=dielectric eta=1.5 kd=0.6 rho_s=0.4"
#: The baseline finish of REFERENCE_SCENE, which every candidate row replaces.
STOCK_FINISH = "finish { diffuse 0.6 phong 0.6 phong_size 30 specular 0.2 roughness 0.02 }"

def _table_side(lookup: str = "") -> Side:
    """The fork rendering the reference scene with the 1 deg table finish."""
    return Side("fork", REFERENCE_SCENE.replace(STOCK_FINISH, f'finish {{ brdf_table {{ "t.brdf"{lookup} }} }}'),
                files={"t.brdf": lambda: tables.tabulated(TABLE_SPEC, step=1.0, fold=True)})


row("brdf_table 1 deg trilinear / stock phong+specular", Side("stock", REFERENCE_SCENE), _table_side(),
    goal=1.15)
row("brdf_table 1 deg trilinear / fork phong+specular", Side("fork", REFERENCE_SCENE), _table_side(),
    note="same binary: the cost of the table path alone")
row("brdf_table 1 deg nearest / stock phong+specular", Side("stock", REFERENCE_SCENE), _table_side(" interpolate 0"))
row("brdf_model (same microfacet, direct) / stock phong+specular",
    Side("stock", REFERENCE_SCENE),
    Side("fork", REFERENCE_SCENE.replace(STOCK_FINISH, f'finish {{ brdf_model {{ "{TABLE_SPEC}" }} }}')),
    note="analytic evaluation")

def _halfdiff_side() -> Side:
    """The reference scene with the same material as a half/difference table (layout 3, the
    default 256 x 128 x 32 nodes): the narrow-lobe layout's lookup cost on the 1 deg table's scene."""
    return Side("fork", REFERENCE_SCENE.replace(STOCK_FINISH, 'finish { brdf_table { "t.brdf" } }'),
                files={"t.brdf": lambda: tables.tabulated_halfdiff(TABLE_SPEC)})


row("brdf_table halfdiff trilinear / stock phong+specular", Side("stock", REFERENCE_SCENE), _halfdiff_side(),
    note="goal: the 1 deg table's")
row("brdf_table halfdiff trilinear / brdf_table 1 deg trilinear", _table_side(), _halfdiff_side(),
    note="same binary: the layouts' lookups; goal ~1.0")
assert all(STOCK_FINISH not in r.candidate.scene for r in ROWS[1:])  # every candidate replaced it

#: Issue 16's speed scene: 5 x 5 spheres of radius 1, spacing 2.2, over a plane, one parallel
#: and one point light, orthographic camera; rendered at 1536 x 1536 without anti-aliasing.
GRID_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 14, -14> look_at <0, 0.5, 0> right x*15 up y*15 }}
light_source {{ <-1, 1.5, -0.6> * 1000 rgb <0.9, 0.9, 0.85> parallel point_at 0 }}
light_source {{ <6, 9, -8> rgb <0.5, 0.55, 0.6> }}
plane {{ y, 0 pigment {{ rgb 0.6 }} finish {{ diffuse 0.7 }} }}
#declare I = 0;
#while (I < 25)
  sphere {{ <mod(I, 5) * 2.2 - 4.4, 1, div(I, 5) * 2.2 - 4.4>, 1
    pigment {{ rgb <0.8, 0.5, 0.3> }}
    finish {{ {finish} }} }}
  #declare I = I + 1;
#end
"""
GRID_PHONG = "diffuse 0.6 phong 0.5 phong_size 40"
#: A gold-like conductor: Beckmann lobe, Smith G, conductor Fresnel (n + ik per channel).
GRID_MODEL = "microfacet d=beckmann m=0.2 f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8"
GRID_SIZE = 1536


def grid_side(finish: str, binary: str = "fork", lookup: str = "") -> Side:
    """One side of the grid rows: `finish` is "phong" (stock finish), "table" (the 1 deg table,
    `lookup` appended to its block), "halfdiff" (the same material as a half/difference table,
    the default 256 x 128 x 32 nodes) or "model" (GRID_MODEL)."""
    if finish == "table":
        return Side(binary, GRID_SCENE.format(finish=f'brdf_table {{ "t.brdf"{lookup} }}'),
                    files={"t.brdf": lambda: tables.tabulated(TABLE_SPEC, step=1.0, fold=True)})
    if finish == "halfdiff":
        return Side(binary, GRID_SCENE.format(finish='brdf_table { "t.brdf" }'),
                    files={"t.brdf": lambda: tables.tabulated_halfdiff(TABLE_SPEC)})
    if finish == "model":
        return Side(binary, GRID_SCENE.format(finish=f'brdf_model {{ "{GRID_MODEL}" }}'))
    return Side(binary, GRID_SCENE.format(finish=GRID_PHONG))


#: Bands per round of the grid rows (``Row.bands``): 128 rows each.
GRID_BANDS = 12

for _threads, _group in ((1, "grid"), (2, "grid 2 threads")):
    _kw = dict(width=GRID_SIZE, height=GRID_SIZE, threads=_threads, group=_group, count_instructions=_threads == 1,
               bands=GRID_BANDS)
    row(f"{_group}: stock phong / stock phong", grid_side("phong", "stock"), grid_side("phong", "stock"),
        note="the same binary and scene: the method's own noise", **_kw)
    row(f"{_group}: fork phong / stock phong", grid_side("phong", "stock"), grid_side("phong"),
        note="(+- noise)", goal=1.00, **_kw)
    row(f"{_group}: brdf_table 1 deg trilinear / stock phong", grid_side("phong", "stock"), grid_side("table"),
        goal=1.05, **_kw)
    if _threads == 1:
        row(f"{_group}: brdf_table 1 deg nearest / stock phong", grid_side("phong", "stock"),
            grid_side("table", lookup=" interpolate 0"), **_kw)
    row(f"{_group}: brdf_table halfdiff trilinear / stock phong", grid_side("phong", "stock"),
        grid_side("halfdiff"), note="(the narrow-lobe layout's lookup)", goal=1.05, **_kw)
    row(f"{_group}: brdf_model Beckmann conductor / stock phong", grid_side("phong", "stock"), grid_side("model"),
        goal=1.25, **_kw)


# Subsurface in real geometry (issue 31): each shape's default (profile) render against a sphere
# of its size in the same camera and light, every preset. What a shape adds is its cloud's
# sampling and, where it is thin, the slab profiles of its thickness nodes (built per render).
for _shape in ("blob", "difference", "mesh"):
    for _preset in ("Marble", "Skin1", "Ketchup", "Skimmilk"):
        row(f"dipole {_shape} / sphere of its size: {_preset}", Side("fork", shapes.scene(_shape, _preset, sphere=True)),
            Side("fork", shapes.scene(_shape, _preset)), width=192, height=160, threads=2, goal=3.0,
            note="method profile, default settings")

# What `directional on` (light entering at a slant: shading/DIPOLE.md 6b) costs where it is
# for: walk_bench's shadow edge on a block under light at 45 degrees (issue 31's first case), a
# 10 x 4 mm view at 320 x 128, where the cloud is refined 5 levels along the edge.
for _preset in ("Skin1", "Ketchup"):
    _t = math.radians(45)
    _edge = walk_bench.EDGE.format(width=10, height=4, light=walk_bench.vec([-math.sin(_t), 0.0, math.cos(_t)]),
                                   edge=walk_bench.plate_edge(_t), dipole=walk_bench.medium_text(_preset, 0.0, 1.3) + "{extra}")
    row(f"dipole directional on / off, slanted shadow edge: {_preset}",
        Side("fork", _edge.replace("{extra}", " directional off")), Side("fork", _edge.replace("{extra}", " directional on")),
        width=320, height=128, threads=2, note="ior 1.3, light at 45 deg")

# What `directional on` (the default since 2026-12-07) costs on the study's blob and on the
# sphere of its size: its cloud's shifts (the fade at creases) and its lookups' three images per
# point and channel. No goal: the cost of being right at a slant.
for _sphere in (False, True):
    for _preset in ("Marble", "Skin1", "Ketchup", "Skimmilk"):
        row(f"dipole directional on / off, {'sphere of the blob' if _sphere else 'blob'}: {_preset}",
            Side("fork", shapes.scene("blob", _preset, extra="directional off", sphere=_sphere)),
            Side("fork", shapes.scene("blob", _preset, extra="directional on", sphere=_sphere)),
            width=192, height=160, threads=2, note="method profile")


@dataclass
class Result:
    row: Row
    baseline_s: list[float]
    candidate_s: list[float]
    #: POV's trace CPU-seconds (all render threads) of the same renders: on a shared machine
    #: other work inflates them far less than the wall-clock trace time
    baseline_cpu: list[float] = field(default_factory=list)
    candidate_cpu: list[float] = field(default_factory=list)
    #: instructions of the trace (trace_instructions), when counted
    baseline_instructions: Optional[int] = None
    candidate_instructions: Optional[int] = None

    @property
    def instruction_ratio(self) -> Optional[float]:
        if not self.baseline_instructions or self.candidate_instructions is None:
            return None
        return self.candidate_instructions / self.baseline_instructions

    @property
    def ratios(self) -> list[float]:
        return [c / b for b, c in zip(self.baseline_s, self.candidate_s) if b > 0]

    @property
    def ratio(self) -> float:
        return statistics.median(self.ratios)

    @property
    def cpu_ratio(self) -> Optional[float]:
        rs = [c / b for b, c in zip(self.baseline_cpu, self.candidate_cpu) if b > 0]
        return statistics.median(rs) if rs else None

    @property
    def interval(self) -> tuple[float, float, float]:
        """median_interval of the wall ratios."""
        return median_interval(self.ratios)

    @property
    def verdict(self) -> str:
        """The row's goal against the interval of its median wall ratio (``-`` without a goal)."""
        if self.row.goal is None:
            return "-"
        lo, hi, _ = self.interval
        return goal_verdict(lo, hi, self.row.goal)


#: Confidence of the interval the verdicts read (a median's, distribution-free).
CONFIDENCE = 0.95


def median_interval(values: Sequence[float], confidence: float = CONFIDENCE) -> tuple[float, float, float]:
    """(low, high, coverage): an interval of order statistics that holds the median of the
    distribution the values were drawn from with probability ``coverage`` >= ``confidence``,
    whatever that distribution (the number of values below the median is binomial(n, 1/2)):
    the k-th smallest and k-th largest value for the largest k that keeps the coverage. With
    too few values for the confidence (n <= 5 at 0.95) it is the whole range and its smaller
    coverage, 1 - 2^(1-n)."""
    from scipy.stats import binom

    x = sorted(values)
    n = len(x)
    if n == 0:
        raise ValueError("median_interval: no values")
    k = 1
    while k < (n + 1) // 2 and 2 * binom.cdf(k, n, 0.5) <= 1 - confidence:
        k += 1
    return x[k - 1], x[n - k], 1 - 2 * binom.cdf(k - 1, n, 0.5)


def goal_verdict(low: float, high: float, goal: float) -> str:
    """``met`` when the whole interval is at or under the goal, ``missed`` when it is all
    above, ``not shown`` when it holds the goal (the machine's noise is wider than the
    distance to the goal: more rounds, or a quieter machine)."""
    if high <= goal:
        return "met"
    if low > goal:
        return "missed"
    return "not shown"


class RoundTimes(list):
    """Trace wall seconds, with the CPU-seconds of the same renders alongside."""

    def __init__(self) -> None:
        super().__init__()
        self.cpu: list[float] = []


def band_rows(height: int, bands: int) -> list[tuple[int, int]]:
    """(first, last) image rows, counted from 1 as POV's +SR/+ER count them, of ``bands``
    bands that cover ``height`` rows. Each band has at least two rows: POV reads a row
    number of 1 or less as a fraction of the image (+ER1 is the whole image)."""
    if not 1 <= bands <= height // 2:
        raise ValueError(f"{bands} bands of a {height}-row image: 1 to {height // 2}")
    edges = [round(k * height / bands) for k in range(bands + 1)]
    return [(edges[k] + 1, edges[k + 1]) for k in range(bands)]


def trace_render(side: Side, r: Row, band: Optional[tuple[int, int]] = None) -> tuple[float, float]:
    """(trace wall seconds, trace CPU-seconds) of one render, of the rows ``band`` only if given."""
    extra = [f"+SR{band[0]}", f"+ER{band[1]}"] if band else []
    res = runner.render(side.scene, side.binary, width=r.width, height=r.height, threads=r.threads,
                        files=side.resolved_files(), extra_args=extra)
    if res.trace_seconds is None:
        raise RuntimeError(f"{r.name}: POV printed no trace time")
    return res.trace_seconds, float(res.stats.get("trace_cpu_time", res.trace_seconds))


def measure_round(sides: Sequence[Side], r: Row, i: int, into: Sequence[RoundTimes]) -> None:
    """Round ``i``: every side renders the whole image once, as ``r.bands`` bands; each band
    is rendered by every side back to back, in an order that rotates with the band and the
    round. A side's time for the round (appended to its ``into``) is the sum over the bands."""
    bands = band_rows(r.height, r.bands) if r.bands > 1 else [None]
    wall = [0.0] * len(sides)
    cpu = [0.0] * len(sides)
    for k, band in enumerate(bands):
        for m in range(len(sides)):
            j = (m + i + k) % len(sides)
            w, c = trace_render(sides[j], r, band)
            wall[j] += w
            cpu[j] += c
    for t, w, c in zip(into, wall, cpu):
        t.append(w)
        t.cpu.append(c)


#: Fractions of a row's image size whose renders' instruction counts are subtracted.
INSTRUCTION_SCALES = (1 / 8, 1 / 4)
_IREFS = re.compile(r"^==\d+== I\s+refs:\s+([\d,]+)\s*$", re.M)


def parse_instructions(report: str) -> int:
    """The total from valgrind's summary (``==PID== I   refs:   1,234,567``)."""
    m = _IREFS.findall(report)
    if len(m) != 1:
        raise ValueError(f"expected one valgrind 'I refs' line, found {len(m)}")
    return int(m[0].replace(",", ""))


def instruction_difference(small: int, large: int) -> int:
    """Instructions of the extra pixels: ``large - small`` (counts of the two renders)."""
    if large <= small:
        raise ValueError(f"the larger render counted {large} instructions, the smaller {small}")
    return large - small


def have_valgrind() -> bool:
    return shutil.which("valgrind") is not None


def trace_instructions(side: Side, r: Row) -> int:
    """Instructions the trace of ``side`` executes over 3/64 of the row's pixels: callgrind's
    count of a render at 1/4 of the row's size minus one at 1/8 (INSTRUCTION_SCALES)."""
    counts = []
    for f in INSTRUCTION_SCALES:
        w, h = max(8, round(r.width * f)), max(8, round(r.height * f))
        res = runner.render(side.scene, side.binary, width=w, height=h, threads=r.threads,
                            files=side.resolved_files(), timeout=3600.0,
                            wrapper=("valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null"))
        counts.append(parse_instructions(res.stderr))
    return instruction_difference(*counts)


def count_instructions(results: Sequence[Result], log: Optional[Callable[[str], None]] = None) -> None:
    """Fill in the instruction counts of ``results`` (each distinct side counted once)."""
    seen: dict[tuple, int] = {}
    for x in results:
        r = x.row
        for side, attr in ((r.baseline, "baseline_instructions"), (r.candidate, "candidate_instructions")):
            # the staged files by what they are, not by name: two tables staged as t.brdf differ
            files = tuple(sorted((k, str(v)) for k, v in side.resolved_files().items()))
            key = (side.binary, side.scene, files, r.width, r.height, r.threads)
            if key not in seen:
                seen[key] = trace_instructions(side, r)
                if log:
                    log(f"  {r.name}: {side.binary} {seen[key]:,} instructions")
            setattr(x, attr, seen[key])


def measure(r: Row, repeat: int = 5, log: Optional[Callable[[str], None]] = None) -> Result:
    """Baseline and candidate in ``repeat`` interleaved rounds (after one warm-up pair)."""
    return measure_group([r], repeat, log)[0]


def measure_group(rows: Sequence[Row], repeat: int = 5,
                  log: Optional[Callable[[str], None]] = None) -> list[Result]:
    """Rows sharing one baseline, in ``repeat`` interleaved rounds after a warm-up round.

    Each round renders the baseline and every candidate once (``measure_round``: the order
    rotates from round to round, and from band to band where the rows ask for bands); a row's
    ratios divide its candidate's time by the same round's baseline.
    """
    first = rows[0]
    assert all(r.baseline == first.baseline and (r.width, r.height, r.threads, r.bands) ==
               (first.width, first.height, first.threads, first.bands) for r in rows), "a group shares its baseline"
    sides = [first.baseline] + [r.candidate for r in rows]
    for side in sides:
        trace_render(side, first)  # warm file caches and table caches
    times = [RoundTimes() for _ in sides]
    for i in range(repeat):
        measure_round(sides, first, i, times)
        if log:
            log(f"  {first.group or first.name} [{i + 1}/{repeat}] baseline {times[0][-1]:.3f} s, " +
                ", ".join(f"{c[-1]:.3f}" for c in times[1:]))
    base = times[0]
    return [Result(r, list(base), list(c), list(base.cpu), list(c.cpu)) for r, c in zip(rows, times[1:])]


def measure_all(rows: Sequence[Row], repeat: int = 5,
                log: Optional[Callable[[str], None]] = None) -> list[Result]:
    """Every row, groups together (in the order of their first row), results in row order."""
    done: dict[str, Result] = {}
    for r in rows:
        if r.name in done:
            continue
        members = [x for x in rows if r.group and x.group == r.group] or [r]
        results = measure_group(members, repeat, log) if len(members) > 1 else [measure(r, repeat, log)]
        done.update({x.row.name: x for x in results})
    return [done[r.name] for r in rows]


def format_table(results: Sequence[Result]) -> str:
    """Medians of the per-round ratios of trace wall time (``ratio``, with its spread, the
    interval that holds the true median at CONFIDENCE and the goal's verdict from it) and of
    trace CPU-seconds (``cpu ratio``); the ratio of trace instructions (``instr ratio``) where
    they were counted."""
    w = max([len(x.row.name) for x in results] + [4])
    pct = f"{CONFIDENCE:.0%} interval"
    lines = [f"{'row':<{w}}  {'baseline s':>10}  {'candidate s':>11}  {'ratio':>6}  {'spread':>13}  "
             f"{pct:>13}  {'verdict':>9}  {'cpu ratio':>9}  {'instr ratio':>11}  note", "-" * (w + 110)]
    small = None
    for x in results:
        rs = x.ratios
        lo, hi, coverage = x.interval
        if coverage < CONFIDENCE:
            small = coverage if small is None else min(small, coverage)
        cpu = f"{x.cpu_ratio:9.3f}" if x.cpu_ratio is not None else f"{'-':>9}"
        ir = x.instruction_ratio
        instr = f"{ir:11.4f}" if ir is not None else f"{'-':>11}"
        lines.append(f"{x.row.name:<{w}}  {statistics.median(x.baseline_s):10.3f}  "
                     f"{statistics.median(x.candidate_s):11.3f}  {x.ratio:6.3f}  "
                     f"{min(rs):6.3f}..{max(rs):6.3f}  {lo:6.3f}..{hi:6.3f}  {x.verdict:>9}  {cpu}  {instr}  "
                     f"{x.row.label}")
    if small is not None:
        lines.append(f"(too few rounds for a {CONFIDENCE:.0%} interval: the spread holds the median with "
                     f"probability {small:.1%}; --repeat 6 or more)")
    lines.append(f"verdict: the goal against the {pct} of the median wall ratio: met (all of it at or under "
                 "the goal), missed (all above), not shown (it holds the goal: more rounds or a quieter machine)")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("-k", dest="pattern", default="", help="only rows whose name contains this text")
    ap.add_argument("--repeat", type=int, default=5, help="baseline/candidate pairs per row (default 5)")
    ap.add_argument("--list", action="store_true", help="list the rows and exit")
    ap.add_argument("-q", "--quiet", action="store_true", help="no per-render progress")
    ap.add_argument("--instructions", choices=("auto", "all", "none"), default="auto",
                    help="count trace instructions with valgrind: for the rows that ask (auto, the "
                         "one-thread grid rows), every selected row, or none")
    args = ap.parse_args(argv)
    rows = [r for r in ROWS if args.pattern in r.name]
    if args.list:
        print("\n".join(r.name for r in rows))
        return 0
    if not rows:
        print(f"no benchmark row matches {args.pattern!r}", file=sys.stderr)
        return 2
    log = None if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    results = measure_all(rows, max(1, args.repeat), log)
    counted = [x for x in results if args.instructions == "all" or (args.instructions == "auto" and x.row.count_instructions)]
    if counted and not have_valgrind():
        print("valgrind is not installed: no instruction counts", file=sys.stderr)
    elif counted:
        count_instructions(counted, log)
    print(format_table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
