#!/usr/bin/env python3
"""make mutate: does every test that should catch a small bug catch it?

Each mutation of ``mk/mutations.toml`` (a fixed, documented list) changes one thing in a
scratch copy of the shading library (``build/mutate/src/shading``, built incrementally with
ninja in ``build/mutate/shading``) or of the Python harness (``build/mutate/py``): a constant
off by 1 %, swapped arguments, an off-by-one index, a dropped cosine, a sign. Then:

1. C++ mutations: the unit tests (``shading_tests --gtest_fail_fast``) run first; if they
   catch it, that is the answer. Otherwise the fork is relinked against the mutated library
   (``build/mutate/bin/povray-brdf``, POV-Ray's own objects and link line) and the mutation's
   fast pytest targets run against it (``POVRAY_BRDF``, ``BRDFTOOL``, ``SSTOOL`` point at the
   scratch binaries, ``POVRAY_BRDF_CACHE`` at a cache emptied for every mutation), stopping at
   the first failure (``-x``).
2. Python mutations (files under ``harness/``): the pytest targets run in a scratch tree whose
   ``harness/`` is the mutated copy; the fork, brdftool and the ready tables are the real ones.

A mutation is *caught* when a test fails (or crashes, or times out), *missed* when all pass.
Before the first mutation the unmutated scratch build runs the same tests (the baseline): a
failure there is an error of the set-up, not a catch. The tool prints one line per mutation
(caught by which test, or MISSED, and its time), writes ``build/mutate/report.txt`` and
``report.json``, and exits 1 if any mutation is missed, does not apply (its text is not found
exactly once) or does not compile.

``build/`` of the checkout is never written, except ``build/mutate/``; ``shading/`` and
``harness/`` are only read.

Usage: ``python mk/mutate.py [--only ID ...] [--no-baseline] [--list]`` (``make mutate``,
``MUTATE_ONLY="id ..."``).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

TOP = Path(__file__).resolve().parents[1]
MUTATIONS = TOP / "mk" / "mutations.toml"
SCRATCH = TOP / "build" / "mutate"
SRC = SCRATCH / "src" / "shading"
BLD = SCRATCH / "shading"
BIN = SCRATCH / "bin" / "povray-brdf"
PYTREE = SCRATCH / "py"
CACHE = SCRATCH / "cache"
LOGS = SCRATCH / "logs"
PY = TOP / ".venv" / "bin" / "python"
JOBS = os.environ.get("JOBS", str(os.cpu_count() or 2))
UNIT_TIMEOUT = 600
PYTEST_TIMEOUT = 1200


class SetupError(RuntimeError):
    """The test run itself went wrong (not a failing test): neither caught nor missed."""


@dataclass
class Mutation:
    id: str
    file: str
    find: str
    replace: str
    what: str
    pytest: list[str] = field(default_factory=list)
    gtest: str = ""  # unit tests to run first (a --gtest_filter), the rest after

    @property
    def python(self) -> bool:
        return self.file.startswith("harness/")


def load() -> list[Mutation]:
    data = tomllib.loads(MUTATIONS.read_text())
    out = [Mutation(**m) for m in data["mutation"]]
    for m in out:
        for t in m.pytest:
            path = TOP / t.split("::")[0]
            if not path.is_file():
                sys.exit(f"mutate: {MUTATIONS}: mutation {m.id} names a missing test file {t}")
        if not (TOP / m.file).is_file():
            sys.exit(f"mutate: {MUTATIONS}: mutation {m.id} names a missing file {m.file}")
    ids = [m.id for m in out]
    dup = {i for i in ids if ids.count(i) > 1}
    if dup:
        sys.exit(f"mutate: {MUTATIONS}: duplicate ids {sorted(dup)}")
    return out


def log(msg: str) -> None:
    print(msg, flush=True)


def run(cmd, log_path: Path, cwd: Path = TOP, env=None, timeout=None) -> tuple[int, str]:
    """Run a command, output to log_path; return (exit status, output). 124 on timeout."""
    try:
        p = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                           timeout=timeout, shell=isinstance(cmd, str), executable="/bin/bash" if isinstance(cmd, str) else None)
        out, rc = p.stdout, p.returncode
    except subprocess.TimeoutExpired as e:
        out = (e.stdout or b"").decode(errors="replace") if isinstance(e.stdout, bytes) else (e.stdout or "")
        rc = 124
    log_path.parent.mkdir(parents=True, exist_ok=True)
    log_path.write_text(out)
    return rc, out


# ---------------------------------------------------------------- scratch copies

def sync_tree(src: Path, dst: Path, skip=()) -> int:
    """Make dst a copy of src by content: changed files are rewritten (fresh mtime, so ninja
    rebuilds them), files gone from src are removed. Returns the number of files written."""
    written = 0
    want = set()
    for p in src.rglob("*"):
        rel = p.relative_to(src)
        if any(part in skip for part in rel.parts):
            continue
        want.add(rel)
        q = dst / rel
        if p.is_dir():
            q.mkdir(parents=True, exist_ok=True)
            continue
        data = p.read_bytes()
        if not q.is_file() or q.read_bytes() != data:
            q.parent.mkdir(parents=True, exist_ok=True)
            q.write_bytes(data)
            written += 1
    if dst.exists():
        for q in sorted(dst.rglob("*"), reverse=True):
            rel = q.relative_to(dst)
            if rel not in want and not any(part in skip for part in rel.parts):
                shutil.rmtree(q) if q.is_dir() and not q.is_symlink() else q.unlink()
    return written


def build_env() -> dict:
    env = dict(os.environ)
    env.setdefault("CCACHE_BASEDIR", "/work" if str(TOP).startswith("/work/") else str(TOP))
    return env


def configure() -> None:
    if (BLD / "build.ninja").is_file():
        return
    # (the library's CMakeLists.txt puts ccache in front of the compiler where it is installed)
    args = ["cmake", "-S", str(SRC), "-B", str(BLD), "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release"]
    rc, out = run(args, LOGS / "configure.log", env=build_env())
    if rc:
        sys.exit(f"mutate: configuring {BLD} failed:\n{out[-3000:]}")


def build(targets: list[str], tag: str) -> tuple[bool, str]:
    rc, out = run(["cmake", "--build", str(BLD), "-j", JOBS, "--target", *targets], LOGS / f"{tag}.build.log",
                  env=build_env())
    return rc == 0, out


def printvar(directory: Path, expr: str) -> str:
    mk = f"print-it:\n\t@echo '{expr}'\n"
    p = subprocess.run(["make", "-s", "--no-print-directory", "-C", str(directory), "-f", "Makefile", "-f", "-",
                        "print-it"], input=mk, capture_output=True, text=True, check=True)
    return p.stdout.strip()


_LINK: str | None = None


def link_fork(tag: str) -> tuple[bool, str]:
    """Relink POV-Ray's own objects with the scratch library (POV's link line, -L swapped)."""
    global _LINK
    unix = TOP / "povray" / "unix"
    if _LINK is None:
        pre = printvar(unix, "$(CXXLD) $(AM_CXXFLAGS) $(CXXFLAGS) $(AM_LDFLAGS) $(LDFLAGS)")
        objects = printvar(unix, "$(povray_OBJECTS)")
        ldadd = printvar(unix, "$(povray_LDADD)")
        libs = printvar(unix, "$(LIBS)")
        real = f"-L{TOP}/build/shading"
        if real not in pre:
            sys.exit(f"mutate: POV's link line does not name {real}: {pre}")
        _LINK = f"{pre.replace(real, f'-L{BLD}')} -o {BIN}.tmp {objects} {ldadd} {libs}"
    BIN.parent.mkdir(parents=True, exist_ok=True)
    rc, out = run(_LINK, LOGS / f"{tag}.link.log", cwd=unix)
    if rc == 0:
        os.replace(f"{BIN}.tmp", BIN)
    return rc == 0, out


def make_pytree() -> None:
    """build/mutate/py: a copy of harness/ and tests/ with links to the rest of the checkout;
    its build/ links every entry of the real one except the table cache."""
    PYTREE.mkdir(parents=True, exist_ok=True)
    sync_tree(TOP / "harness", PYTREE / "harness", skip=("__pycache__",))
    sync_tree(TOP / "tests", PYTREE / "tests", skip=("__pycache__",))
    shutil.copy2(TOP / "pytest.ini", PYTREE / "pytest.ini")
    for name in ("Makefile", "patches", "scenes", "brdf_data", "conf", "shading", "docs", "mk", "studies",
                 "pyproject.toml", "VERSION", "povray", ".venv"):
        link = PYTREE / name
        if (TOP / name).exists() and not link.is_symlink():
            link.symlink_to(TOP / name)
    b = PYTREE / "build"
    b.mkdir(exist_ok=True)
    for entry in (TOP / "build").iterdir():
        if entry.name in ("brdf_cache", "mutate", "costs.txt"):
            continue
        link = b / entry.name
        if not link.is_symlink():
            link.symlink_to(entry)
    (b / "brdf_cache").mkdir(exist_ok=True)


# ---------------------------------------------------------------- test runs

def unit_tests(tag: str, first: str = "") -> tuple[str | None, str]:
    """Run the unit tests (those matching ``first`` before the rest), stopping at the first
    failure; return (failed test or None, log)."""
    filters = [first, "-" + first] if first else ["*"]
    out_all = ""
    for k, flt in enumerate(filters):
        rc, out = run([str(BLD / "shading_tests"), "--gtest_fail_fast", "--gtest_brief=1", f"--gtest_filter={flt}"],
                      LOGS / f"{tag}.unit{k}.log", timeout=UNIT_TIMEOUT)
        out_all += out
        if rc == 124:
            return "shading_tests (timed out)", out_all
        if rc != 0:
            failed = re.findall(r"^\[  FAILED  \] (\S+)", out, re.M)
            return (f"ctest {failed[0]}" if failed else f"shading_tests (exit {rc})"), out_all
    return None, out_all


def pytest_env(python_mode: bool) -> dict:
    env = dict(os.environ)
    for k in ("POVRAY_BRDF", "BRDFTOOL", "SSTOOL", "POVRAY_BRDF_CACHE"):
        env.pop(k, None)
    if not python_mode:
        env["POVRAY_BRDF"] = str(BIN)
        env["BRDFTOOL"] = str(BLD / "brdftool")
        if (BLD / "sstool").exists():
            env["SSTOOL"] = str(BLD / "sstool")
        env["POVRAY_BRDF_CACHE"] = str(CACHE)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def py_tests(targets: list[str], tag: str, python_mode: bool) -> tuple[str | None, str]:
    """Run pytest on targets (fast tests only), stop at the first failure; (failed node or None, log)."""
    if python_mode:
        cache = PYTREE / "build" / "brdf_cache"
    else:
        cache = CACHE
    shutil.rmtree(cache, ignore_errors=True)
    cache.mkdir(parents=True)
    cwd = PYTREE if python_mode else TOP
    cmd = [str(PY), "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-m", "not slow", "-rfE", *targets]
    rc, out = run(cmd, LOGS / f"{tag}.pytest.log", cwd=cwd, env=pytest_env(python_mode), timeout=PYTEST_TIMEOUT)
    if rc == 0:
        return None, out
    if rc == 124:
        return "pytest (timed out)", out
    if rc != 1:  # 2 interrupted, 3 internal error, 4 usage, 5 nothing collected: not a catch
        raise SetupError(f"pytest exited with {rc} (not a test failure); see {LOGS}/{tag}.pytest.log")
    failed = re.findall(r"^(?:FAILED|ERROR) (.+?)(?: - .*)?$", out, re.M)
    return (failed[0] if failed else "pytest (a test failed)"), out


# ---------------------------------------------------------------- main

def apply(m: Mutation) -> tuple[Path, str]:
    base = PYTREE if m.python else SRC.parent
    rel = m.file if m.python else m.file  # shading/src/x.cpp lives at SRC.parent/shading/src/x.cpp
    path = base / rel
    text = path.read_text()
    n = text.count(m.find)
    if n != 1:
        raise ValueError(f"{m.file}: the text to mutate occurs {n} times (must be exactly once): {m.find!r}")
    path.write_text(text.replace(m.find, m.replace))
    return path, text


def restore(path: Path, text: str) -> None:
    path.write_text(text)  # a fresh mtime: ninja recompiles (ccache makes it a hit)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="*", default=None, help="run only these mutation ids")
    ap.add_argument("--no-baseline", action="store_true", help="skip the unmutated baseline run")
    ap.add_argument("--list", action="store_true", help="list the mutations and exit")
    ap.add_argument("--skip-unit", action="store_true",
                    help="skip the unit tests: show whether the Python tests alone catch each mutation")
    args = ap.parse_args()
    muts = load()
    if args.list:
        for m in muts:
            print(f"{m.id:28s} {m.file:38s} {m.what}")
        return 0
    if args.only:
        unknown = set(args.only) - {m.id for m in muts}
        if unknown:
            sys.exit(f"mutate: unknown ids {sorted(unknown)}")
        muts = [m for m in muts if m.id in args.only]
    t_all = time.time()
    LOGS.mkdir(parents=True, exist_ok=True)
    n = sync_tree(TOP / "shading", SRC, skip=("__pycache__",))
    log(f"mutate: scratch library {SRC} ({n} files refreshed), build {BLD}")
    configure()
    cpp = [m for m in muts if not m.python]
    pym = [m for m in muts if m.python]
    if pym:
        make_pytree()
    # Baseline: the unmutated scratch build passes what the mutations will run.
    ok, out = build(["all"], "baseline")
    if not ok:
        sys.exit(f"mutate: the unmutated scratch library does not build:\n{out[-3000:]}")
    if not args.no_baseline:
        t0 = time.time()
        if cpp:
            failed, _ = unit_tests("baseline")
            if failed:
                sys.exit(f"mutate: baseline: {failed} fails without any mutation (see {LOGS}/baseline.unit0.log)")
            ok, out = link_fork("baseline")
            if not ok:
                sys.exit(f"mutate: relinking the fork failed:\n{out[-3000:]}")
            targets = sorted({t for m in cpp for t in m.pytest})
            if targets:
                failed, _ = py_tests(targets, "baseline", False)
                if failed:
                    sys.exit(f"mutate: baseline: {failed} fails without any mutation (see {LOGS}/baseline.pytest.log)")
        targets = sorted({t for m in pym for t in m.pytest})
        if targets:
            failed, _ = py_tests(targets, "baseline-py", True)
            if failed:
                sys.exit(f"mutate: baseline: {failed} fails in the Python scratch tree without any mutation "
                         f"(see {LOGS}/baseline-py.pytest.log)")
        log(f"mutate: baseline passes ({time.time() - t0:.0f} s)")
    results = []
    for i, m in enumerate(muts, 1):
        t0 = time.time()
        tag = m.id
        status, by = "missed", ""
        try:
            path, original = apply(m)
        except ValueError as e:
            results.append({"id": m.id, "what": m.what, "status": "error", "by": str(e), "seconds": 0.0})
            log(f"[{i:2d}/{len(muts)}] {m.id:28s} ERROR {e}")
            continue
        try:
            if m.python:
                failed, _ = py_tests(m.pytest, tag, True)
                if failed:
                    status, by = "caught", failed
            else:
                ok, out = build(["shading_tests"], tag)
                if not ok:
                    status, by = "error", f"does not compile (see {LOGS}/{tag}.build.log)"
                else:
                    failed = None if args.skip_unit else unit_tests(tag, m.gtest)[0]
                    if failed:
                        status, by = "caught", failed
                    elif m.pytest:
                        ok, out = build(["all"], tag + ".all")
                        ok = ok and link_fork(tag)[0]
                        if not ok:
                            status, by = "error", f"tools or fork do not build (see {LOGS}/{tag}.*)"
                        else:
                            failed, _ = py_tests(m.pytest, tag, False)
                            if failed:
                                status, by = "caught", failed
        except SetupError as e:
            status, by = "error", str(e)
        finally:
            restore(path, original)
        dt = time.time() - t0
        results.append({"id": m.id, "what": m.what, "file": m.file, "status": status, "by": by, "seconds": round(dt, 1)})
        mark = {"caught": "caught by", "missed": "MISSED", "error": "ERROR"}[status]
        log(f"[{i:2d}/{len(muts)}] {m.id:28s} {mark} {by} ({dt:.0f} s)")
    # Leave the scratch library unmutated and built (the next run starts incremental).
    if cpp:
        build(["all"], "restore")
    total = time.time() - t_all
    caught = sum(r["status"] == "caught" for r in results)
    lines = [f"{r['id']:28s} {r['status']:7s} {r['by']}  ({r['seconds']:.0f} s)  -- {r['what']}" for r in results]
    summary = f"mutate: {caught} of {len(results)} mutations caught in {total / 60:.1f} min"
    (SCRATCH / "report.txt").write_text("\n".join(lines + [summary]) + "\n")
    (SCRATCH / "report.json").write_text(json.dumps({"results": results, "seconds": round(total, 1)}, indent=1))
    log(summary)
    bad = [r for r in results if r["status"] != "caught"]
    for r in bad:
        log(f"  {r['status'].upper()}: {r['id']} ({r['what']}) {r['by']}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
