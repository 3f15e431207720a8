"""``make report``: every finish's error and cost on one page (written by :mod:`harness.core.page`).

The finish report (``python -m harness.reports.report [--quick]``, ``make report``) writes
``out/report/index.html`` with its plots and error maps next to it, and ``report.json`` with
every number. It measures nothing itself; it runs the harness modules and lays out what they
return:

* **analytic models** (:data:`harness.reports.model_bench.MODELS`): rel-RMSE of the fork's sphere
  against the numpy model at 0/45/80/89.9 deg (:func:`harness.reports.model_bench.closed_form_errors`),
  trace time against stock ``phong`` on the bench scene (:func:`harness.reports.model_bench.cost_row`,
  :func:`harness.reports.bench.measure`);
* **tables** (:data:`harness.reports.table_error.MATERIALS` at 0.5/1/2/5 deg): rel-RMSE of the table
  against the ``brdf_model`` it tabulates (:func:`harness.reports.table_error.study`), trace time of
  the same bench scene with the table;
* **table layouts** (:data:`harness.reports.table_error.NARROW`, narrow Beckmann lobes): rel-RMSE
  against the numpy model vs bytes per RGB table, isotropic at several steps and half/difference
  at several node counts (:func:`harness.reports.table_error.layout_study`), one plot;
* **dipole** (:mod:`harness.reports.dipole_bench`): the half-lit slab's profile error against the
  closed form at several ``error_bound``, stock POV subsurface beside it, trace time against
  stock ``phong`` on the same slab;
* **edge** (:func:`harness.reports.dipole_bench.run_edge`): issue 15's shadow-edge scene, the fork
  at default and other settings against stock subsurface at several sample counts: max and rms
  profile error against the closed form and trace time (interleaved rounds, medians), as a
  speed-vs-error curve;
* **subsurface** (:mod:`harness.reports.ss_profiles`): the exact profile and the dipole against the
  harness's Monte Carlo over alpha' x g x eta (totals, Rd(r)), and the rendered slab's radiance;
* **geometry** (:func:`harness.reports.walk_bench.report_rows`): issue 31's scenes, Skin1: a shadow
  edge under slanted light, a sphere with its image beside the reference's, Rd(r) as rendered; the
  profile, the random walk and ``method auto`` against the harness's volumetric reference;
* **gonioreflectometer round trip** (:mod:`harness.reports.gonio`) and the **stability suite**
  (:mod:`harness.reports.stability`), their tables as the tests print them.

The images the modules render are recorded while they run (:func:`recording`), so the error
maps (:func:`harness.core.compare.error_map_png`) need no second render.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime
import json
import math
import os
import platform
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator, Optional, Sequence

import numpy as np

from harness.core import plotting
from harness.core.page import Section, write_page
from harness.core.paths import git_commit
from harness.core.progress import bar as progress_bar
from harness.core.progress import write as progress_write

# ---------------------------------------------------------------- the finish report

#: POV's own highlight on the bench scenes, as the inside of a finish block (the baseline).
STOCK_PHONG = "diffuse 0.6 phong 0.6 phong_size 30 specular 0.2 roughness 0.02"


@dataclass(frozen=True)
class Settings:
    """Sizes and repeats of one report run (:data:`FULL` or :data:`QUICK`)."""

    quick: bool = False
    model_size: int = 128            # sphere renders of harness.reports.model_bench (pixels)
    table_size: int = 160            # sphere renders of harness.reports.table_error
    steps: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0)
    layouts: Optional[tuple] = None  # table_error.LAYOUTS unless given (the layouts section)
    time_size: tuple[int, int] = (640, 480)   # bench scene, for trace-time ratios
    rounds: int = 3                  # timing rounds (each: every finish once between stock renders)
    dipole_width: int = 160          # half-lit slab profile (harness.reports.dipole_bench)
    dipole_time_size: tuple[int, int] = (640, 80)
    error_bounds: tuple[float, ...] = (0.1, 0.3, 0.7, 1.5)
    stock_samples: tuple[tuple[int, int], ...] = ((25, 5), (100, 20), (400, 40))
    edge_quick: bool = False         # edge scene: the four main cases only
    gonio_grid: str = "full"
    ss_alphas: tuple[float, ...] = (0.3, 0.5, 0.7, 0.9, 0.99, 0.999)  # exact profile vs dipole vs Monte Carlo
    ss_seconds: float = 45.0         # simulation per medium (harness.reports.ss_profiles.photons_for)
    timing: bool = True
    workers: int = 2                 # concurrent error renders (timing always runs alone)
    progress: bool = True            # a bar per part on stderr (harness.core.progress); -q: off


FULL = Settings()
QUICK = Settings(quick=True, model_size=64, table_size=96, rounds=1, dipole_width=80,
                 error_bounds=(0.3, 0.7, 1.5), stock_samples=((25, 5), (100, 20)),
                 gonio_grid="quick", edge_quick=True, ss_alphas=(0.5, 0.99), ss_seconds=3.0,
                 layouts=(("isotropic", 2.0), ("isotropic", 1.0), ("halfdiff", (128, 64, 32)),
                          ("halfdiff", (256, 128, 32))))
SECTIONS = ("models", "tables", "layouts", "dipole", "edge", "subsurface", "geometry", "gonio", "stability")

_rec_local = threading.local()
_rec_lock = threading.Lock()
_rec_state: dict[str, Any] = {"depth": 0, "orig": None}


@contextlib.contextmanager
def recording() -> Iterator[list]:
    """Record ``(scene, RenderResult)`` of every :func:`harness.core.runner.render` call that this
    thread makes inside the block (in order), so the report draws error maps from the renders
    a benchmark function makes, without rendering twice. ``runner.render`` is wrapped while
    any thread is inside a block; each thread sees only its own renders."""
    from harness.core import runner

    def rec(scene, *a, **kw):
        res = _rec_state["orig"](scene, *a, **kw)
        seen_here = getattr(_rec_local, "seen", None)
        if seen_here is not None:
            seen_here.append((scene, res))
        return res

    with _rec_lock:
        if _rec_state["depth"] == 0:
            _rec_state["orig"] = runner.render
            runner.render = rec
        _rec_state["depth"] += 1
    prev = getattr(_rec_local, "seen", None)
    seen: list = []
    _rec_local.seen = seen
    try:
        yield seen
    finally:
        _rec_local.seen = prev
        with _rec_lock:
            _rec_state["depth"] -= 1
            if _rec_state["depth"] == 0:
                runner.render = _rec_state["orig"]




def _error_map(*args, **kw) -> Path:
    """:func:`harness.core.compare.error_map_png`, one at a time (pyplot is not thread-safe)."""
    from harness.core.compare import error_map_png
    with plotting.LOCK:
        return error_map_png(*args, **kw)


def run_parallel(fn: Callable, items: Sequence, workers: int, label: str = "", unit: str = "item",
              progress: bool = False) -> list:
    """``[fn(x) for x in items]``, ``workers`` at a time (threads: each render is a process),
    with a progress bar ``label`` (items done, elapsed, left) when ``progress``."""
    with progress_bar(len(items), label, unit=unit, enabled=progress) as bar:
        def one(x):
            r = fn(x)
            bar.update(1)
            return r
        if workers <= 1 or len(items) <= 1:
            return [one(x) for x in items]
        with ThreadPoolExecutor(max_workers=workers) as pool:
            return list(pool.map(one, items))


# ---------------------------------------------------------------- timing

def _trace_cpu(side, row) -> float:
    """POV's trace CPU seconds (one thread) of one side of a :class:`harness.reports.bench.Row`:
    CPU time, like harness.tools.cost, so other work on a shared machine inflates it less than
    wall time."""
    from harness.core import runner
    res = runner.render(side.scene, side.binary, width=row.width, height=row.height, threads=1,
                        files=side.resolved_files())
    t = res.stats.get("trace_cpu_time", res.trace_seconds)
    if not t:
        raise RuntimeError(f"{row.name}: POV printed no trace time")
    return float(t)


def time_rows(jobs: Sequence[tuple[dict, Any]], rounds: int, log: Callable[[str], None],
              progress: bool = False) -> None:
    """Trace-time ratios for ``(entry, harness.reports.bench.Row)`` pairs, written into the entries.

    Rows with the same baseline (binary, scene, size) share it: after a warm-up render of the
    baseline and of the first candidate, every round renders ``baseline, c1 ... cN, baseline`` (the
    order reversed on alternate rounds, consecutive rounds sharing the baseline between
    them); a candidate's ratio in a round is its time over the mean of the two baselines
    around the round, and its ratio is the median over rounds. That is N + 1 renders per
    round instead of 2N for a pair per candidate (:func:`harness.reports.bench.measure`).
    """
    groups: dict[tuple, list] = {}
    for e, row in jobs:
        key = (row.baseline.binary, row.baseline.scene, row.width, row.height)
        groups.setdefault(key, []).append((e, row))
    renders = sum(3 + max(1, rounds) * (len(m) + 1) for m in groups.values())
    with progress_bar(renders, "report: timing", unit="render", enabled=progress) as bar:
        _time_groups(groups, rounds, log, bar)


def _time_groups(groups: dict[tuple, list], rounds: int, log: Callable[[str], None], bar: Any) -> None:
    """:func:`time_rows` for rows grouped by baseline; ``bar`` counts the renders."""
    def timed(side, row) -> float:
        t = _trace_cpu(side, row)
        bar.update(1)
        return t

    for members in groups.values():
        base_row = members[0][1]
        timed(base_row.baseline, base_row)  # warm-up of both binaries
        timed(members[0][1].candidate, members[0][1])
        base = [timed(base_row.baseline, base_row)]
        times: dict[int, list[float]] = {i: [] for i in range(len(members))}
        ratios: dict[int, list[float]] = {i: [] for i in range(len(members))}
        for r in range(max(1, rounds)):
            order = list(range(len(members)))
            if r % 2:
                order.reverse()
            got = {}
            for i in order:
                got[i] = timed(members[i][1].candidate, members[i][1])
            base.append(timed(base_row.baseline, base_row))
            ref = 0.5 * (base[-2] + base[-1])
            for i, t in got.items():
                times[i].append(t)
                ratios[i].append(t / ref)
            log(f"  timing round {r + 1}/{rounds}: stock {base[-1]:.3f} s, {len(members)} finishes")
        for i, (e, _) in enumerate(members):
            rs = ratios[i]
            e.update({"ratio": float(np.median(rs)), "ratio_min": min(rs), "ratio_max": max(rs),
                      "stock_s": float(np.median(base)), "finish_s": float(np.median(times[i]))})


# ---------------------------------------------------------------- errors

def model_entries(st: Settings, maps: Path, log: Callable[[str], None]) -> list[tuple[dict, Any]]:
    """Every analytic model of :data:`harness.reports.model_bench.MODELS`: errors and map; with the
    :class:`harness.reports.bench.Row` that times it (:func:`harness.reports.model_bench.cost_row`)."""
    from harness.reports import model_bench
    from harness.reference.expect import expected_image, surface_samples

    def one(item):
        i, (label, spec) = item
        with recording() as seen:
            errs = model_bench.closed_form_errors(spec, st.model_size)
        scene, res = seen[model_bench.ANGLES.index(45.0)]
        png = _error_map(maps / f"model-{i:02d}.png", res.image, expected_image(scene),
                            mask=surface_samples(scene).mask, title=f"{label}\nfork − numpy, light 45°")
        log(f"model {label}: rel-RMSE {max(errs):.1e}")
        e = {"kind": "model", "label": label, "spec": spec, "errors": errs, "rel_rmse": max(errs), "map": png,
             "ratio": None}
        row = model_bench.cost_row(spec)
        return e, dataclasses.replace(row, width=st.time_size[0], height=st.time_size[1])
    return run_parallel(one, list(enumerate(model_bench.MODELS)), st.workers, "report: models", "model", st.progress)


def table_entries(st: Settings, maps: Path, log: Callable[[str], None]) -> list[tuple[dict, Any]]:
    """Tables of :data:`harness.reports.table_error.MATERIALS` at each step, nearest and trilinear;
    trilinear ones with the bench row that times them (the bench scene with the table)."""
    from harness.reports import bench, table_error
    from harness.core import tables
    from harness.reference.expect import surface_samples

    def one(item):
        mi, (label, spec) = item
        with recording() as seen:
            rows = table_error.study(spec, st.steps, st.table_size)
        ref_scene, ref = seen[0]
        mask = surface_samples(ref_scene).mask
        out = []
        for k, r in enumerate(rows):
            scene, res = seen[1 + k]
            assert scene.finish["brdf_table"]["interpolate"] == (0 if r["interp"] == "nearest" else 1)
            png = _error_map(maps / f"table-{mi}-{r['step']:g}-{r['interp']}.png", res.image, ref.image,
                                mask=mask, relative=True,
                                title=f"{label}, {r['step']:g}° {r['interp']}\n|table − model| / model")
            e = {"kind": "table", "label": f"{label}, {r['step']:g}° {r['interp']}", "material": label,
                 "spec": spec, **r, "map": png, "ratio": None}
            row = None
            if r["interp"] == "trilinear":
                path = tables.tabulated(spec, step=r["step"], fold=True)
                cand = bench.REFERENCE_SCENE.replace(bench.STOCK_FINISH, 'finish { brdf_table { "t.brdf" } }')
                row = bench.Row(e["label"], bench.Side("stock", bench.REFERENCE_SCENE),
                                bench.Side("fork", cand, files={"t.brdf": path}),
                                width=st.time_size[0], height=st.time_size[1])
            log(f"table {e['label']}: rel-RMSE {r['rel_rmse']:.1e}")
            out.append((e, row))
        return out
    return [x for chunk in run_parallel(one, list(enumerate(table_error.MATERIALS.items())), st.workers,
                                     "report: tables", "material", st.progress) for x in chunk]


def layout_entries(st: Settings, log: Callable[[str], None]) -> list[dict]:
    """Both table layouts for every material of :data:`harness.reports.table_error.NARROW`:
    rel-RMSE against the numpy model and bytes (:func:`harness.reports.table_error.layout_study`)."""
    from harness.reports import table_error
    layouts = st.layouts or table_error.LAYOUTS

    def one(item):
        label, spec = item
        rows = table_error.layout_study(spec, layouts, st.table_size)
        for r in rows:
            log(f"layout {label}, {r['layout']} {r['resolution']}: rel-RMSE {r['rel_rmse']:.1e}, "
                f"{r['bytes'] / 1e6:.1f} MB")
        return [{"material": label, "spec": spec, **r} for r in rows]
    return [x for chunk in run_parallel(one, list(table_error.NARROW.items()), st.workers, "report: layouts", "material",
                                        st.progress) for x in chunk]


def dipole_entries(st: Settings, maps: Path, log: Callable[[str], None]) -> list[tuple[dict, Any]]:
    """The fork's dipole at several error_bound values and stock subsurface on the half-lit slab,
    each with the bench row timing it against stock phong on the same slab."""
    from harness.reports import bench, dipole_bench
    from harness.core.compare import rel_rmse
    x, want = dipole_bench.reference(st.dipole_width)
    lit = float(want[-1])
    keep = np.abs(x) >= 1.0  # dipole_bench's rule: 1 mm around the edge excluded
    slab_phong = dipole_bench.SCENE.format(globals="", pigment=1, finish=STOCK_PHONG, interior="")
    cases = [("fork", f"dipole, error_bound {eb:g}" + (" (default)" if eb == 0.7 else ""), eb,
              dipole_bench.fork_scene(eb)) for eb in st.error_bounds]
    cases += [("stock", f"stock subsurface, samples {d}, {s}", None, dipole_bench.stock_scene(d, s))
              for d, s in st.stock_samples]

    def one(item):
        i, (binary, label, eb, text) = item
        with recording() as seen:
            _, rms, mx, stderr = dipole_bench.measure(text, binary, st.dipole_width, 1)
        img = seen[-1][1].image[..., 0].astype(np.float64)
        ref = np.broadcast_to(want, img.shape)
        mask = np.broadcast_to(keep, img.shape)
        # every row of the slab sees the same profile: rows repeated 4x so the strip is readable
        png = _error_map(maps / f"dipole-{i}.png", np.repeat(img / lit, 4, axis=0),
                            np.repeat(ref / lit, 4, axis=0), mask=np.repeat(mask, 4, axis=0),
                            title=f"{label}\n(render − closed form) / lit level")
        e = {"kind": "dipole" if binary == "fork" else "stock subsurface", "label": label, "error_bound": eb,
             "binary": binary, "rel_rmse": rel_rmse(img, ref, mask), "rms_lit": rms, "max_lit": mx,
             "nodes": dipole_bench.nodes_per_lookup(stderr) if binary == "fork" else None,
             "profile": (img.mean(axis=0) - want) / lit, "map": png, "ratio": None}
        log(f"{label}: rel-RMSE {e['rel_rmse']:.1e}, rms/lit {rms:.1e}")
        row = bench.Row(label, bench.Side("stock", slab_phong), bench.Side(binary, text),
                        width=st.dipole_time_size[0], height=st.dipole_time_size[1])
        return e, row
    return run_parallel(one, list(enumerate(cases)), st.workers, "report: dipole", "case", st.progress)


def edge_entries(st: Settings, log: Callable[[str], None]) -> list[dict]:
    """The shadow-edge scene (harness.reports.dipole_bench): every case rendered in interleaved
    rounds (st.rounds; one thread), errors of the first render."""
    from harness.reports import dipole_bench
    cases = dipole_bench.edge_cases()
    if st.edge_quick:
        keep = ("fork, default", "fork, refine_levels 0", "stock, samples 25, 5", "stock, samples 50, 50")
        cases = [c for c in cases if c.label.startswith(keep)]
    dipole_bench.run_edge(cases, max(1, st.rounds), log=log)
    out = []
    for c in cases:
        out.append({"kind": "edge " + c.binary, "label": c.label, "trace_s": c.trace,
                    "cpu_s": float(np.median(c.cpu)), "max_lit": c.max_err, "rms_lit": c.rms_err,
                    "profile": c.profile, "nodes": dipole_bench.nodes_per_lookup(c.stderr) if c.binary == "fork" else None})
    return out


# ---------------------------------------------------------------- plots

def plot_speed_error(entries: Sequence[dict], path: Path) -> Optional[Path]:
    """Error vs trace-time ratio for every finish that was timed (log-log)."""
    pts = [e for e in entries if e.get("ratio") and e.get("rel_rmse") and e["rel_rmse"] > 0]
    if not pts:
        return None
    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(8.5, 5.5), dpi=100)
    models = [e for e in pts if e["kind"] == "model"]
    ax.scatter([e["ratio"] for e in models], [e["rel_rmse"] for e in models], s=28, c="tab:blue",
               label=f"analytic models ({len(models)}): vs numpy, worst of 4 lights")
    tabs = [e for e in pts if e["kind"] == "table"]
    steps = sorted({e["step"] for e in tabs})
    mats = list(dict.fromkeys(e["material"] for e in tabs))
    markers = ["s", "D", "p", "h", "v"]
    cmap = plt.get_cmap("viridis")
    colour = {s: cmap(k / max(1, len(steps) - 1) * 0.85) for k, s in enumerate(steps)}
    for e in tabs:
        ax.scatter([e["ratio"]], [e["rel_rmse"]], s=34, marker=markers[mats.index(e["material"]) % len(markers)],
                   color=colour[e["step"]])
    for s in steps:  # legend proxies: colour = step, marker = material
        ax.scatter([], [], s=34, marker="s", color=colour[s], label=f"table {s:g}° trilinear vs its model")
    for k, m in enumerate(mats):
        ax.scatter([], [], s=34, marker=markers[k % len(markers)], facecolors="none", edgecolors="0.3",
                   label=f"table of {m}")
    for kind, colour, marker, name in (("dipole", "tab:red", "^", "dipole (slab) vs closed form"),
                                       ("stock subsurface", "0.4", "x", "stock subsurface (slab)")):
        sel = [e for e in pts if e["kind"] == kind]
        if not sel:
            continue
        ax.scatter([e["ratio"] for e in sel], [e["rel_rmse"] for e in sel], s=44, marker=marker, c=colour, label=name)
        for e in sel:
            tag = f"eb {e['error_bound']:g}" if kind == "dipole" else e["label"].split("samples ")[-1]
            ax.annotate(tag, (e["ratio"], e["rel_rmse"]), textcoords="offset points", xytext=(5, 3), fontsize=plotting.SMALL_PT)
    ax.set(xscale="log", yscale="log", xlabel="trace time / stock POV phong on the same scene",
           ylabel="rel-RMSE against the expectation", title="Speed vs error, every finish")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=plotting.SMALL_PT, loc="center right")
    fig.tight_layout()
    plotting.save(fig, path)
    return path


def plot_table_steps(entries: Sequence[dict], path: Path) -> Optional[Path]:
    """rel-RMSE and max relative error of tables against their models vs the table step."""
    tabs = [e for e in entries if e["kind"] == "table"]
    if not tabs:
        return None
    plt = plotting.pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4), dpi=100)
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple"]
    for k, mat in enumerate(dict.fromkeys(e["material"] for e in tabs)):
        for interp, style in (("trilinear", "-o"), ("nearest", "--s")):
            sel = sorted((e for e in tabs if e["material"] == mat and e["interp"] == interp), key=lambda e: e["step"])
            kw = dict(color=colours[k % len(colours)], ms=4, label=f"{mat}, {interp}")
            a.plot([e["step"] for e in sel], [e["rel_rmse"] for e in sel], style, **kw)
            b.plot([e["step"] for e in sel], [e["max_rel_bright"] for e in sel], style, **kw)
    steps = sorted({e["step"] for e in tabs})
    for ax, what in ((a, "rel-RMSE over the sphere"), (b, "max rel. error, pixels > 5 % of peak")):
        ax.set(xscale="log", yscale="log", xlabel="table step (degrees)", ylabel=what)
        ax.set_xticks(steps)
        ax.set_xticklabels([f"{s:g}" for s in steps])
        ax.minorticks_off()
        ax.grid(True, which="both", alpha=0.25)
    a.set_title("Table vs the model it tabulates")
    b.set_title("Worst pixel")
    handles, labels = a.get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=plotting.SMALL_PT, loc="lower center", ncol=3)
    fig.tight_layout(rect=(0, 0.11, 1, 1))
    plotting.save(fig, path)
    return path


def plot_layouts(rows: Sequence[dict], path: Path) -> Optional[Path]:
    """rel-RMSE against the model vs bytes per RGB table: one colour per material, one line per
    layout (isotropic steps: circles; half/difference node counts: squares; MERL's own
    90 x 90 x 180 grid, which spends its nodes differently: triangles), the issue's goal marked."""
    from harness.reports.table_error import GOAL_BYTES, GOAL_REL_RMSE
    if not rows:
        return None
    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(8.5, 5.5), dpi=100)
    colours = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
    merl = "90×90×180"
    series = (("isotropic", lambda r: r["layout"] == "isotropic", "-o", "isotropic (θi, θr, φ) at the step shown"),
              ("halfdiff", lambda r: r["layout"] == "halfdiff" and r["resolution"] != merl, "--s",
               "half/difference, θh × θd × φd nodes"),
              ("merl", lambda r: r["resolution"] == merl, "^", "half/difference, MERL's 90×90×180 grid"))
    mats = list(dict.fromkeys(r["material"] for r in rows))
    for k, mat in enumerate(mats):
        for _, pick, style, _ in series:
            sel = sorted((r for r in rows if r["material"] == mat and pick(r)), key=lambda r: r["bytes"])
            if sel:
                ax.plot([r["bytes"] / 1e6 for r in sel], [r["rel_rmse"] for r in sel], style, ms=4,
                        color=colours[k % len(colours)])
    for r in rows:  # resolution labels along the first material's curves
        if r["material"] == mats[0]:
            ax.annotate(r["resolution"], (r["bytes"] / 1e6, r["rel_rmse"]), textcoords="offset points",
                        xytext=(4, 4), fontsize=plotting.SMALL_PT, color="0.3")
    for k, mat in enumerate(mats):  # legend: colour = material, style = layout
        ax.plot([], [], "-", color=colours[k % len(colours)], label=mat)
    for _, _, style, name in series:
        ax.plot([], [], style, color="0.3", ms=4, label=name)
    ax.axhline(GOAL_REL_RMSE, color="0.4", lw=0.8, ls=":")
    ax.axvline(GOAL_BYTES / 1e6, color="0.4", lw=0.8, ls=":")
    ax.annotate(f"goal: ≤ {GOAL_REL_RMSE:.1%} at ≤ {GOAL_BYTES / 1e6:g} MB", (GOAL_BYTES / 1e6, GOAL_REL_RMSE),
                textcoords="offset points", xytext=(4, 4), fontsize=plotting.SMALL_PT, color="0.3")
    ax.set(xscale="log", yscale="log", xlabel="bytes per RGB table (MB)",
           ylabel="rel-RMSE of the sphere against the numpy model",
           title="Table layouts for narrow lobes: isotropic (θi, θr, φ) vs half/difference (θh, θd, φd)")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=plotting.SMALL_PT, ncol=2, loc="lower left")
    fig.tight_layout()
    plotting.save(fig, path)
    return path


def plot_dipole(entries: Sequence[dict], width: int, path: Path) -> Optional[Path]:
    """Profile error across the shadow edge, and rms error vs cost, fork dipole and stock."""
    from harness.reports import dipole_bench
    dips = [e for e in entries if e["kind"] in ("dipole", "stock subsurface")]
    if not dips:
        return None
    plt = plotting.pyplot()
    x, _ = dipole_bench.reference(width)
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4), dpi=100)
    cmap = plt.get_cmap("autumn")
    forks = [e for e in dips if e["kind"] == "dipole"]
    for k, e in enumerate(dips):
        colour = cmap(k / max(1, len(forks))) if e["kind"] == "dipole" else f"{0.2 + 0.2 * (k - len(forks))}"
        a.plot(x, e["profile"], lw=1.2 if e["kind"] == "dipole" else 0.9, color=colour, label=e["label"],
               ls="-" if e["kind"] == "dipole" else ":")
    a.axvspan(-1.0, 1.0, color="0.9", zorder=0)
    a.set(xlabel="x (mm), shadow for x < 0", ylabel="(render − closed form) / lit level",
          title="Half-lit slab: profile error (grey: excluded)")
    a.set_ylim(-0.1, 0.1)
    a.grid(True, alpha=0.3)
    a.legend(fontsize=plotting.SMALL_PT, loc="lower left")
    for kind, colour, marker in (("dipole", "tab:red", "^-"), ("stock subsurface", "0.4", "x--")):
        sel = [e for e in dips if e["kind"] == kind and e.get("ratio")]
        if not sel:
            continue
        b.plot([e["ratio"] for e in sel], [e["rms_lit"] for e in sel], marker, color=colour, label=kind)
        for e in sel:
            tag = f"eb {e['error_bound']:g}" if kind == "dipole" else e["label"].split("samples ")[-1]
            b.annotate(tag, (e["ratio"], e["rms_lit"]), textcoords="offset points", xytext=(4, 3), fontsize=plotting.SMALL_PT)
    b.set(xscale="log", yscale="log", xlabel="trace time / stock phong on the slab",
          ylabel="rms profile error / lit level", title="Speed vs error on the slab")
    b.grid(True, which="both", alpha=0.25)
    if b.lines:
        b.legend(fontsize=plotting.SMALL_PT)
    fig.tight_layout()
    plotting.save(fig, path)
    return path


def plot_edge(entries: Sequence[dict], path: Path) -> Optional[Path]:
    """Issue 15's edge scene: profile error across the edge, and max error vs trace time."""
    from harness.reports import dipole_bench
    edges = [e for e in entries if e["kind"].startswith("edge ")]
    if not edges:
        return None
    plt = plotting.pyplot()
    x, _ = dipole_bench.edge_reference(dipole_bench.EDGE_WIDTH)
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2), dpi=100)
    shown = [e for e in edges if e["label"].startswith(("fork, default", "fork, refine_levels 0", "stock, samples 50, 50"))]
    for e, colour in zip(shown, ("tab:red", "tab:orange", "0.3")):
        a.plot(x, e["profile"][1], lw=1.1, color=colour, label=e["label"])  # green channel
    a.set(xlabel="x (mm), shadow for x > 0", ylabel="(render − closed form) / lit plateau (green)",
          title="Shadow edge: profile error", xlim=(-6, 6))
    a.grid(True, alpha=0.3)
    a.legend(fontsize=plotting.SMALL_PT, loc="lower left")
    for kind, colour, marker in (("edge fork", "tab:red", "^"), ("edge stock", "0.35", "x")):
        sel = [e for e in edges if e["kind"] == kind]
        if not sel:
            continue
        b.scatter([e["trace_s"] for e in sel], [e["max_lit"] for e in sel], marker=marker, color=colour,
                  label="fork dipole" if kind == "edge fork" else "stock subsurface")
        for e in sel:
            tag = e["label"].split(", ", 1)[1].split(" (")[0]
            b.annotate(tag, (e["trace_s"], e["max_lit"]), textcoords="offset points", xytext=(4, 3), fontsize=plotting.SMALL_PT)
    b.axhline(0.03, color="tab:green", lw=0.8, ls="--", label="3 % (issue 15)")
    b.set(xscale="log", yscale="log", xlabel="trace time (s, one thread, precompute included)",
          ylabel="max profile error / lit plateau", title="Speed vs error on the edge scene")
    b.grid(True, which="both", alpha=0.25)
    b.legend(fontsize=plotting.SMALL_PT)
    fig.tight_layout()
    plotting.save(fig, path)
    return path


# ---------------------------------------------------------------- assembly

def _fmt_ratio(e: dict) -> Any:
    if e.get("ratio") is None:
        return "–"
    if e["ratio_min"] == e["ratio_max"]:
        return f"{e['ratio']:.2f}"
    return f"{e['ratio']:.2f} ({e['ratio_min']:.2f}..{e['ratio_max']:.2f})"


def headline_rows(entries: Sequence[dict]) -> list[dict]:
    """One row per finish: error against its expectation and trace ratio (trilinear tables only)."""
    rows = []
    for e in entries:
        if e["kind"] == "table" and e["interp"] != "trilinear":
            continue
        what = {"model": "vs numpy model, worst of 4 lights", "table": "vs brdf_model of its spec",
                "dipole": "vs closed-form slab profile", "stock subsurface": "vs closed-form slab profile"}[e["kind"]]
        rows.append({"kind": e["kind"], "finish": e["label"], "rel-RMSE": e["rel_rmse"], "against": what,
                     "trace / stock phong": _fmt_ratio(e), "error map": e["map"]})
    return rows


def markdown(entries: Sequence[dict]) -> str:
    lines = ["| kind | finish | rel-RMSE | trace / stock phong |", "|---|---|---|---|"]
    for r in headline_rows(entries):
        lines.append(f"| {r['kind']} | {r['finish']} | {r['rel-RMSE']:.1e} | {r['trace / stock phong']} |")
    return "\n".join(lines)


def jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, (np.floating, np.integer)):
        return v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    return v


def build(out_dir: Path, st: Settings, sections: Sequence[str] = SECTIONS,
          log: Callable[[str], None] = lambda s: None) -> Path:
    """Run the selected parts and write ``out_dir/index.html`` (+ plots, maps, report.json)."""
    from harness.reports import gonio, stability
    t0 = time.perf_counter()
    load0 = os.getloadavg()[0]
    out_dir = Path(out_dir)
    maps = out_dir / "maps"
    maps.mkdir(parents=True, exist_ok=True)
    jobs: list[tuple[dict, Any]] = []
    if "models" in sections:
        jobs += model_entries(st, maps, log)
    if "tables" in sections:
        jobs += table_entries(st, maps, log)
    if "dipole" in sections:
        jobs += dipole_entries(st, maps, log)
    entries = [e for e, _ in jobs]
    layout_rows = layout_entries(st, log) if "layouts" in sections else []
    if st.timing:
        time_rows([(e, row) for e, row in jobs if row is not None], st.rounds, log, st.progress)
    edges = edge_entries(st, log) if "edge" in sections else []
    ss_rows, ss_renders = [], []
    if "subsurface" in sections:
        from harness.reports import ss_profiles
        ss_rows = ss_profiles.grid(st.ss_alphas, seconds=st.ss_seconds, log=log)
        ss_renders = ss_profiles.render_rows(ss_rows, log=log)
    geo_rows = []
    if "geometry" in sections:
        from harness.reports import walk_bench
        log("subsurface in real geometry (walk_bench): edge, Rd(r), sphere")
        geo_rows = walk_bench.report_rows(st.quick)
    gonio_points = (gonio.measure(gonio.FULL if st.gonio_grid == "full" else gonio.QUICK, progress=st.progress)
                    if "gonio" in sections else [])
    stab = stability.run(log=log, progress=st.progress) if "stability" in sections else []
    wall = time.perf_counter() - t0
    load1 = os.getloadavg()[0]

    pages: list[Section] = []
    if entries:
        scatter = plot_speed_error(entries, out_dir / "speed_vs_error.png")
        pages.append(Section(
            "Every finish: error and cost", headline_rows(entries), anchor="headline",
            notes=("rel-RMSE = sqrt(mean((render − expected)²)) / sqrt(mean(expected²)) over the object's pixels, "
                   "every colour channel a sample (harness.core.compare.rel_rmse). Analytic models: the fork's sphere "
                   "against the numpy model (harness.reference.models), the worst of four lights (0, 45, 80, 89.9° from the "
                   "view); float32 rounding is about 3e-8. Tables: trilinear lookup against the brdf_model of the "
                   "spec it tabulates (nearest lookups in the table section). Dipole: the half-lit slab against "
                   "the closed-form half-plane exitance, 1 mm around the shadow edge excluded.\n\n"
                   "trace / stock phong: POV's trace CPU seconds (one thread) of the finish over stock POV-Ray's "
                   "on the same scene with its own highlight (" + STOCK_PHONG + "); after a warm-up, each of "
                   f"{st.rounds} round(s) renders every finish once between two stock renders, a ratio is over the "
                   "mean of those two, and the table shows the median over rounds (min..max in brackets). Ratios "
                   "from one round on a shared two-core machine move by 10-20 %; make bench measures longer. "
                   "Models and tables: the bench scene (9 spheres "
                   f"and a reflective plane, {st.time_size[0]}×{st.time_size[1]}); dipole and stock subsurface: the "
                   f"slab ({st.dipole_time_size[0]}×{st.dipole_time_size[1]}), where stock phong takes a few "
                   "milliseconds and the dipole's time includes sampling the object."),
            images=[("speed vs error", scatter)] if scatter else []))
    models = [e for e in entries if e["kind"] == "model"]
    if models:
        from harness.reports.model_bench import ANGLES
        rows = [{"model": e["label"], "spec": e["spec"],
                 **{f"rel-RMSE {a:g}°": v for a, v in zip(ANGLES, e["errors"])},
                 "trace / stock phong": _fmt_ratio(e), "finish s": e.get("finish_s", "–"),
                 "stock s": e.get("stock_s", "–"), "error map (45°)": e["map"]} for e in models]
        pages.append(Section("Analytic models (harness.reports.model_bench)", rows, anchor="models",
                             notes=f"Sphere {st.model_size}×{st.model_size}, orthographic, one distant light per "
                                   "render, float EXR. The error maps show the signed difference fork − numpy "
                                   "(light at 45°)."))
    tabs = [e for e in entries if e["kind"] == "table"]
    if tabs:
        steps_png = plot_table_steps(entries, out_dir / "table_steps.png")
        rows = [{"material": e["material"], "step °": e["step"], "lookup": e["interp"], "rel-RMSE": e["rel_rmse"],
                 "max rel. (>5 % peak)": e["max_rel_bright"], "file MB": e["bytes"] / 1e6,
                 "trace / stock phong": _fmt_ratio(e), "error map": e["map"]} for e in tabs]
        pages.append(Section("BRDF tables vs the models they tabulate (harness.reports.table_error)", rows, anchor="tables",
                             notes=f"Sphere {st.table_size}×{st.table_size} under three lights (0°, 45°, 80°); "
                                   "reference: the same spec as brdf_model, rendered by the fork. Tables are "
                                   "reciprocity-folded (brdftool tabulate --fold). Error maps: |table − model| / "
                                   "model per pixel.",
                             images=[("error vs table step", steps_png)] if steps_png else []))
    if layout_rows:
        from harness.reports.table_error import GOAL_BYTES, GOAL_REL_RMSE
        lpng = plot_layouts(layout_rows, out_dir / "table_layouts.png")
        rows = [{"material": r["material"], "layout": r["layout"], "nodes / step": r["resolution"],
                 "MB": r["bytes"] / 1e6, "rel-RMSE": r["rel_rmse"],
                 "goal": "yes" if r["rel_rmse"] <= GOAL_REL_RMSE and r["bytes"] <= GOAL_BYTES else ""}
                for r in layout_rows]
        pages.append(Section("Table layouts for narrow lobes: error vs memory (harness.reports.table_error --layouts)",
                             rows, anchor="layouts",
                             notes=f"Sphere {st.table_size}×{st.table_size} under three lights (0°, 45°, 80°); "
                                   "reference: the numpy model (harness.reference.models), not the fork. Isotropic "
                                   "tables at the step shown, reciprocity-folded; half/difference tables (layout 3, "
                                   "brdf_data/README.md) with θh × θd × φd nodes (90×90×180 is MERL's grid, "
                                   "256×128×32 brdftool's default). MB: the file (payload + header), the bytes "
                                   "a loaded RGB table holds. Goal (issue 16): rel-RMSE ≤ "
                                   f"{GOAL_REL_RMSE:.1%} at ≤ {GOAL_BYTES / 1e6:g} MB.",
                             images=[("error vs memory, both layouts", lpng)] if lpng else []))
    dips = [e for e in entries if e["kind"] in ("dipole", "stock subsurface")]
    if dips:
        dpng = plot_dipole(entries, st.dipole_width, out_dir / "dipole.png")
        rows = [{"renderer": e["label"], "rel-RMSE": e["rel_rmse"], "rms / lit": e["rms_lit"],
                 "max / lit": e["max_lit"], "nodes / lookup": "–" if e["nodes"] is None else e["nodes"],
                 "trace / stock phong": _fmt_ratio(e), "finish s": e.get("finish_s", "–"),
                 "stock phong s": e.get("stock_s", "–"), "error map": e["map"]} for e in dips]
        pages.append(Section("Dipole subsurface vs stock subsurface (harness.reports.dipole_bench)", rows, anchor="dipole",
                             notes="Half-lit slab: sigma_s' = 1/mm, sigma_a = 0.05/mm, eta = 1.3, lit from above, "
                                   f"shadowed for x < 0; {st.dipole_width}×20 pixels across 20 mm. Stock POV "
                                   "subsurface is set up as harness.reports.dipole_bench documents (its half-float EXR "
                                   "adds ~5e-4).",
                             images=[("dipole: profile error and speed vs error", dpng)] if dpng else []))
    if edges:
        epng = plot_edge(edges, out_dir / "edge.png")
        stock_default = next((e["trace_s"] for e in edges if "(stock default)" in e["label"]), float("nan"))
        rows = [{"renderer": e["label"], "max / lit": e["max_lit"], "rms / lit": e["rms_lit"],
                 "trace s": e["trace_s"], "trace CPU s": e["cpu_s"],
                 "stock samples 50, 50 / this": stock_default / e["trace_s"],
                 "nodes / lookup": "–" if e["nodes"] is None else e["nodes"]} for e in edges]
        pages.append(Section("Dipole at a shadow edge vs stock subsurface (issue 15; harness.reports.dipole_bench)",
                             rows, anchor="edge",
                             notes="A 200 × 200 × 50 mm marble slab (Jensen 2001, mm_per_unit 1) under a parallel light "
                                   "from normalize(1, 0, 1); a black plate casts a sharp shadow edge along x = 0; "
                                   "orthographic view of [−16, 16]² mm, 256², one thread. Row-averaged profile against "
                                   "the closed-form half-plane dipole plus single scattering, per channel as a fraction "
                                   "of its lit plateau, every pixel counted, worst channel. Stock subsurface is set up "
                                   "as harness.reports.dipole_bench documents (its own Rd fit: a different model, hence "
                                   "its plateau error). Trace time: POV's own (wall, precompute included), median of "
                                   f"{max(1, st.rounds)} interleaved round(s); on a shared machine the CPU column is "
                                   "steadier.",
                             images=[("edge scene: profile error and speed vs error", epng)] if epng else []))
    if ss_rows:
        from harness.reports import ss_profiles
        tpng = ss_profiles.plot_totals(ss_rows, out_dir / "ss_totals.png")
        ppng = ss_profiles.plot_profiles(ss_rows, out_dir / "ss_profiles.png")
        rows = [{"medium": r.case.label(), "MC total": r.mc_total, "MC se": r.mc_total_err,
                 "exact total err": r.exact_total_err, "dipole total err": r.dipole_total_err,
                 "exact max |Rd(r) err|": r.exact_rd_max, "dipole max |Rd(r) err|": r.dipole_rd_max,
                 "r compared (mfp')": f"{r.covered[0]:.2g}-{r.covered[1]:.2g} ({len(r.rd_radii)})",
                 "photons": r.photons} for r in ss_rows]
        pages.append(Section("Subsurface: exact profile vs dipole vs Monte Carlo (harness.reports.ss_profiles)", rows,
                             anchor="subsurface",
                             notes="Reference: the harness's own photon migration (harness.reference.mc_subsurface, no code "
                                   "shared with the library). Exact total = the tables' multiple scattering + the exact "
                                   "single-scattering albedo; the dipole's Rd against the reference's total. Rd(r): "
                                   "annulus means over [0.1, 31.6] mfp' (4 bins a decade) where the reference's relative "
                                   "error is below 2.5 % (multiple scattering for the exact profile, all orders for the "
                                   "dipole). Errors are relative.",
                             images=[("total reflectance vs Monte Carlo", tpng), ("Rd(r)", ppng)]))
        pages.append(Section("Subsurface: rendered slab at default settings vs Monte Carlo radiance", ss_renders,
                             anchor="subsurface-renders",
                             notes="An 800 x 800 x 400 mfp' slab, lit by a parallel light at normal incidence, orthographic "
                                   "camera at the view cosine; pixel = pi L against the reference's next-event radiance "
                                   "times the entering Fresnel factor. 'exact' is the default finish, 'dipole' `profile "
                                   "dipole` (single scattering off, its default)."))
    if geo_rows:
        from harness.reports import walk_bench
        images = [(title, png) for title, png in (
            ("shadow edge under slanted light: every method against the reference",
             walk_bench.plot_edges(geo_rows, out_dir / "geometry_edge.png")),
            ("sphere: the reference and each method side by side, and their errors",
             walk_bench.plot_spheres(geo_rows, out_dir / "geometry_sphere.png")),
            ("Rd(r) as rendered", walk_bench.plot_rd(geo_rows, out_dir / "geometry_rd.png"))) if png]
        pages.append(Section("Subsurface in real geometry: profile, random walk and auto vs exact transport "
                             "(issue 31; harness.reports.walk_bench)", walk_bench.summary(geo_rows), anchor="geometry",
                             notes="Jensen's Skin1 (g 0, mm_per_unit 1), every method at its defaults but the walk's "
                                   "samples, against harness.reference.volume_ref (a numpy photon tracer sharing no "
                                   "code with the library). Shadow edge: a block under parallel light past a black "
                                   "plate's edge, ior 1.3, row-averaged profile, max |error| as a fraction of the lit "
                                   "plateau. Sphere: radius 3 diffusion lengths, ior 1, light from normalize(1, 0.5, 1), "
                                   "camera from +z: flux and per-pixel rms. Rd(r): a half-space lit through a hole of "
                                   "radius 0.5 mfp', annulus means 1-30 mfp' (each channel in its own). Trace time: "
                                   "POV's own, two threads. python -m harness.reports.walk_bench runs the full grid "
                                   "(every preset, ior, g, sheets).",
                             images=images))
    if gonio_points:
        gpng = gonio.plot(gonio_points, out_dir / "gonio.png")
        pages.append(Section("Gonioreflectometer round trip (harness.reports.gonio)", gonio.summary(gonio_points),
                             anchor="gonio",
                             notes=f"A {gonio.STEP:g}° RGB table of '{gonio.SPEC}' rendered on the virtual "
                                   "gonioreflectometer (FlatSampleScene, one direction pair per render) and "
                                   "re-measured as f = pixel / (π cos θi E). On-node angles must give the stored "
                                   "values, off-node angles their trilinear interpolation; 'table vs model' is the "
                                   "table's own interpolation error, for scale.",
                             images=[("round-trip error per geometry", gpng)]))
    if stab:
        pages.append(Section("Stability suite (harness.reports.stability, tests/test_stability.py)",
                             [r.row() for r in stab], anchor="stability",
                             notes="Each case rendered by the fork; NaN, Inf and negative samples counted over the "
                                   "whole image; the error against its limit where the case has one."))
    notes = (f"{'Quick' if st.quick else 'Full'} run (python -m harness.reports.report{' --quick' if st.quick else ''}), "
             f"{datetime.datetime.now().strftime('%Y-%m-%d %H:%M')}, commit {git_commit()}, "
             f"{os.cpu_count()} CPUs, {platform.system()} {platform.machine()}, {wall:.0f} s; load average "
             f"{load0:.1f} at the start, {load1:.1f} at the end (other work on the machine skews the timings).")
    page = write_page(out_dir / "index.html", "povray-brdf: finishes against their expectations", pages, notes)
    dump = {"settings": dataclasses.asdict(st), "wall_s": wall, "entries": entries, "layouts": layout_rows,
            "edge": edges, "subsurface": [dataclasses.asdict(r) for r in ss_rows], "subsurface_renders": ss_renders,
            "geometry": geo_rows,
            "gonio": [dataclasses.asdict(p) for p in gonio_points],
            "stability": [dataclasses.asdict(r) for r in stab]}
    (out_dir / "report.json").write_text(json.dumps(jsonable(dump), indent=1, allow_nan=False))
    if entries:
        print(markdown(entries))
    if layout_rows:
        print("\n| material | layout | nodes / step | MB | rel-RMSE |\n|---|---|---|---|---|")
        for r in layout_rows:
            print(f"| {r['material']} | {r['layout']} | {r['resolution']} | {r['bytes'] / 1e6:.1f} | {r['rel_rmse']:.2e} |")
    if gonio_points:
        print("\n" + gonio.markdown(gonio_points))
    if stab:
        print("\n" + stability.markdown(stab))
    print(f"\nreport: {page} ({wall:.0f} s)")
    return page


def main(argv: Optional[Sequence[str]] = None) -> int:
    from harness.core.paths import out_dir
    ap = argparse.ArgumentParser(prog="brdf-report",
                                 description="Every finish's error against its expectation and cost against stock "
                                             "phong, as one HTML page (out/report/index.html).")
    ap.add_argument("--quick", action="store_true", help="CI-size renders, one timing pair, quick gonio grid")
    ap.add_argument("-o", "--out", type=Path, default=out_dir("report"), help="output directory (default out/report)")
    ap.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated parts (default {','.join(SECTIONS)})")
    ap.add_argument("--rounds", type=int, help="timing rounds (default 3, quick 1)")
    ap.add_argument("--no-time", action="store_true", help="errors only, no trace-time ratios")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress bars or log lines on stderr")
    args = ap.parse_args(argv)
    parts = [p.strip() for p in args.only.split(",") if p.strip()]
    bad = [p for p in parts if p not in SECTIONS]
    if bad:
        ap.error(f"unknown part(s) {bad}; known: {', '.join(SECTIONS)}")
    st = QUICK if args.quick else FULL
    if args.rounds is not None:
        st = dataclasses.replace(st, rounds=max(1, args.rounds))
    if args.no_time:
        st = dataclasses.replace(st, timing=False)
    if args.quiet:
        st = dataclasses.replace(st, progress=False)
    build(args.out, st, parts, (lambda s: None) if args.quiet else progress_write)
    return 0


if __name__ == "__main__":
    sys.exit(main())
