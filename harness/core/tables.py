"""BRDF tables for scenes: made with ``brdftool`` once, cached under ``build/brdf_cache``
(outside a checkout: the cache folder of :func:`harness.core.paths.cache_dir`).

    path = tables.tabulated("microfacet d=beckmann m=0.3", step=1.0)
    path = tables.tabulated_halfdiff("microfacet d=beckmann m=0.02", nodes=(256, 128, 32))

The cache key is the tool's whole command line (hashed), so a table is rebuilt only when
what it would contain changes; delete ``build/brdf_cache`` to force it.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
from pathlib import Path
from typing import Sequence

from harness.core.files import pid_alive
from harness.core.paths import brdftool, cache_dir

CACHE_DIR = cache_dir("brdf_cache")


def cached(args: Sequence[str], stem: str) -> Path:
    """The table ``brdftool ARGS -o FILE`` writes, made once: ``build/brdf_cache/STEM-KEY.brdf``
    with KEY a hash of the whole command line."""
    key = hashlib.sha256("\0".join(args).encode()).hexdigest()[:16]
    out = CACHE_DIR / f"{stem}-{key}.brdf"
    if out.is_file():
        return out
    CACHE_DIR.mkdir(parents=True, exist_ok=True)
    _sweep(CACHE_DIR)
    tmp = out.with_suffix(f".tmp{os.getpid()}")
    try:
        proc = subprocess.run([str(brdftool()), *args, "-o", str(tmp)], capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"brdftool {' '.join(args)} failed: {proc.stderr.strip()}")
        tmp.replace(out)
    finally:  # failed, interrupted (Ctrl-C) or done: no temporary table stays behind
        tmp.unlink(missing_ok=True)
    return out


def _sweep(folder: Path) -> None:
    """Remove the temporary tables (``*.tmpPID``) of processes that were killed while writing them."""
    for f in folder.glob("*.tmp*"):
        pid = f.suffix[len(".tmp"):]
        if pid.isdigit() and int(pid) != os.getpid() and not pid_alive(int(pid)):
            f.unlink(missing_ok=True)


def tabulated(spec: str, step: float = 1.0, fold: bool = False, channels: int = 3) -> Path:
    """A table of the analytic model ``spec`` at ``step`` degrees."""
    args = ["tabulate", spec, "--step", repr(float(step)), "--channels", str(channels)]
    if fold:
        args.append("--fold")
    return cached(args, "tab")


def tabulated_halfdiff(spec: str, nodes: Sequence[int] = (256, 128, 32), channels: int = 3) -> Path:
    """A half/difference table (layout 3) of ``spec`` with ``nodes`` = (theta_h, theta_d, phi_d) counts."""
    n = ",".join(str(int(x)) for x in nodes)
    return cached(["tabulate", spec, "--layout", "halfdiff", "--nodes", n, "--channels", str(channels)], "hd")


def measured_like(spec: str, step: float = 1.0, noise: float = 0.02, missing: float = 0.001,
                  seed: int = 1) -> Path:
    """A simulated gonioreflectometer measurement of ``spec`` (noise, missing cells filled)."""
    args = ["measured-like", spec, "--step", repr(float(step)), "--noise", repr(noise),
            "--missing", repr(missing), "--seed", str(seed)]
    return cached(args, "meas")
