"""Side-by-side material studies: ``make study`` (``python -m harness.reports.study STUDY.toml``).

A study file (TOML) names materials, shapes and lights; every material is rendered on every
shape under every light with the fork, and the renders go into a labelled contact sheet
(``sheet.png`` and ``index.html`` in ``out/study/<study name>/``) with each image's trace time
and the renderer's peak memory (its own peak resident set size, not the harness's:
:func:`harness.core.runner.render`), plus BRDF polar plots (:mod:`harness.tools.brdfplot`) of the
table materials. ``studies/example.toml`` documents the format; in short::

    title = "..."
    size = [160, 160]                      # pixels per render
    shapes = ["sphere", "torus", "blob"]   # presets: sphere torus blob text box
    lights = ["key", "rim"]                # presets: key rim area top

    [[material]]                           # one of: table, model, dipole, finish, pov
    name = "gold (1 deg table)"
    table = "gold.brdf"                    # build/brdf_data, or a path relative to the study
    # brdftool = ["tabulate", "lambert rho=0.5", "--step", "5"]   # makes `table` (cached)
    # model = "microfacet d=tr m=0.2 ..."  # brdf_model spec
    # dipole = "Marble"  or  dipole = { sigma_s_prime = [..], sigma_a = [..], ior = 1.3 }
    # mm_per_unit = 10                     # dipole
    # finish = "F_BRDF_Gold_Satin"  include = "brdf_metals.inc"   # a named finish
    # pov = "finish { ... }"               # raw POV text for the object (texture, finish...)
    # interpolate, scale, use_color, direction, samples: the brdf_table/brdf_model options
    # pigment = [r, g, b]                  # default 0.8 grey (used with use_color / raw POV)

    [shape.NAME] pov = "..."               # extra shapes: an object with MATERIAL where the
    [light.NAME] pov = "..."               # material goes; extra light rigs: any POV text

Renders run as local parallel jobs (:func:`harness.core.runner.render_many`, ``--jobs`` at a
time) or, with ``--scheduler ADDRESS``, on an existing Dask distributed scheduler
(``tcp://host:8786``): each render is one task (:func:`harness.reports.dask_task.render_task`) that
runs :func:`harness.core.runner.render` on a worker. The harness itself is uploaded to the
scheduler and workers (they need numpy and OpenEXR, not a checkout); the fork binary and the
study's tables must be at the same paths there as here (a shared file system or the same
checkout; ``POVRAY_BRDF`` on a worker overrides the binary path).

Faults. Each finished render is stored at once, whole (temporary file, then rename), in
``<out>/renders/<key>.npz`` (:class:`RenderStore`), the key hashing what made it: the scene
text, the binary (path, size, mtime), the options, the staged tables' contents and the
library folders' listing. A study that is killed (even SIGKILL) and run again takes up the
renders it finished (a render whose ``povray`` finished just before the kill is recovered from
its job folder ``<key>.job``, not run again) and renders only the rest; an entry that does not
read back whole with its key and the hash of its pixels is rendered again. Every renderer
runs in its own process group and dies with the harness (Linux parent-death signal). Ctrl-C
or SIGTERM kills the renderers, removes their folders and prints one line: how many of the
renders are done and where they are kept (exit 130, or 143). The output folder is checked
writable before the first render; ``summary.json``, ``index.html`` and ``sheet.png`` of an
earlier run are removed before rendering and written again (whole) only at the end,
``summary.json`` last, so a run that fails (a full disk: the message names the file) leaves
none of them. Temporary folders of killed runs (``povjob-<pid>-*``, ``.*.<pid>.*.tmp``) are
removed by the next run. With Dask, a worker that dies takes its renderers with it and its
renders are run again on another worker; with no worker left for ``--worker-wait`` seconds the
study stops and names the renders not done. (With Dask a render is kept when its result
reaches this process: one that finished on a worker just before this process was killed is
rendered again.)
"""

from __future__ import annotations

import signal
import sys

if __name__ == "__main__":  # Ctrl-C while the imports below load (seconds on a busy machine): one line
    def _early(signum: int, frame: object) -> None:
        print(f"study: interrupted ({'Ctrl-C' if signum == signal.SIGINT else signal.Signals(signum).name}) "
              "while starting; nothing was rendered", file=sys.stderr)
        sys.exit(128 + signum)

    signal.signal(signal.SIGINT, _early)
    signal.signal(signal.SIGTERM, _early)

import argparse
import hashlib
import json
import os
import re
import shutil
import tempfile
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from harness.core import exr, files, page, plotting, povwriter, runner, tables
from harness.core.paths import (REPO_ROOT, Binary, BinaryNotFound, fork_binary, in_checkout, include_dirs, out_dir,
                                ready_tables_dir)
from harness.core.progress import bar as progress_bar
from harness.tools import brdfplot

READY_TABLES = ready_tables_dir()
OUT_ROOT = out_dir("study")

#: Shape presets: POV text with MATERIAL where the material goes (about 2 units across,
#: centred 1 unit above the floor at y = 0).
SHAPES: dict[str, str] = {
    "sphere": "sphere { <0, 1, 0>, 1 MATERIAL }",
    "torus": "torus { 0.72, 0.3 rotate x * 60 rotate y * 20 translate y * 1 MATERIAL }",
    "blob": ("blob { threshold 0.55 sphere { <-0.45, 0.9, 0>, 0.85, 1 } sphere { <0.5, 1.15, 0.1>, 0.75, 1 }"
             " sphere { <0.05, 0.6, -0.35>, 0.7, 1 } cylinder { <-0.6, 1.5, 0>, <0.6, 1.6, 0>, 0.35, 1 } MATERIAL }"),
    "text": ('text { ttf "timrom.ttf" "Rg" 0.5, 0 scale 1.5 translate <-0.9, 0.35, -0.25> MATERIAL }'),
    "box": "superellipsoid { <0.25, 0.25> scale 0.75 rotate <-20, 35, 0> translate y * 1 MATERIAL }",
}

#: Light rigs: POV light sources (the camera looks at <0, 1, 0> from <0, 2.3, -5.2>).
LIGHTS: dict[str, str] = {
    "key": ("light_source { <-4, 6, -5> rgb 1 }\n"
            "light_source { <5, 2, -3> rgb <0.22, 0.24, 0.28> }"),
    "rim": ("light_source { <2.5, 4, 5> rgb 1.1 }\n"
            "light_source { <-4, 3, -5> rgb 0.25 }"),
    "area": "light_source { <-4, 6, -5> rgb 1 area_light x * 2, z * 2, 4, 4 adaptive 1 circular orient }",
    "top": "light_source { <0, 8, 0> rgb 1 }\nlight_source { <0, 2, -6> rgb 0.15 }",
}

SCENE_TEMPLATE = """#version 3.7;
// study: {material} | {shape} | {light}
global_settings {{ assumed_gamma 1.0 max_trace_level 5 }}
{includes}
camera {{ location <0, 2.3, -5.2> look_at <0, 1, 0> angle 32 right x * image_width / image_height }}
sky_sphere {{ pigment {{ gradient y color_map {{ [0 rgb <0.55, 0.6, 0.7>] [1 rgb <0.12, 0.16, 0.3>] }} }} }}
plane {{ y, 0 pigment {{ checker rgb 0.55 rgb 0.35 scale 0.5 }} finish {{ diffuse 0.8 }} }}
{lights}
{obj}
"""

class StudyError(ValueError):
    """A study file that cannot be used: the message says where and why."""

@dataclass
class Material:
    """One ``[[material]]``: its label, the POV text that goes into the object, its table."""

    name: str
    kind: str                      # table | model | dipole | finish | pov
    pov: str                       # material text placed in the object
    includes: list[str] = field(default_factory=list)
    table: Optional[Path] = None   # the .brdf file of a table material (for the polar plot)
    files: dict[str, Path] = field(default_factory=dict)
    describe: str = ""

@dataclass
class Study:
    title: str
    path: Path
    width: int
    height: int
    materials: list[Material]
    shapes: dict[str, str]
    lights: dict[str, str]

# ---------------------------------------------------------------- reading a study

def _rgb(v: Any, where: str) -> str:
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return repr(float(v))
    if isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) for x in v):
        return "<" + ", ".join(repr(float(x)) for x in v) + ">"
    raise StudyError(f"{where}: expected a number or [r, g, b], found {v!r}")

def _quote(s: str) -> str:
    if '"' in s or "\\" in s:
        raise StudyError(f"quotes and backslashes are not allowed in {s!r}")
    return f'"{s}"'

def _options(m: dict, where: str, table: bool) -> str:
    if "interpolate" in m and not table:
        raise StudyError(f"{where}: interpolate applies to table materials only")
    for key in ("scale", "direction"):
        if key in m:
            _rgb(m[key], f"{where} {key}")  # a clear study error before the writer sees it
    opts = {k: m[k] for k in ("interpolate", "scale", "use_color", "direction", "samples") if k in m}
    out = povwriter.model_options(opts)
    return (" " + " ".join(out)) if out else ""

def _material(m: dict, i: int, base: Path) -> Material:
    where = f"material {i + 1}"
    if not isinstance(m.get("name"), str) or not m["name"]:
        raise StudyError(f"{where}: every material needs a name")
    name = m["name"]
    where = f"material {i + 1} ({name})"
    kinds = [k for k in ("table", "model", "dipole", "finish", "pov") if k in m]
    if len(kinds) != 1:
        raise StudyError(f"{where}: give exactly one of table, model, dipole, finish, pov (found {kinds or 'none'})")
    kind = kinds[0]
    pigment = f"pigment {{ rgb {_rgb(m.get('pigment', 0.8), where + ' pigment')} }} "
    includes = [m["include"]] if isinstance(m.get("include"), str) else list(m.get("include", []))
    extra = m.get("extra", "")  # POV finish items added inside the finish (e.g. "specular 0.3 roughness 0.01")
    mat = Material(name, kind, "", includes)
    if kind == "table":
        tname = str(m["table"])
        if "brdftool" in m:
            args = [str(a) for a in m["brdftool"]]
            path = tables.cached(args, "study")
            stage = Path(tname).name
            mat.files[stage] = path
            mat.describe = f"brdftool {' '.join(args)}"
        elif (base / tname).is_file():
            path = (base / tname).resolve()
            stage = path.name
            mat.files[stage] = path
            mat.describe = f"table {tname}"
        elif (READY_TABLES / tname).is_file():
            path, stage = READY_TABLES / tname, tname  # found on the fork's library path
            mat.describe = f"ready table build/brdf_data/{tname}"
        else:
            raise StudyError(f"{where}: table {tname!r} not found next to the study nor in {READY_TABLES} "
                             "(run `make brdf-data`, or give brdftool = [...] to make it)")
        mat.table = path
        mat.pov = f"{pigment}finish {{ brdf_table {{ {_quote(stage)}{_options(m, where, True)} }} {extra} }}"
    elif kind == "model":
        mat.pov = f"{pigment}finish {{ brdf_model {{ {_quote(str(m['model']))}{_options(m, where, False)} }} {extra} }}"
        mat.describe = f"brdf_model {m['model']}"
    elif kind == "dipole":
        d = m["dipole"]
        mm = f" mm_per_unit {float(m.get('mm_per_unit', 10.0))!r}"
        if isinstance(d, str):
            body = f"{_quote(d)}{mm}"
            mat.describe = f"dipole preset {d}"
        elif isinstance(d, dict):
            parts = []
            for key, val in d.items():
                if key in ("sigma_s", "sigma_s_prime", "sigma_a", "anisotropy"):
                    parts.append(f"{key} {_rgb(val, where + ' ' + key)}")
                elif key in ("ior", "sample_spacing", "error_bound"):
                    parts.append(f"{key} {float(val)!r}")
                elif key == "single_scatter":
                    parts.append(f"single_scatter {'on' if val else 'off'}")
                else:
                    raise StudyError(f"{where}: unknown dipole key {key!r}")
            body = " ".join(parts) + mm
            mat.describe = "dipole " + " ".join(parts)
        else:
            raise StudyError(f"{where}: dipole is a preset name or a table of coefficients")
        coat = f" brdf_model {{ {_quote(m['coat'])} }}" if "coat" in m else ""
        mat.pov = f"finish {{ dipole {{ {body} }}{coat} {extra} }}"
    elif kind == "finish":
        f = str(m["finish"])
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", f):
            mat.pov = f"{pigment}finish {{ {f} {extra} }}"
        else:
            mat.pov = f"{pigment}{f}"  # a macro call that expands to a finish
        mat.describe = f"{f} ({', '.join(includes)})" if includes else f
    else:
        mat.pov = str(m["pov"])
        mat.describe = "POV text"
    return mat

def load_study(path: Union[str, os.PathLike]) -> Study:
    """Read and check a study file."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise StudyError(f"{path}: {e}") from None
    size = data.get("size", [160, 160])
    if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and 8 <= v <= 4096 for v in size)):
        raise StudyError(f"{path}: size: expected [width, height] in pixels, found {size!r}")
    shapes = dict(SHAPES)
    shapes.update({k: v["pov"] for k, v in data.get("shape", {}).items()})
    lights = dict(LIGHTS)
    lights.update({k: v["pov"] for k, v in data.get("light", {}).items()})
    use_shapes = data.get("shapes", ["sphere"])
    use_lights = data.get("lights", ["key"])
    for what, names, known in (("shape", use_shapes, shapes), ("light", use_lights, lights)):
        for n in names:
            if n not in known:
                raise StudyError(f"{path}: unknown {what} {n!r}; known: {', '.join(known)}")
    for n in use_shapes:
        if "MATERIAL" not in shapes[n]:
            raise StudyError(f"{path}: shape {n!r}: its POV text needs MATERIAL where the material goes")
    mats = [_material(m, i, path.parent) for i, m in enumerate(data.get("material", []))]
    if not mats:
        raise StudyError(f"{path}: no [[material]]")
    if len({m.name for m in mats}) != len(mats):
        raise StudyError(f"{path}: material names must be unique")
    return Study(str(data.get("title", path.stem)), path, size[0], size[1], mats,
                 {n: shapes[n] for n in use_shapes}, {n: lights[n] for n in use_lights})

def scene_text(study: Study, mat: Material, shape: str, light: str) -> str:
    """The .pov text of one cell."""
    inc = "\n".join(f"#include {_quote(i)}" for i in mat.includes)
    return SCENE_TEMPLATE.format(material=mat.name, shape=shape, light=light, includes=inc,
                                 lights=study.lights[light], obj=study.shapes[shape].replace("MATERIAL", mat.pov))

# ---------------------------------------------------------------- kept renders (resume)

#: Bumped when what a kept render holds changes: older entries are then not used.
STORE_VERSION = 1


class Interrupted(Exception):
    """The study was stopped by a signal (Ctrl-C, SIGTERM); ``done`` of ``total`` renders are
    kept in ``where`` and the next run of the same study takes them up."""

    def __init__(self, signum: int, done: int, total: int, where: Path) -> None:
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        super().__init__(f"interrupted ({name}): {done} of {total} renders done, kept in {where}; "
                         "run the same command again to render the rest")
        self.signum, self.done, self.total, self.where = signum, done, total, where


class _Signalled(BaseException):
    """Raised in the main thread by :func:`main`'s SIGINT/SIGTERM handler."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


_HASHES: dict[tuple[str, int, int], str] = {}


def _file_hash(path: Path) -> str:
    """sha256 of a file's bytes (remembered per path, size and mtime within this process)."""
    st = path.stat()
    k = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if k not in _HASHES:
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        _HASHES[k] = h.hexdigest()
    return _HASHES[k]


def _library_dirs(study: Study) -> list[Path]:
    """Where the fork finds tables and include files a scene names without staging them (its
    library path; a table beside the study is staged, and hashed, instead)."""
    dirs = [READY_TABLES, REPO_ROOT / "brdf_data", REPO_ROOT / "scenes" / "include"]
    return [d for d in dirs if d.is_dir()] + include_dirs()


def _library_fingerprint(study: Study) -> list[Any]:
    """Name, size and mtime of every file in the library folders (tables and include files a
    scene may name, directly or inside an include file): a change there redoes the renders."""
    out: list[Any] = []
    for d in _library_dirs(study):
        for f in sorted(d.iterdir()):
            if f.is_file():
                st = f.stat()
                out.append([str(f), st.st_size, st.st_mtime_ns])
    return out


def render_key(scene: str, binary: Binary, options: dict[str, Any], library: Sequence[Any] = ()) -> str:
    """What makes a render: the scene text, the binary (resolved path, size, mtime), the render
    options, the staged files' contents (sha256) and ``library`` (:func:`_library_fingerprint`),
    hashed. A kept render is used only under the same key."""
    b = binary.path.resolve()
    st = b.stat()
    opts = {k: v for k, v in options.items() if k not in ("files", "workdir", "tag", "binary")}
    ident = {"version": STORE_VERSION, "scene": scene, "binary": [str(b), binary.flavour, st.st_size, st.st_mtime_ns],
             "options": opts, "files": {k: _file_hash(Path(v)) for k, v in sorted(options.get("files", {}).items())},
             "library": list(library)}
    return hashlib.sha256(json.dumps(ident, sort_keys=True, default=str).encode()).hexdigest()[:32]


class RenderStore:
    """Finished renders of a study, kept in ``folder`` (``<out>/renders``) one file each,
    ``<key>.npz`` (the float image and the result's numbers), written whole; a render in
    progress runs in ``<key>.job/``. An entry is used only if it reads back whole with its key
    and the sha256 of its pixels; anything else is removed and rendered again."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder

    def entry(self, key: str) -> Path:
        return self.folder / f"{key}.npz"

    def job_dir(self, key: str) -> Path:
        return self.folder / f"{key}.job"

    def save(self, key: str, r: runner.RenderResult) -> Path:
        image = np.ascontiguousarray(r.image, dtype=np.float32)
        meta = {"key": key, "sha256": hashlib.sha256(image.tobytes()).hexdigest(), "shape": list(image.shape),
                "exr_dtype": str(np.dtype(r.exr_dtype)), "trace_seconds": r.trace_seconds,
                "parse_seconds": r.parse_seconds, "peak_memory_bytes": r.peak_memory_bytes, "stats": r.stats,
                "warnings": r.warnings, "command": r.command, "stderr": r.stderr,
                "wall_seconds": r.wall_seconds, "binary": [str(r.binary.path), r.binary.flavour],
                "pov_text": r.pov_text}
        blob = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        return files.write_whole(self.entry(key), lambda f: np.savez(f, image=image, meta=blob))

    def load(self, key: str) -> Optional[runner.RenderResult]:
        path = self.entry(key)
        if not path.is_file():
            return None
        try:
            with np.load(path, allow_pickle=False) as z:
                image = np.array(z["image"], dtype=np.float32)
                meta = json.loads(bytes(z["meta"]).decode())
            if meta["key"] != key or list(image.shape) != meta["shape"] or \
                    hashlib.sha256(np.ascontiguousarray(image).tobytes()).hexdigest() != meta["sha256"]:
                raise ValueError("key or pixels do not match")
            return runner.RenderResult(
                image=image, exr_dtype=np.dtype(meta["exr_dtype"]), trace_seconds=meta["trace_seconds"],
                parse_seconds=meta["parse_seconds"], peak_memory_bytes=meta["peak_memory_bytes"],
                stats={k: float(v) for k, v in meta["stats"].items()}, warnings=meta["warnings"],
                command=meta["command"], stderr=meta["stderr"], wall_seconds=float(meta["wall_seconds"]),
                binary=Binary(Path(meta["binary"][0]), meta["binary"][1]), pov_text=meta["pov_text"])
        except Exception:  # noqa: BLE001 - truncated, corrupt or foreign: not a finished render
            path.unlink(missing_ok=True)
            return None

    def done(self, keys: Sequence[str]) -> int:
        return sum(self.entry(k).is_file() for k in set(keys))

    def settle_jobs(self, study: Study, by_key: dict[str, runner.RenderJob], common: dict[str, Any]) -> int:
        """Keep the renders that finished in a job folder before the harness could store them
        (it was killed: :func:`harness.core.runner.result_from_job`); remove every job folder
        but one whose finished render cannot be stored now (a full disk: the next run tries
        again). Returns how many were kept."""
        kept = 0
        for d in sorted(self.folder.glob("*.job")):
            key = d.name[:-4]
            if key in by_key and not self.entry(key).is_file():
                opts = {**common, **by_key[key].options}
                r = runner.result_from_job(d, opts["binary"], opts["width"], opts["height"],
                                           opts.get("float_exr", False), opts.get("threads", 1))
                if r is not None:
                    try:
                        self.save(key, r)
                    except files.WriteError:
                        continue
                    kept += 1
            shutil.rmtree(d, ignore_errors=True)
        return kept

    def prune(self, keys: Sequence[str]) -> None:
        """Remove kept renders that are not among ``keys`` (other options, an older binary)."""
        for f in self.folder.glob("*.npz"):
            if f.stem not in set(keys):
                f.unlink(missing_ok=True)


def check_writable(folder: Path) -> None:
    """Raise :class:`StudyError` unless ``folder`` can be created and written (a real write:
    as root, permission bits say nothing; a read-only mount or a full disk still stop it)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        probe = files.write_whole(folder / f".write-test-{os.getpid()}", b"povray-brdf study\n")
        probe.unlink()
    except OSError as e:
        raise StudyError(f"the output folder {folder} is not writable ({e.strerror or e}, errno {e.errno}): "
                         "nothing was rendered; give another folder with --out, or make this one writable "
                         "(free space, remount read-write, fix its permissions)") from None


#: What the study writes from the renders; removed before a run starts (so an older run's
#: summary never stands for this one) and written again at its end, summary.json last.
DERIVED = ("summary.json", "index.html", "sheet.png")


def _invalidate(out_dir: Path) -> None:
    for name in DERIVED:
        (out_dir / name).unlink(missing_ok=True)
    for sub in ("images", "plots"):
        if (out_dir / sub).is_dir():
            shutil.rmtree(out_dir / sub)


# ---------------------------------------------------------------- rendering: local or Dask

#: The client's temporary folder (the harness zip): ``study-dask-<pid>-*``.
DASK_TMP_PREFIX = "study-dask-"


def _harness_zip(directory: Path) -> Path:
    """The ``harness`` package (its .py files) as a zip, for ``Client.upload_file``."""
    import zipfile

    out = directory / "povray_brdf_harness.zip"
    pkg = Path(__file__).resolve().parents[1]
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(pkg.rglob("*.py")):
            z.write(f, f"harness/{f.relative_to(pkg).as_posix()}")
    return out


def render_dask(jobs: Sequence[runner.RenderJob], scheduler: str, progress: bool = True,
                connect_timeout: float = 20.0, worker_wait: float = 60.0,
                on_done: Optional[Callable[[int, Union[runner.RenderResult, Exception]], None]] = None,
                labels: Optional[Sequence[str]] = None,
                **common: Any) -> list[Union[runner.RenderResult, Exception]]:
    """Render ``jobs`` as tasks of the Dask distributed scheduler at ``scheduler``; results in order.

    A failed render comes back as its exception (like ``render_many(return_exceptions=True)``);
    ``on_done(index, result)`` runs here as each one arrives. A worker that dies takes its
    renders with it (its ``povray`` dies too: :func:`harness.core.runner.render`); the scheduler
    runs them again on another worker (up to its ``allowed-failures``, then the cell fails with
    ``KilledWorker``). With no worker at all for ``worker_wait`` seconds the study stops with a
    :class:`StudyError` naming the renders not done (``labels``). Interrupted (Ctrl-C), it
    cancels its tasks and kills their renderers on the workers before raising.
    """
    try:
        from distributed import Client
        from distributed import wait as dask_wait
    except ImportError as e:  # the harness works without it; only this backend needs it
        raise StudyError("--scheduler needs Dask distributed: .venv/bin/pip install 'dask[distributed]' "
                         f"(the study extra of pyproject.toml); import failed: {e}") from None
    labels = list(labels) if labels is not None else [f"render {i + 1}" for i in range(len(jobs))]
    out: list[Union[runner.RenderResult, Exception, None]] = [None] * len(jobs)
    try:
        client = Client(scheduler, timeout=f"{connect_timeout}s")
    except (OSError, TimeoutError) as e:
        raise StudyError(f"cannot reach the Dask scheduler at {scheduler}: {e}") from None
    from harness.reports import dask_task

    fork = fork_binary()
    tag = f"study-{os.getpid()}-{time.monotonic_ns()}"
    runner.sweep_stale_jobs(prefix=DASK_TMP_PREFIX)
    with client, tempfile.TemporaryDirectory(prefix=f"{DASK_TMP_PREFIX}{os.getpid()}-") as tmp:
        # The scheduler and the workers may run elsewhere (another venv, no checkout): send
        # them this harness (a zip placed first on their sys.path); they need the fork binary
        # and the staged files at the same paths (or POVRAY_BRDF on the workers).
        # (Not to a cluster inside this process, e.g. LocalCluster(processes=False): the upload
        # would put the zip first on our own sys.path and reload our own harness from it.)
        if jobs and client.run_on_scheduler(os.getpid) != os.getpid():
            client.upload_file(str(_harness_zip(Path(tmp))), load=True)
        futures = {}
        for i, job in enumerate(jobs):
            fut = client.submit(dask_task.render_task, job.scene, {**common, **job.options}, str(fork.path), tag,
                                pure=False, key=f"povray-brdf-render-{i}-{os.getpid()}-{time.monotonic_ns()}")
            futures[fut] = i
        failed = 0
        pending = set(futures)
        no_workers_since: Optional[float] = None
        try:
            with progress_bar(len(jobs), "study (dask)", enabled=progress) as prog:
                while pending:
                    try:
                        done, _ = dask_wait(list(pending), timeout=0.5, return_when="FIRST_COMPLETED")
                    except TimeoutError:
                        done = set()
                    if not done:
                        if not client.scheduler_info().get("workers"):
                            no_workers_since = no_workers_since or time.monotonic()
                            if time.monotonic() - no_workers_since > worker_wait:
                                names = ", ".join(labels[futures[f]] for f in sorted(pending, key=futures.get))
                                raise StudyError(f"no Dask worker at {scheduler} for {worker_wait:.0f} s (they died "
                                                 f"or were stopped); {len(pending)} renders not done: {names}")
                        else:
                            no_workers_since = None
                        continue
                    for fut in done:
                        pending.discard(fut)
                        i = futures[fut]
                        try:
                            r: Union[runner.RenderResult, Exception] = fut.result()
                        except Exception as e:  # noqa: BLE001 - a failed render is reported in its cell
                            if type(e).__name__ == "KilledWorker":
                                e = RuntimeError(f"{labels[i]}: its Dask workers died while rendering it, "
                                                 f"too often to try again ({e})")
                            r = e
                            failed += 1
                            prog.set_postfix_str(f"{failed} failed", refresh=False)
                        out[i] = r
                        if on_done is not None:
                            on_done(i, r)
                        prog.update(1)
        except BaseException:
            client.cancel(list(pending))
            try:  # the cancelled tasks' threads go on; their renderers must not
                client.run(dask_task.stop, tag, wait=True)
            except Exception:  # noqa: BLE001 - a worker gone already has nothing left to stop
                pass
            raise
    return out  # type: ignore[return-value]


@dataclass
class Cell:
    material: Material
    shape: str
    light: str
    result: Union[runner.RenderResult, Exception, None] = None
    png: Optional[Path] = None


def _save_png(path: Path, image: np.ndarray) -> Path:
    import matplotlib.image as mpimg

    img = exr.to_display(image)
    return files.write_whole(path, lambda f: mpimg.imsave(f, img, format="png"))


def run(study: Study, out_dir: Path, *, jobs: Optional[int] = None, scheduler: Optional[str] = None,
        progress: bool = True, worker_wait: float = 60.0) -> dict[str, Any]:
    """Render every cell of ``study`` into ``out_dir``; write sheet.png, index.html, summary.json.

    Each finished render is kept at once in ``out_dir/renders`` (:class:`RenderStore`) and not
    rendered again by a later run with the same scene, binary, options and tables. The folder
    is checked writable first; the previous run's sheet, page and summary are removed before
    any render and written again, each whole, at the end (summary.json last). Raises
    :class:`StudyError` (a write failed: the message names the file) and :class:`Interrupted`.
    """
    fork = fork_binary()  # fail early, here, if the fork is missing
    out_dir = Path(out_dir)
    check_writable(out_dir)
    runner.sweep_stale_jobs()
    store = RenderStore(out_dir / "renders")
    for d in (out_dir, out_dir / "images", out_dir / "plots", store.folder):
        files.sweep_temps(d)
    _invalidate(out_dir)
    cells = [Cell(m, s, l) for m in study.materials for s in study.shapes for l in study.lights]
    common = dict(width=study.width, height=study.height, float_exr=True, threads=1, binary=fork)
    rjobs = [runner.RenderJob(scene_text(study, c.material, c.shape, c.light),
                              {"files": {k: str(v) for k, v in c.material.files.items()}})
             for c in cells]
    library = _library_fingerprint(study)
    keys = [render_key(j.scene, fork, {**common, **j.options}, library) for j in rjobs]
    labels = [f"{c.material.name} | {c.shape} | {c.light}" for c in cells]
    t0 = time.perf_counter()
    try:
        store.folder.mkdir(parents=True, exist_ok=True)
        recovered = store.settle_jobs(study, dict(zip(keys, rjobs)), common)
        results: list[Union[runner.RenderResult, Exception, None]] = [store.load(k) for k in keys]
        reused = sum(r is not None for r in results)
        todo = [i for i, r in enumerate(results) if r is None]
        if reused and progress:
            print(f"study: {reused} of {len(cells)} renders kept from an earlier run ({store.folder})"
                  + (f", {recovered} of them finished after it was killed" if recovered else ""), file=sys.stderr)

        def done(j: int, r: Union[runner.RenderResult, Exception]) -> None:
            i = todo[j]
            if isinstance(r, files.WriteError):
                raise r  # the job folder is on a full or read-only disk: the next one would fail too
            if isinstance(r, runner.RenderResult):
                store.save(keys[i], r)  # whole, then counted: a WriteError stops the study
            shutil.rmtree(store.job_dir(keys[i]), ignore_errors=True)

        if not todo:
            got = []
        elif scheduler:
            got = render_dask([rjobs[i] for i in todo], scheduler, progress=progress, on_done=done,
                              labels=[labels[i] for i in todo], worker_wait=worker_wait,
                              **{k: v for k, v in common.items() if k != "binary"})
        else:
            work = [runner.RenderJob(rjobs[i].scene, {**rjobs[i].options, "workdir": str(store.job_dir(keys[i]))})
                    for i in todo]
            got = runner.render_many(work, max_workers=jobs, progress=progress, return_exceptions=True,
                                     progress_label="study", on_done=done, **common)
        for i, r in zip(todo, got):
            results[i] = r
    except (KeyboardInterrupt, _Signalled) as e:
        signum = e.signum if isinstance(e, _Signalled) else signal.SIGINT
        runner.stop_renders()  # any renderer still running (render_many stopped its own)
        try:
            store.settle_jobs(study, dict(zip(keys, rjobs)), common)
        finally:
            runner.allow_renders()
        raise Interrupted(signum, store.done(keys), len(keys), store.folder) from None
    except files.WriteError as e:
        store.settle_jobs(study, dict(zip(keys, rjobs)), common)
        raise StudyError(f"{e}; {store.done(keys)} of {len(keys)} renders are done and kept in {store.folder}: "
                         "the next run renders only the rest") from None
    wall = time.perf_counter() - t0
    try:
        return _write_outputs(study, cells, results, out_dir, store, keys, wall, reused,
                              f"dask {scheduler}" if scheduler else f"local, {jobs or os.cpu_count()} jobs")
    except files.WriteError as e:
        _invalidate(out_dir)  # no partial set of pages left looking like a finished study
        raise StudyError(f"{e}; {store.done(keys)} of {len(keys)} renders are done and kept in {store.folder}: "
                         "the next run renders only the rest") from None
    except (KeyboardInterrupt, _Signalled) as e:
        _invalidate(out_dir)
        raise Interrupted(e.signum if isinstance(e, _Signalled) else signal.SIGINT, store.done(keys), len(keys),
                          store.folder) from None
    except BaseException:
        _invalidate(out_dir)
        raise


def _write_outputs(study: Study, cells: list[Cell], results: Sequence[Any], out_dir: Path, store: RenderStore,
                   keys: Sequence[str], wall: float, reused: int, backend: str) -> dict[str, Any]:
    img_dir = out_dir / "images"
    for i, (c, r) in enumerate(zip(cells, results)):
        c.result = r
        if isinstance(r, runner.RenderResult):
            c.png = _save_png(img_dir / f"{i:03d}-{page.slug(c.material.name, 40)}-{c.shape}-{c.light}.png", r.image)
    plots = polar_plots(study, out_dir / "plots")
    sheet = contact_sheet(study, cells, out_dir / "sheet.png")
    summary = {
        "title": study.title, "study": str(study.path), "backend": backend, "wall_seconds": wall,
        "complete": True, "renders": len(cells), "renders_reused": reused,
        "failed": sum(isinstance(c.result, Exception) for c in cells), "materials": len(study.materials),
        "cells": [{"material": c.material.name, "shape": c.shape, "light": c.light, "key": k,
                   "trace_seconds": getattr(c.result, "trace_seconds", None),
                   "parse_seconds": getattr(c.result, "parse_seconds", None),
                   "peak_memory_bytes": getattr(c.result, "peak_memory_bytes", None),
                   "worker_pid": (c.result.stats.get("worker_pid") if isinstance(c.result, runner.RenderResult) else None),
                   "error": str(c.result) if isinstance(c.result, Exception) else None,
                   "image": str(c.png) if c.png else None} for c, k in zip(cells, keys)],
    }
    write_html(study, cells, plots, sheet, out_dir / "index.html", summary)
    files.write_whole(out_dir / "summary.json", json.dumps(summary, indent=1))  # last: the run is complete
    store.prune(keys)
    return summary


#: Incidence angles of the study page's polar plots: three panels, 990 px, shown at that size.
POLAR_ANGLES = (0, 45, 75)


def polar_plots(study: Study, out_dir: Path) -> dict[str, Path]:
    """Polar plots (:mod:`harness.tools.brdfplot`) of every table material (name -> PNG); a
    failed plot is reported and skipped."""
    plots: dict[str, Path] = {}
    for m in study.materials:
        if m.table is None:
            continue
        try:
            plots[m.name] = brdfplot.plot(Path(m.table), out_dir / f"{page.slug(m.name, 40)}.png",
                                          theta_i=POLAR_ANGLES, title=m.name)
        except files.WriteError:
            raise
        except (OSError, ValueError) as e:
            print(f"study: plot of {m.table} failed: {e}", file=sys.stderr)
    return plots

def _cell_caption(c: Cell) -> str:
    r = c.result
    if isinstance(r, runner.RenderResult):
        t = f"{r.trace_seconds:.2f} s" if r.trace_seconds is not None else "? s"
        mb = f"{r.peak_memory_bytes / 2**20:.1f} MiB" if r.peak_memory_bytes else "? MiB"
        return f"trace {t}, {mb}"
    return "FAILED"

def contact_sheet(study: Study, cells: Sequence[Cell], path: Path) -> Path:
    """A labelled grid: one row per material, one column per (shape, light)."""
    plt = plotting.pyplot()

    cols = [(s, l) for s in study.shapes for l in study.lights]
    rows = study.materials
    cw = 1.9
    ch = cw * study.height / study.width + 0.35
    fig, axes = plt.subplots(len(rows), len(cols), figsize=(1.6 + cw * len(cols), 0.6 + ch * len(rows)),
                             squeeze=False, dpi=100)
    by_key = {(c.material.name, c.shape, c.light): c for c in cells}
    for i, m in enumerate(rows):
        for j, (s, l) in enumerate(cols):
            ax = axes[i][j]
            c = by_key[(m.name, s, l)]
            if isinstance(c.result, runner.RenderResult):
                ax.imshow(exr.to_display(c.result.image), interpolation="nearest")
            else:
                ax.text(0.5, 0.5, "render failed", ha="center", va="center", color="red", fontsize=9,
                        transform=ax.transAxes)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_xlabel(_cell_caption(c), fontsize=plotting.SMALL_PT, labelpad=2)
            if i == 0:
                ax.set_title(f"{s} / {l}", fontsize=8.5)
            if j == 0:
                ax.set_ylabel(m.name, fontsize=8, rotation=0, ha="right", va="center", labelpad=4)
    fig.suptitle(study.title, fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.98))
    path.parent.mkdir(parents=True, exist_ok=True)
    plotting.save(fig, path)
    return path

def write_html(study: Study, cells: Sequence[Cell], plots: dict[str, Path], sheet: Path, path: Path,
               summary: dict[str, Any]) -> Path:
    """index.html: one block per material (its text, then its renders, each with trace time and
    memory, and its polar plot, side by side where the window is wide enough and wrapped where
    it is not), then the contact sheet. Renders and plots are shown at their natural size."""
    base = path.parent
    cols = [(s, l) for s in study.shapes for l in study.lights]
    by_key = {(c.material.name, c.shape, c.light): c for c in cells}
    notes = (f"{len(study.materials)} materials x {len(study.shapes)} shapes x {len(study.lights)} lights = "
             f"{len(cells)} renders at {study.width}x{study.height} (-A, one thread each), "
             f"{summary['wall_seconds']:.1f} s wall, backend: {summary['backend']}; {summary['failed']} failed. "
             f"Study file: {study.path}. Under each image: POV-Ray's own trace time (seconds) and the "
             "renderer's peak memory (its peak resident set size in MiB, measured for the renderer alone: "
             "harness.core.runner). Table materials add their BRDF in the plane of incidence (1/sr).")
    blocks: list[page.Markup] = []
    for m in study.materials:
        figs = []
        for s, l in cols:
            c = by_key[(m.name, s, l)]
            if c.png:
                img = page.image(c.png, base, f"{m.name}: {s} / {l}", cls=None)
                figs.append(page.tag("figure", img, page.tag("figcaption", f"{s} / {l}", page.tag("br"),
                                                             page.text_html(_cell_caption(c)))))
            else:
                figs.append(page.tag("figure", page.tag("figcaption", f"{s} / {l}: ", page.tag("span", str(c.result)[:400],
                                                                                               class_="fail"))))
        plot = plots.get(m.name)
        if plot:
            figs.append(page.tag("figure", page.plot(plot, base, f"{m.name}: BRDF, plane of incidence"),
                                 page.tag("figcaption", "BRDF, plane of incidence (1/sr)")))
        blocks.append(page.tag("div",
                               page.tag("h3", m.name, id=f"m-{page.slug(m.name)}"),
                               page.tag("p", page.small(m.describe), page.tag("br"), page.code(m.pov)),
                               page.tag("div", *figs, class_="gallery"),
                               class_="material"))
    sections = [page.Section("Materials", anchor="materials", body=blocks),
                page.Section("Contact sheet", anchor="sheet", body=[page.plot(sheet, base, "contact sheet")])]
    return page.write_page(path, study.title, sections, notes, contents=False)

# ---------------------------------------------------------------- command line

def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="brdf-study", description=__doc__.split("\n\n")[0])
    ap.add_argument("study", type=Path, nargs="?",
                    default=REPO_ROOT / "studies" / "example.toml" if in_checkout() else None,
                    help="the study file (TOML; default: studies/example.toml of the checkout)")
    ap.add_argument("--out", type=Path, default=None, help="output directory (default out/study/<study name>)")
    ap.add_argument("--jobs", type=int, default=None, help="local renders at a time (default: the CPU count)")
    ap.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="send the renders to this Dask distributed scheduler (e.g. tcp://127.0.0.1:8786)")
    ap.add_argument("--worker-wait", type=float, default=60.0, metavar="SECONDS",
                    help="with --scheduler: stop when no Dask worker is left for this long (default 60)")
    ap.add_argument("--size", type=int, nargs=2, default=None, metavar=("W", "H"), help="override the study's size")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress line")
    a = ap.parse_args(argv)
    if a.study is None:
        ap.error("name a study file (TOML); its format: harness/reports/study.py, studies/example.toml")
    def on_signal(signum: int, frame: Any) -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # a second Ctrl-C must not cut the clean-up short
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        raise _Signalled(signum)

    handlers = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        study = load_study(a.study)
        if a.size:
            study.width, study.height = a.size
        out = a.out or OUT_ROOT / a.study.stem
        summary = run(study, out, jobs=a.jobs, scheduler=a.scheduler, progress=not a.quiet, worker_wait=a.worker_wait)
    except Interrupted as e:
        print(f"study: {e}", file=sys.stderr)
        return 128 + e.signum
    except (KeyboardInterrupt, _Signalled) as e:  # before or after the renders
        signum = e.signum if isinstance(e, _Signalled) else signal.SIGINT
        print(f"study: interrupted ({'Ctrl-C' if signum == signal.SIGINT else signal.Signals(signum).name}) "
              "before or after the renders; renders done are kept in the output folder's renders/", file=sys.stderr)
        return 128 + signum
    except (StudyError, BinaryNotFound, RuntimeError, OSError) as e:
        print(f"study: {e}", file=sys.stderr)
        return 2
    finally:
        for sig, h in handlers.items():
            signal.signal(sig, h)
    traces = [c["trace_seconds"] for c in summary["cells"] if c["trace_seconds"] is not None]
    print(f"study: {summary['materials']} materials, {summary['renders']} renders "
          f"({summary['failed']} failed, {summary['renders_reused']} kept from an earlier run) in "
          f"{summary['wall_seconds']:.1f} s wall ({summary['backend']}); trace time total {sum(traces):.1f} s")
    print(f"study: sheet {out / 'sheet.png'}; page {out / 'index.html'}")
    return 1 if summary["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
