"""The harness as an installable package: its wheel, built from the checkout's sources, is
installed into a fresh venv, and every console script answers ``--help`` from outside the
checkout; there the tools find the fork and brdftool through the environment or ``PATH``
(where ``make install`` puts them) and say how to fix it when they cannot.

No download: the wheel is built offline with the project venv's setuptools (pinned in the
test extra), installed without dependencies, and the fresh venv sees the project venv's
packages (the pinned dependencies, checked below) through a ``.pth`` file. About 5 s.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

from harness.core.paths import REPO_ROOT

PYPROJECT = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())
SCRIPTS = sorted(PYPROJECT["project"]["scripts"])


def run(cmd, **kw):
    return subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=300, **kw)


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """A venv with the harness installed from its wheel; returns (venv, a folder outside the checkout)."""
    root = tmp_path_factory.mktemp("package")
    src = root / "src"  # the sources a wheel is built from (setuptools writes build/ next to them)
    src.mkdir()
    for f in ("pyproject.toml", "README.md"):
        shutil.copy(REPO_ROOT / f, src / f)
    shutil.copytree(REPO_ROOT / "harness", src / "harness", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    p = run([sys.executable, "-m", "pip", "wheel", "-q", "--no-cache-dir", "--no-deps", "--no-build-isolation", "--no-index",
             "-w", root / "wheels", src])
    assert p.returncode == 0, p.stderr
    wheel = next((root / "wheels").glob("povray_brdf_harness-*.whl"))
    venv = root / "venv"
    p = run([sys.executable, "-m", "venv", "--without-pip", venv])
    assert p.returncode == 0, p.stderr
    py = venv / "bin" / "python"
    site = Path(run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
    (site / "zz-project-dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    p = run([sys.executable, "-m", "pip", "--python", py, "install", "-q", "--no-cache-dir", "--no-deps", "--no-index", wheel])
    assert p.returncode == 0, p.stderr
    away = root / "elsewhere"
    away.mkdir()
    return venv, away


def bare_env(away: Path, path: str = "/usr/bin:/bin") -> dict[str, str]:
    """No fork or brdftool anywhere: a PATH without them, no overrides, HOME outside."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("POVRAY_BRDF", "BRDFTOOL", "POVRAY_BRDF_CACHE", "PYTHONPATH", "VIRTUAL_ENV")}
    env.update(PATH=path, HOME=str(away), XDG_CACHE_HOME=str(away / "cache"))
    return env


def test_wheel_installs_the_harness_and_its_scripts(fresh):
    venv, away = fresh
    py = venv / "bin" / "python"
    where = run([py, "-c", "import harness, harness.core.paths as p; print(harness.__file__); print(p.in_checkout())"],
                cwd=away, env=bare_env(away))
    assert where.returncode == 0, where.stderr
    file, checkout = where.stdout.split()
    assert Path(file).is_relative_to(venv) and checkout == "False"  # the installed copy, not the checkout
    for script in SCRIPTS:
        assert (venv / "bin" / script).is_file(), script
    # the pinned dependencies are what this venv runs with
    for req in PYPROJECT["project"]["dependencies"]:
        name, version = req.split("==")
        assert metadata.version(name) == version, req


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_console_script_answers_help(fresh, script):
    venv, away = fresh
    p = run([venv / "bin" / script, "--help"], cwd=away, env=bare_env(away))
    assert p.returncode == 0, p.stderr[-2000:]
    # each script names itself (argparse's prog), not the module it runs (issue 33)
    assert p.stdout.startswith(f"usage: {script} "), p.stdout[:200]
    # and so does its usage error
    p = run([venv / "bin" / script, "--no-such-option"], cwd=away, env=bare_env(away))
    assert p.returncode == 2 and p.stderr.startswith(f"usage: {script} "), p.stderr[:300]
    assert f"\n{script}: error: " in p.stderr, p.stderr[-300:]


def test_outside_a_checkout_the_tools_say_where_they_looked(fresh):
    venv, away = fresh
    py = venv / "bin" / "python"
    for name, env, call in (("brdftool", "BRDFTOOL", "brdftool()"), ("povray-brdf", "POVRAY_BRDF", "fork_binary()")):
        p = run([py, "-c", f"from harness.core.paths import *; {call}"], cwd=away, env=bare_env(away))
        assert p.returncode != 0
        msg = p.stderr.strip().splitlines()[-1]
        assert msg.startswith("harness.core.paths.BinaryNotFound: ") and f"${env}" in msg and "PATH" in msg
        assert "make install PREFIX=" in msg, msg
    table = REPO_ROOT / "build" / "brdf_data" / "lambert-white.brdf"
    p = run([venv / "bin" / "brdf-plot", table, "-o", away / "p.png", "--fit", "lambert"], cwd=away, env=bare_env(away))
    assert p.returncode != 0 and "brdftool not found" in p.stderr, p.stderr[-1500:]


def test_outside_a_checkout_the_tools_find_the_fork_and_brdftool_on_path(fresh, fork):
    venv, away = fresh
    bindir = away / "bin"  # what `make install` leaves on PATH
    bindir.mkdir(exist_ok=True)
    for name, target in (("povray-brdf", fork.path), ("brdftool", REPO_ROOT / "build" / "shading" / "brdftool")):
        if not (bindir / name).exists():
            (bindir / name).symlink_to(target)
    env = bare_env(away, f"{bindir}:/usr/bin:/bin")
    p = run([venv / "bin" / "python", "-c", "from harness.core.paths import *; print(fork_binary().path, brdftool(), "
             "cache_dir('brdf_cache'), out_dir('study'))"], cwd=away, env=env)
    assert p.returncode == 0, p.stderr
    assert p.stdout.split() == [str(bindir / "povray-brdf"), str(bindir / "brdftool"), str(away / "cache" / "povray-brdf"
                                / "brdf_cache"), str(away / "out" / "study")]
    table = REPO_ROOT / "build" / "brdf_data" / "lambert-white.brdf"
    p = run([venv / "bin" / "brdf-plot", table, "-o", away / "p.png", "--fit", "lambert"], cwd=away, env=env)
    assert p.returncode == 0 and (away / "p.png").stat().st_size > 1000, p.stderr[-1500:]
    # the environment still wins over PATH
    env["BRDFTOOL"] = str(away / "missing-brdftool")
    p = run([venv / "bin" / "python", "-c", "from harness.core.paths import *; brdftool()"], cwd=away, env=env)
    assert p.returncode != 0 and "BRDFTOOL" in p.stderr
