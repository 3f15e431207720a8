"""Golden-image regression renders: ``make regress`` and ``make regress-bless``.

    python -m harness.reports.regress            # render, compare, report; exit 1 on any regression
    python -m harness.reports.regress --bless    # render and rewrite the goldens; the report says what changed

The scenes live in ``scenes/regress/``: ``regress.toml`` lists them (size, what each covers,
the tables it needs), ``NAME.pov`` is the scene, ``golden/NAME.exr`` its golden image (half
float, ZIP: a few tens of kB) and ``golden/NAME.toml`` the tolerance with its reason, plus
where the golden came from (written by ``--bless``).

Every scene is rendered with the fork through :func:`harness.core.runner.render_many` (``-A``,
``+FE32``, one thread per render, ``--jobs`` renders at a time) and compared with its golden
with :func:`harness.core.compare.compare` (the new render is ``a``, the golden ``b``). A scene
fails when

* the render fails (POV's error, file and line are reported), or the golden is missing;
* the new image has NaN or Inf samples, or a different size;
* ``rel_rmse``  > ``tolerance.rel_rmse`` (the change over the whole image), or
* ``half_ulps`` > ``tolerance.half_ulps`` (the worst sample, in float16 spacings of the
  golden: an unchanged render rounds to within 0.5), or
* ``max_abs``   > ``tolerance.max_abs`` where a scene sets one.

Scenes with ``stock_check`` are also rendered by Debian's stock POV-Ray, and the fork must
agree with it to ``tolerance.stock_half_ulps`` (stock writes half floats).

The report is ``out/regress/index.html`` (golden / new / signed-difference heat map per
scene, the numbers, pass or FAIL) with ``summary.json`` beside it; ``NAME/new.exr`` keeps each
new render at full precision.
"""

from __future__ import annotations

import argparse
import datetime
import json
import re
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

from harness.core import compare as cmp
from harness.core import exr, page, runner, tables
from harness.core.paths import (REPO_ROOT, Binary, BinaryNotFound, fork_binary, git_commit, out_dir,
                                ready_tables_dir, resolve_binary, stock_binary)

SCENES_DIR = REPO_ROOT / "scenes" / "regress"
OUT_DIR = out_dir("regress")
READY_TABLES = ready_tables_dir()

#: Tolerances of a scene whose golden/NAME.toml does not set them (see DEFAULT_REASON).
DEFAULT_TOLERANCE: dict[str, float] = {"rel_rmse": 1.0e-3, "half_ulps": 1.0, "stock_half_ulps": 1.0}
DEFAULT_REASON = (
    "Default: the fork renders a scene bit-identically across runs (tests/test_determinism.py), "
    "so the only difference from the golden is its half-float storage: at most 0.5 float16 "
    "ulp per sample, rel-RMSE at most 2^-11 = 4.9e-4. The tolerances are twice that.")


# ---------------------------------------------------------------- scenes and tolerances

@dataclass
class Scene:
    """One entry of ``regress.toml``."""

    name: str
    pov: Path
    width: int
    height: int
    covers: str = ""
    tables: dict[str, list[str]] = field(default_factory=dict)
    ready_tables: list[str] = field(default_factory=list)
    stock_check: bool = False


@dataclass
class Tolerance:
    """The ``[tolerance]`` of ``golden/NAME.toml``."""

    rel_rmse: float
    half_ulps: float
    stock_half_ulps: float
    max_abs: Optional[float]
    reason: str


def load_scenes(scenes_dir: Path) -> list[Scene]:
    """The scenes of ``scenes_dir/regress.toml``, in file order."""
    manifest = scenes_dir / "regress.toml"
    if not manifest.is_file():
        raise FileNotFoundError(f"{manifest}: no regression manifest here (the scenes are scenes/regress/ of a "
                                "povray-brdf checkout; give --scenes-dir)")
    data = tomllib.loads(manifest.read_text())
    out = []
    for name, s in data.get("scene", {}).items():
        if not re.fullmatch(r"[A-Za-z0-9_-]+", name):
            raise ValueError(f"{manifest}: scene name {name!r}: use letters, digits, '_' and '-'")
        size = s.get("size")
        if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and v > 0 for v in size)):
            raise ValueError(f"{manifest}: [scene.{name}] size: expected [width, height], found {size!r}")
        pov = scenes_dir / f"{name}.pov"
        if not pov.is_file():
            raise ValueError(f"{manifest}: [scene.{name}]: {pov} does not exist")
        out.append(Scene(name, pov, size[0], size[1], s.get("covers", ""),
                         {k: [str(a) for a in v] for k, v in s.get("tables", {}).items()},
                         list(s.get("ready_tables", [])), bool(s.get("stock_check", False))))
    return out


def golden_paths(scenes_dir: Path, name: str) -> tuple[Path, Path]:
    """``(golden/NAME.exr, golden/NAME.toml)``."""
    g = scenes_dir / "golden"
    return g / f"{name}.exr", g / f"{name}.toml"


def load_tolerance(path: Path) -> Tolerance:
    """The tolerance of a scene (defaults for what its file does not set, or a missing file)."""
    t = tomllib.loads(path.read_text()).get("tolerance", {}) if path.is_file() else {}
    return Tolerance(rel_rmse=float(t.get("rel_rmse", DEFAULT_TOLERANCE["rel_rmse"])),
                     half_ulps=float(t.get("half_ulps", DEFAULT_TOLERANCE["half_ulps"])),
                     stock_half_ulps=float(t.get("stock_half_ulps", DEFAULT_TOLERANCE["stock_half_ulps"])),
                     max_abs=float(t["max_abs"]) if "max_abs" in t else None,
                     reason=str(t.get("reason", DEFAULT_REASON)).strip())


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return json.dumps(str(v))  # a basic TOML string: JSON escapes are valid TOML escapes


GOLDEN_MARK = "# Written by `make regress-bless`"


def write_golden_record(path: Path, record: dict[str, Any]) -> None:
    """Rewrite the ``[golden]`` part of ``golden/NAME.toml``, keeping the tolerance above it.

    A missing file gets the default tolerance and reason, to be reviewed by whoever adds
    the scene.
    """
    if path.is_file():
        head = path.read_text()
        cut = head.find(GOLDEN_MARK)
        if cut < 0:
            cut = head.find("[golden]")
        head = (head[:cut] if cut >= 0 else head).rstrip() + "\n"
    else:
        head = (f"# Tolerance of scenes/regress/{path.stem}.pov against golden/{path.stem}.exr: the scene\n"
                "# fails when the new render exceeds any of these (harness/reports/regress.py).\n"
                "[tolerance]\n"
                + "".join(f"{k} = {_toml_value(v)}\n" for k, v in DEFAULT_TOLERANCE.items())
                + f"reason = {_toml_value(DEFAULT_REASON)}\n")
    body = "".join(f"{k} = {_toml_value(v)}\n" for k, v in record.items())
    path.write_text(f"{head}\n{GOLDEN_MARK}: where the golden image came from.\n[golden]\n{body}")
    tomllib.loads(path.read_text())  # what we wrote must read back


# ---------------------------------------------------------------- tables

def scene_files(scene: Scene) -> dict[str, Path]:
    """Tables to stage into the scene's render directory (made and cached by brdftool)."""
    return {name: tables.cached(args, "regress") for name, args in scene.tables.items()}


def missing_ready_tables(scenes: Sequence[Scene]) -> list[str]:
    """Ready tables (build/brdf_data) that a scene needs and that are not there."""
    return sorted({t for s in scenes for t in s.ready_tables if not (READY_TABLES / t).is_file()})


# ---------------------------------------------------------------- checking

@dataclass
class Outcome:
    """What happened to one scene."""

    scene: Scene
    ok: bool
    status: str                       # pass | FAIL | error | no golden | new | changed | unchanged
    problems: list[str] = field(default_factory=list)
    stats: Optional[cmp.ErrorStats] = None
    stock_stats: Optional[cmp.ErrorStats] = None
    tolerance: Optional[Tolerance] = None
    trace_seconds: Optional[float] = None
    wall_seconds: Optional[float] = None
    images: dict[str, Path] = field(default_factory=dict)
    error: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {"scene": self.scene.name, "ok": self.ok, "status": self.status, "problems": self.problems,
                "covers": self.scene.covers, "size": [self.scene.width, self.scene.height],
                "stats": self.stats.as_dict() if self.stats else None,
                "stock_stats": self.stock_stats.as_dict() if self.stock_stats else None,
                "tolerance": vars(self.tolerance) if self.tolerance else None,
                "trace_seconds": self.trace_seconds, "wall_seconds": self.wall_seconds,
                "images": {k: str(v) for k, v in self.images.items()}, "error": self.error}


def judge(stats: cmp.ErrorStats, tol: Tolerance) -> list[str]:
    """The tolerance breaches of ``stats`` (empty: the scene passes)."""
    bad = []
    if stats.n_nan or stats.n_inf:
        bad.append(f"{stats.n_nan} NaN and {stats.n_inf} Inf samples")
    if not (stats.rel_rmse <= tol.rel_rmse):
        bad.append(f"rel_rmse {stats.rel_rmse:.3g} > {tol.rel_rmse:.3g}")
    if not (stats.half_ulps <= tol.half_ulps):
        bad.append(f"half_ulps {stats.half_ulps:.3g} > {tol.half_ulps:.3g} at (row, col) {stats.worst_pixel}")
    if tol.max_abs is not None and not (stats.max_abs <= tol.max_abs):
        bad.append(f"max_abs {stats.max_abs:.3g} > {tol.max_abs:.3g}")
    return bad


def _previews(outdir: Path, new: Optional[np.ndarray], golden: Optional[np.ndarray],
              title: str, reference: str = "golden") -> dict[str, Path]:
    outdir.mkdir(parents=True, exist_ok=True)
    imgs: dict[str, Path] = {}
    if new is not None:
        imgs["new"] = exr.write_png_preview(outdir / "new.png", new, scale=2)
        exr.write_exr(outdir / "new.exr", new)
    if golden is not None:
        imgs["golden"] = exr.write_png_preview(outdir / "golden.png", golden, scale=2)
    if new is not None and golden is not None and new.shape == golden.shape:
        imgs["diff"] = cmp.error_map_png(outdir / "diff.png", new, golden, title=title,
                                         names=("new", reference))
    return imgs


def run(scenes_dir: Path = SCENES_DIR, out_dir: Path = OUT_DIR, *, bless: bool = False,
        only: Sequence[str] = (), jobs: Optional[int] = None, binary: Optional[str] = None,
        progress: bool = True) -> list[Outcome]:
    """Render every scene (or those named in ``only``), compare or bless, write the report."""
    scenes = load_scenes(scenes_dir)
    if only:
        unknown = sorted(set(only) - {s.name for s in scenes})
        if unknown:
            raise ValueError(f"unknown scene(s) {', '.join(unknown)}; known: {', '.join(s.name for s in scenes)}")
        scenes = [s for s in scenes if s.name in only]
    missing = missing_ready_tables(scenes)
    if missing:
        raise FileNotFoundError(f"ready tables missing from {READY_TABLES}: {', '.join(missing)} (run `make brdf-data`)")
    fork = resolve_binary(binary) if binary else fork_binary()
    if fork.flavour != "fork":
        fork = Binary(fork.path, "fork")
    stock: Optional[Binary] = stock_binary() if any(s.stock_check for s in scenes) else None

    jobs_list: list[runner.RenderJob] = []
    for s in scenes:
        opts = dict(width=s.width, height=s.height, files=scene_files(s), float_exr=True, threads=1)
        jobs_list.append(runner.RenderJob(s.pov.read_text(), {**opts, "binary": fork}))
    stock_index = {}
    for s in scenes:
        if s.stock_check and stock is not None:
            stock_index[s.name] = len(jobs_list)
            jobs_list.append(runner.RenderJob(s.pov.read_text(), dict(width=s.width, height=s.height,
                                                                      files=scene_files(s), binary=stock)))
    t0 = time.perf_counter()
    results = runner.render_many(jobs_list, max_workers=jobs, progress=progress, return_exceptions=True,
                                 progress_label="regress")
    wall = time.perf_counter() - t0

    out_dir.mkdir(parents=True, exist_ok=True)
    commit = git_commit()
    outcomes: list[Outcome] = []
    for i, s in enumerate(scenes):
        res = results[i]
        gexr, gtoml = golden_paths(scenes_dir, s.name)
        tol = load_tolerance(gtoml)
        golden = exr.read_exr(gexr) if gexr.is_file() else None
        if isinstance(res, Exception):
            msg = str(res)
            if isinstance(res, runner.RenderError):
                msg = f"{res}\n{res.stderr[-1500:]}"
            o = Outcome(s, False, "error", [f"render failed: {res}"], tolerance=tol, error=msg)
            o.images = _previews(out_dir / s.name, None, golden, "")
            outcomes.append(o)
            continue
        new = res.image
        o = Outcome(s, True, "pass", tolerance=tol, trace_seconds=res.trace_seconds, wall_seconds=res.wall_seconds)
        if golden is not None and golden.shape == new.shape:
            o.stats = cmp.compare(new, golden)
        if s.name in stock_index:
            sres = results[stock_index[s.name]]
            if isinstance(sres, Exception):
                o.problems.append(f"stock render failed: {sres}")
            else:
                o.stock_stats = cmp.compare(new, sres.image)
                if o.stock_stats.half_ulps > tol.stock_half_ulps or o.stock_stats.n_nan or o.stock_stats.n_inf:
                    o.problems.append(f"fork vs stock: half_ulps {o.stock_stats.half_ulps:.3g} > "
                                      f"{tol.stock_half_ulps:.3g} at (row, col) {o.stock_stats.worst_pixel}")
        if bless:
            if golden is None:
                o.status, change = "new", "new golden"
            elif golden.shape != new.shape:
                o.status, change = "changed", f"size {golden.shape[1]}x{golden.shape[0]} -> {new.shape[1]}x{new.shape[0]}"
            else:
                within = not judge(o.stats, tol)
                o.status = "unchanged" if within else "changed"
                change = (f"{'unchanged, within tolerance' if within else 'changed'}: rel_rmse {o.stats.rel_rmse:.3g}, "
                          f"half_ulps {o.stats.half_ulps:.3g}, max_abs {o.stats.max_abs:.3g} vs the previous golden")
            o.problems.insert(0, change)
            o.images = _previews(out_dir / s.name, new, golden, f"{s.name}: new - previous golden",
                                 "previous golden")
            gexr.parent.mkdir(parents=True, exist_ok=True)
            exr.write_exr(gexr, new, half=True)
            write_golden_record(gtoml, {
                "blessed": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                "commit": commit, "binary": str(fork.path.name), "size": [s.width, s.height],
                "trace_seconds": round(res.trace_seconds or 0.0, 3), "change": change})
            o.ok = not any(p.startswith(("fork vs stock", "stock render")) for p in o.problems)
        else:
            if golden is None:
                o.ok, o.status = False, "no golden"
                o.problems.append(f"no golden image {gexr.relative_to(scenes_dir.parent) if gexr.is_relative_to(scenes_dir.parent) else gexr}"
                                  " (make regress-bless)")
            elif golden.shape != new.shape:
                o.ok, o.status = False, "FAIL"
                o.problems.append(f"size {new.shape[1]}x{new.shape[0]}, golden {golden.shape[1]}x{golden.shape[0]}")
            else:
                o.problems += judge(o.stats, tol)
            if o.problems:
                o.ok, o.status = False, ("FAIL" if o.status == "pass" else o.status)
            o.images = _previews(out_dir / s.name, new, golden, f"{s.name}: new - golden")
        outcomes.append(o)
    write_report(out_dir, outcomes, bless=bless, wall=wall, fork=fork, commit=commit)
    return outcomes


# ---------------------------------------------------------------- report

def _fmt(x: Optional[float]) -> str:
    return "" if x is None else f"{x:.3g}"


def write_report(out_dir: Path, outcomes: Sequence[Outcome], *, bless: bool, wall: float,
                 fork: Binary, commit: str) -> Path:
    """``out_dir/index.html`` (:func:`harness.core.page.write_page`) and ``out_dir/summary.json``."""
    n_bad = sum(not o.ok for o in outcomes)
    title = ("Regression goldens blessed" if bless else
             f"Regression renders: {len(outcomes) - n_bad} of {len(outcomes)} pass")
    stamp = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
    ref = "previous golden" if bless else "golden"
    notes = (f"{fork.path} at {commit}, {stamp}; {len(outcomes)} scenes in {wall:.1f} s (wall). Each render: "
             f"-A, +FE32, one thread. Difference maps: new render minus {ref}, signed, the largest of the three "
             "channels per pixel (red: the new render is brighter). half_ulps: the worst sample in float16 "
             "spacings of the golden (an unchanged render: <= 0.5). 'vs stock' compares the stock_guard scene "
             "with Debian's stock POV-Ray.")

    def status(o: Outcome) -> page.Cell:
        return page.Cell(o.status, "bless" if bless and o.ok else ("pass" if o.ok else "fail"))

    rows = []
    for o in outcomes:
        st, t = o.stats, o.tolerance
        rows.append({"scene": page.link(o.scene.name, f"#{o.scene.name}"), "result": status(o),
                     "rel_rmse": _fmt(st.rel_rmse if st else None), "rel_rmse limit": _fmt(t.rel_rmse if t else None),
                     "half_ulps": _fmt(st.half_ulps if st else None), "half_ulps limit": _fmt(t.half_ulps if t else None),
                     "max_abs": _fmt(st.max_abs if st else None),
                     "NaN/Inf": "" if not st else st.n_nan + st.n_inf,
                     "vs stock (half_ulps)": _fmt(o.stock_stats.half_ulps) if o.stock_stats else "",
                     "trace s": _fmt(o.trace_seconds),
                     "what": page.Cell(o.scene.covers, "wide"),
                     "problems": page.Cell("; ".join(o.problems), "wide")})
    sections = [page.Section("Summary", rows, anchor="summary")]
    for o in outcomes:
        body = [page.bullets(o.problems)]
        if o.stats:
            body.append(page.tag("p", str(o.stats)))
        body += [page.figure(o.images[key], out_dir, cap)
                 for key, cap in (("golden", ref), ("new", "new render"), ("diff", f"new - {ref}"))
                 if key in o.images]
        if o.tolerance:
            body.append(page.tag("p", page.small(f"Tolerance: {o.tolerance.reason}")))
        if o.error:
            body.append(page.pre(o.error))
        sections.append(page.Section(
            o.scene.name, anchor=o.scene.name, status=status(o), body=body,
            notes=f"{o.scene.covers} ({o.scene.width}x{o.scene.height}, scenes/regress/{o.scene.name}.pov)"))
    out = page.write_page(out_dir / "index.html", title, sections, notes, contents=False)
    (out_dir / "summary.json").write_text(json.dumps(
        {"bless": bless, "commit": commit, "binary": str(fork.path), "wall_seconds": wall,
         "failed": n_bad, "scenes": [o.as_dict() for o in outcomes]}, indent=1))
    return out


# ---------------------------------------------------------------- command line

def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="brdf-regress", description=__doc__.split("\n\n")[0])
    ap.add_argument("--bless", action="store_true", help="rewrite the golden images (and their [golden] records)")
    ap.add_argument("--scenes-dir", type=Path, default=SCENES_DIR, help="directory with regress.toml (default scenes/regress)")
    ap.add_argument("--out", type=Path, default=OUT_DIR, help="report directory (default out/regress)")
    ap.add_argument("--only", nargs="+", default=(), metavar="NAME", help="only these scenes")
    ap.add_argument("--jobs", type=int, default=None, help="renders at a time (default: the CPU count)")
    ap.add_argument("--binary", default=None, help="the fork binary (default: POVRAY_BRDF or build/bin/povray-brdf)")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    a = ap.parse_args(argv)
    try:
        outcomes = run(a.scenes_dir, a.out, bless=a.bless, only=a.only, jobs=a.jobs, binary=a.binary,
                       progress=not a.quiet)
    except (ValueError, FileNotFoundError, BinaryNotFound, tomllib.TOMLDecodeError) as e:
        print(f"regress: {e}", file=sys.stderr)
        return 2
    for o in outcomes:
        st = o.stats
        nums = f"rel_rmse {st.rel_rmse:.3g} half_ulps {st.half_ulps:.3g}" if st else ""
        trace = f"trace {o.trace_seconds:.2f} s" if o.trace_seconds is not None else ""
        print(f"{o.status:>9}  {o.scene.name:<20} {nums:<36} {trace}")
        for prob in o.problems:
            print(f"{'':11}{prob}")
    bad = [o for o in outcomes if not o.ok]
    report = a.out / "index.html"
    if a.bless:
        print(f"regress: blessed {len(outcomes) - len(bad)} golden(s) in {a.scenes_dir / 'golden'}; report {report}")
    else:
        print(f"regress: {len(outcomes) - len(bad)} of {len(outcomes)} pass; report {report}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
