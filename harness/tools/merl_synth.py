"""Write a synthetic MERL ``.binary`` BRDF file (for trying the measured-material workflow).

    python -m harness.tools.merl_synth out/tutorial/synthetic.binary [--kd 0.25,0.08,0.05] [--rho-s 0.7] [--m 0.2] [--f0 0.05]

The repository ships no MERL measurement; this makes a file in exactly MERL's layout so that
``brdftool convert`` and everything after it can be tried: three int32 dimensions (90, 90,
180), then three channel planes (R, G, B) of doubles over (theta_h, theta_d, phi_d) bins,
each value f / scale with MERL's scales 1/1500, 1.15/1500, 1.66/1500 (``shading/src/tables/merl.cpp``).
Bins are sampled at their centres: theta_h = ((i + 0.5) / 90)^2 * 90 deg (MERL's square-root
spacing), theta_d = (j + 0.5) deg, phi_d = (k + 0.5) deg, with phi_h = 0. Bins whose incident
or outgoing direction is below the horizon hold -1, MERL's no-data marker.

The BRDF is a glossy plastic written out independently of the shading library: a Lambertian
base under a Cook-Torrance lobe, ``f = kd/pi + rho_s D G F / (4 cos_i cos_o)`` with the Beckmann
D of RMS slope m, the height-correlated Smith G of that D and Schlick's F(theta_d) =
f0 + (1 - f0)(1 - cos theta_d)^5: the fork's ``microfacet d=beckmann g=smith f=schlick``. So
``brdftool fit`` on the converted table should find m, f0, kd and rho_s again, up to MERL's
binning (a check of the whole path from a .binary to a finish).
"""

from __future__ import annotations

import argparse
import math
import struct
import sys
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

DIMS = (90, 90, 180)
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])


def bin_directions(dims: tuple[int, int, int] = DIMS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """theta_h, theta_d (radians) per bin and the (wi, wo) unit vectors, shapes (nh, nd, np[, 3])."""
    nh, nd, nphi = dims
    th = ((np.arange(nh) + 0.5) / nh) ** 2 * (np.pi / 2)
    td = (np.arange(nd) + 0.5) / nd * (np.pi / 2)
    pd = (np.arange(nphi) + 0.5) / nphi * np.pi
    TH, TD, PD = np.meshgrid(th, td, pd, indexing="ij")
    d = np.stack([np.sin(TD) * np.cos(PD), np.sin(TD) * np.sin(PD), np.cos(TD)], axis=-1)
    # wi = rot_y(d, theta_h) (phi_h = 0); h = (sin theta_h, 0, cos theta_h); wo = 2 (h.wi) h - wi
    c, s = np.cos(TH), np.sin(TH)
    wi = np.stack([d[..., 0] * c + d[..., 2] * s, d[..., 1], -d[..., 0] * s + d[..., 2] * c], axis=-1)
    h = np.stack([s, np.zeros_like(s), c], axis=-1)
    wo = 2.0 * np.sum(h * wi, axis=-1, keepdims=True) * h - wi
    return TH, TD, np.stack([wi, wo])


def _smith_lambda(cos_t: np.ndarray, m: float) -> np.ndarray:
    """Beckmann's Smith Lambda(theta): (erf(a) - 1)/2 + exp(-a^2)/(2 a sqrt(pi)), a = 1/(m tan)."""
    c = np.clip(cos_t, 1e-9, 1.0)
    a = c / (m * np.sqrt(np.maximum(1.0 - c * c, 1e-300)))
    erf = np.frompyfunc(math.erf, 1, 1)(a).astype(float)
    return np.where(a > 30.0, 0.0, (erf - 1.0) / 2.0 + np.exp(-a * a) / (2.0 * a * np.sqrt(np.pi)))


def synthetic_brdf(kd: Sequence[float], rho_s: float, m: float, f0: float,
                   dims: tuple[int, int, int] = DIMS) -> np.ndarray:
    """f per bin and channel, shape (3, nh, nd, np); NaN where a direction is below the horizon."""
    TH, TD, (wi, wo) = bin_directions(dims)
    ci, co = wi[..., 2], wo[..., 2]
    below = (ci <= 0.0) | (co <= 0.0)
    ch = np.cos(TH)
    d = np.exp(-np.tan(TH) ** 2 / (m * m)) / (np.pi * m * m * ch ** 4)
    g = 1.0 / (1.0 + _smith_lambda(ci, m) + _smith_lambda(co, m))
    fres = f0 + (1.0 - f0) * (1.0 - np.cos(TD)) ** 5
    with np.errstate(divide="ignore", invalid="ignore"):
        lobe = rho_s * d * g * fres / (4.0 * ci * co)
    f = np.stack([k / np.pi + lobe for k in kd])
    f[:, below] = np.nan
    return f


def write_merl(path: Path, f: np.ndarray) -> Path:
    """Write ``f`` (3, nh, nd, np) as a MERL .binary (no-data, i.e. NaN, as -1)."""
    raw = f / SCALE[:, None, None, None]
    raw = np.where(np.isnan(raw), -1.0, raw)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        fh.write(struct.pack("<3i", *f.shape[1:]))
        fh.write(np.ascontiguousarray(raw, dtype="<f8").tobytes())
    return path


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="brdf-merl-synth", description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--kd", default="0.25,0.08,0.05", help="Lambertian albedo r,g,b")
    ap.add_argument("--rho-s", type=float, default=0.7, help="lobe scale (kd + rho_s <= 1)")
    ap.add_argument("--m", type=float, default=0.2, help="Beckmann RMS slope")
    ap.add_argument("--f0", type=float, default=0.05, help="Schlick normal-incidence reflectance")
    a = ap.parse_args(argv)
    kd = [float(x) for x in a.kd.split(",")]
    if len(kd) == 1:
        kd *= 3
    f = synthetic_brdf(kd, a.rho_s, a.m, a.f0)
    write_merl(a.out, f)
    nodata = int(np.isnan(f[0]).sum())
    print(f"merl_synth: {a.out}: {DIMS[0]}x{DIMS[1]}x{DIMS[2]} bins, {nodata} below the horizon (-1), "
          f"kd {kd}, rho_s {a.rho_s}, m {a.m}, f0 {a.f0}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
