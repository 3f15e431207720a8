"""Runs of the shading library's ``sstool`` (exact subsurface profiles, shading/ss_profile.h): the
tables' values and the library's own transport Monte Carlo, as plain dicts (the tool prints JSON).

    eval_profile(path, [0.5, 0.9], g=0.5, eta=1.33, edges=[...], cos=[1.0, 0.5])
    library_mc([0.5, 0.9], g=0.0, eta=[1.33], thickness=4.0, photons=20000)
    build(out, g=[0.0], eta=[1.0, 1.33], thickness=[1, 4], photons=20000)

Radii and edges are transport mean free paths (1/sigma_t'); slab thicknesses are transport mfp
in :func:`eval_profile` and mean free paths 1/sigma_t in :func:`library_mc` and :func:`build`.
"""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path
from typing import Optional, Sequence

from harness.core.paths import sstool


def _csv(values: Sequence[float]) -> str:
    return ",".join("inf" if v == math.inf else repr(float(v)) for v in values)


def _run(args: Sequence[str], timeout: float = 3600.0) -> str:
    proc = subprocess.run([str(sstool()), *args], capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"sstool {' '.join(args)} failed ({proc.returncode}): {proc.stderr.strip()}")
    return proc.stdout


def eval_profile(path: Path, alpha_prime: Sequence[float], *, g: float = 0.0, eta: float = 1.0,
                 thickness: float = math.inf, face: str = "r", edges: Sequence[float] = (),
                 cos: Sequence[float] = (1.0,), radii: Sequence[float] = ()) -> list[dict]:
    """One dict per reduced albedo: ``total`` (multiple scattering), ``single``/``ballistic`` (the
    tables' Monte Carlo values), ``annulus_means`` over ``edges``, ``rd`` at ``radii``,
    ``exit_factor``/``entry_factor`` at the outside cosines ``cos``, ``radius_90``."""
    args = ["eval", str(path), "--alpha-prime", _csv(alpha_prime), "--g", repr(g), "--eta", repr(eta),
            "--face", face, "--cos", _csv(cos)]
    if thickness != math.inf:
        args += ["--thickness", repr(thickness)]
    if len(edges):
        args += ["--edges", _csv(edges)]
    if len(radii):
        args += ["--radii", _csv(radii)]
    return json.loads(_run(args))["rows"]


def library_mc(alpha_prime: Sequence[float], *, g: float = 0.0, eta: Sequence[float] = (1.0,),
               thickness: float = math.inf, cos_incidence: float = 1.0, photons: int = 20000,
               short_photons: int = 0, seed: int = 1, threads: int = 0) -> dict:
    """The library's Monte Carlo totals (reflection and transmission, per eta and albedo)."""
    args = ["mc", "--alpha-prime", _csv(alpha_prime), "--g", repr(g), "--eta", _csv(eta),
            "--cos-incidence", repr(cos_incidence), "--photons", str(photons), "--short-photons", str(short_photons),
            "--seed", str(seed), "--threads", str(threads)]
    if thickness != math.inf:
        args += ["--thickness", repr(thickness)]
    return json.loads(_run(args))


def build(out: Path, *, g: Sequence[float], eta: Sequence[float], thickness: Sequence[float] = (math.inf,),
          photons: Optional[int] = None, short_photons: Optional[int] = None, seed: int = 1,
          threads: int = 0) -> str:
    """``sstool build``; returns its log (one line per Monte Carlo run, with the time)."""
    args = ["build", "-o", str(out), "--g", _csv(g), "--eta", _csv(eta), "--thickness", _csv(thickness),
            "--seed", str(seed), "--threads", str(threads)]
    if photons is not None:
        args += ["--photons", str(photons)]
    if short_photons is not None:
        args += ["--short-photons", str(short_photons)]
    proc = subprocess.run([str(sstool()), *args], capture_output=True, text=True, timeout=7200)
    if proc.returncode != 0:
        raise RuntimeError(f"sstool build failed ({proc.returncode}): {proc.stderr.strip()}")
    return proc.stderr
