"""Where things are: the repository root, the two POV-Ray binaries, the include path, and
where the harness keeps what it makes.

Binary discovery is environment-first so CI and people can point the harness elsewhere:

* ``POVRAY_BRDF``  — the fork (default ``<repo>/build/bin/povray-brdf`` in a checkout,
  else ``povray-brdf`` on ``PATH``, where ``make install`` puts it);
* ``BRDFTOOL``     — brdftool (default ``<repo>/build/shading/brdftool``, else ``PATH``);
* ``POVRAY_STOCK`` — Debian's stock 3.7.0.10 (default ``/usr/bin/povray``);
* ``POVRAY_INCLUDE`` — extra include directories (``os.pathsep``-separated), searched
  before the standard ``/usr/share/povray-3.7/include``.

The harness runs from a checkout (``make venv`` installs it editable) or installed on its
own (``pip install .``: the ``brdf-*`` console scripts). Outside a checkout there is no
``build/`` or ``out/``: tables and costs it makes go to the cache folder
(:func:`cache_dir`), pages to ``./out`` (:func:`out_dir`), and the ready tables are the
installed fork's (:func:`ready_tables_dir`).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, Union

Flavour = Literal["fork", "stock"]

#: Repository root: the directory that holds ``harness/`` (this file is harness/core/paths.py).
REPO_ROOT: Path = Path(__file__).resolve().parents[2]

#: Where the build puts the fork, relative to the repository root.
FORK_DEFAULT: Path = REPO_ROOT / "build" / "bin" / "povray-brdf"

#: Debian's stock binary (package ``povray`` 1:3.7.0.10-2+b2).
STOCK_DEFAULT: Path = Path("/usr/bin/povray")

#: Debian installs POV-Ray's standard include files here.
STANDARD_INCLUDE: Path = Path("/usr/share/povray-3.7/include")


class BinaryNotFound(FileNotFoundError):
    """A POV-Ray binary is missing or not executable; the message says how to fix it."""


@dataclass(frozen=True)
class Binary:
    """A resolved renderer: its path and whether it is the fork or the stock build.

    The flavour decides which options the runner may use (``+FE32`` is fork-only).
    """

    path: Path
    flavour: Flavour


def repo_root() -> Path:
    """Return the repository root."""
    return REPO_ROOT


def _check_executable(path: Path, what: str, env: str, hint: str) -> Path:
    if not path.is_file():
        raise BinaryNotFound(f"{what} not found at {path} (set {env} to override). {hint}")
    if not os.access(path, os.X_OK):
        raise BinaryNotFound(f"{what} at {path} is not executable (set {env} to override).")
    return path


def fork_binary() -> Binary:
    """Locate the fork ``povray-brdf``: ``POVRAY_BRDF``, else the checkout's build, else
    ``PATH``; raise :class:`BinaryNotFound` (saying how to fix it) if there is none."""
    env = os.environ.get("POVRAY_BRDF")
    if env or in_checkout():
        path = Path(env or FORK_DEFAULT)
        _check_executable(path, "fork binary povray-brdf", "POVRAY_BRDF",
                          "Build it first (see the README / `make help`).")
        return Binary(path, "fork")
    return Binary(_on_path("povray-brdf", "POVRAY_BRDF"), "fork")


def stock_binary() -> Binary:
    """Locate Debian's stock POV-Ray 3.7; raise :class:`BinaryNotFound` if it is missing."""
    env = os.environ.get("POVRAY_STOCK")
    if env:
        path = Path(env)
    elif STOCK_DEFAULT.is_file():
        path = STOCK_DEFAULT
    else:
        found = shutil.which("povray")
        path = Path(found) if found else STOCK_DEFAULT
    _check_executable(path, "stock POV-Ray", "POVRAY_STOCK",
                      "Install it with `apt-get install povray` (version 1:3.7.0.10).")
    return Binary(path, "stock")


def resolve_binary(which: Union[str, os.PathLike, Binary]) -> Binary:
    """Turn ``'fork'``, ``'stock'``, a :class:`Binary` or a path into a :class:`Binary`.

    A bare path counts as the fork when its file name starts with ``povray-brdf``,
    otherwise as stock; pass a :class:`Binary` to say it explicitly.
    """
    if isinstance(which, Binary):
        return which
    if which == "fork":
        return fork_binary()
    if which == "stock":
        return stock_binary()
    path = Path(which)
    flavour: Flavour = "fork" if path.name.startswith("povray-brdf") else "stock"
    _check_executable(path, f"POV-Ray binary ({flavour})", "the binary argument", "")
    return Binary(path, flavour)


def brdftool() -> Path:
    """The shading library's ``brdftool``: ``BRDFTOOL``, else the checkout's build, else ``PATH``."""
    env = os.environ.get("BRDFTOOL")
    if env:
        return _check_executable(Path(env), "brdftool", "BRDFTOOL", "")
    if in_checkout():
        return _check_executable(REPO_ROOT / "build" / "shading" / "brdftool", "brdftool", "BRDFTOOL",
                                 "Build it first with `make shading`.")
    return _on_path("brdftool", "BRDFTOOL")


def in_checkout() -> bool:
    """True when this harness is a povray-brdf checkout's (the tree itself or an editable
    install of it), False when it was installed on its own (``pip install``)."""
    return (REPO_ROOT / "Makefile").is_file() and (REPO_ROOT / "patches" / "series").is_file()


def _on_path(name: str, env: str) -> Path:
    found = shutil.which(name)
    if found is None:
        raise BinaryNotFound(
            f"{name} not found: this harness is installed outside a povray-brdf checkout, and {name} is neither "
            f"named by ${env} nor on PATH. Install the fork (`make install PREFIX=/opt/povray-brdf` in a checkout, "
            f"then add /opt/povray-brdf/bin to PATH) or set {env}=/path/to/{name}.")
    return Path(found)


def cache_dir(*parts: str) -> Path:
    """Where the harness keeps tables and measurements it makes: ``$POVRAY_BRDF_CACHE`` if set,
    else ``build/`` of a checkout, else ``$XDG_CACHE_HOME/povray-brdf`` (``~/.cache/povray-brdf``).
    (The cache is keyed by brdftool's command line, not by the binary: ``make mutate`` points
    it elsewhere while a mutated brdftool runs.)"""
    if os.environ.get("POVRAY_BRDF_CACHE"):
        base = Path(os.environ["POVRAY_BRDF_CACHE"])
    elif in_checkout():
        base = REPO_ROOT / "build"
    else:
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "povray-brdf"
    return base.joinpath(*parts)


def out_dir(*parts: str) -> Path:
    """Default folder of pages and images: ``out/`` of a checkout, else ``./out``."""
    return (REPO_ROOT / "out" if in_checkout() else Path.cwd() / "out").joinpath(*parts)


def ready_tables_dir() -> Path:
    """The ready tables (``make brdf-data``): ``build/brdf_data`` of a checkout, else the
    installed fork's ``PREFIX/share/povray-brdf/brdf_data`` (beside its ``bin/``)."""
    if in_checkout():
        return REPO_ROOT / "build" / "brdf_data"
    try:
        fork = fork_binary().path.resolve()
    except BinaryNotFound:
        return Path("/usr/local/share/povray-brdf/brdf_data")
    return fork.parent.parent / "share" / "povray-brdf" / "brdf_data"


def sstool() -> Path:
    """The shading library's ``sstool`` (exact subsurface profiles; built by ``make``; ``SSTOOL``
    overrides)."""
    path = Path(os.environ.get("SSTOOL") or REPO_ROOT / "build" / "shading" / "sstool")
    return _check_executable(path, "sstool", "SSTOOL", "Build it first with `make shading`.")


#: The exact subsurface profile tables `make brdf-data` builds (``SS_PROFILES`` overrides).
def ss_profiles() -> Path:
    """The shipped exact-profile tables, ``build/brdf_data/subsurface_profiles.ssp``."""
    path = Path(os.environ.get("SS_PROFILES") or REPO_ROOT / "build" / "brdf_data" / "subsurface_profiles.ssp")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: the exact subsurface profiles are missing; `make brdf-data` builds them")
    return path


#: The exact slab tables of thin geometry `make brdf-data` builds (``SS_SLABS`` overrides).
def ss_slabs() -> Path:
    """The shipped exact slab tables, ``build/brdf_data/subsurface_slabs.ssp``."""
    path = Path(os.environ.get("SS_SLABS") or REPO_ROOT / "build" / "brdf_data" / "subsurface_slabs.ssp")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: the exact slab tables are missing; `make brdf-data` builds them")
    return path


def include_dirs() -> list[Path]:
    """Include directories to pass with ``+L``: ``POVRAY_INCLUDE`` entries, then the standard one.

    Only directories that exist are returned.
    """
    dirs = [Path(p) for p in os.environ.get("POVRAY_INCLUDE", "").split(os.pathsep) if p]
    dirs.append(STANDARD_INCLUDE)
    return [d for d in dirs if d.is_dir()]


def git_commit() -> str:
    """The checkout's commit (short hash), '(working tree modified)' when tracked files
    differ from it; 'unknown' outside a git checkout."""
    try:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO_ROOT, capture_output=True,
                             text=True, check=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO_ROOT,
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return rev + (" (working tree modified)" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
