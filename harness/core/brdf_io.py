"""Read and write ``.brdf`` tables in numpy (format: ``brdf_data/README.md``).

``read_table`` reads every layout (1 isotropic, 2 anisotropic, 3 half/difference) and says
which; ``read_brdf`` is its ``(values, description)`` shorthand. ``halfdiff_lookup``
interpolates a half/difference table as the format specifies (trilinear in sqrt(theta_h),
theta_d, phi_d, virtual pole nodes, phi_d period 180 deg): numpy's own reading of the
specification, written from the README, not from the C++.

``write_brdf`` writes unfolded isotropic tables and keeps no-data values (NaN) as they are,
so a sparse table (e.g. from :mod:`harness.tools.sphere_sampling`) can be filled by
``brdftool fill`` with the format's documented rule, or fitted directly by ``brdftool fit``
(which skips no-data cells).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Union

import numpy as np

MAGIC = b"PVBRDF\0\0"
PathLike = Union[str, Path]


def fnv1a64(data: bytes) -> int:
    """FNV-1a 64 of ``data`` (vectorised over 8-byte-free chunks is not possible: plain loop)."""
    h = 0xCBF29CE484222325
    for byte in data:
        h = ((h ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


ISOTROPIC, ANISOTROPIC, HALFDIFF = 1, 2, 3


@dataclass(frozen=True)
class Table:
    """A ``.brdf`` file: ``f`` in 1/sr, shaped (theta_i, theta_r, phi, C) for layout 1 (folded
    tables unfolded), (theta_i, phi_i, theta_r, phi_r, C) for layout 2 and (theta_h, theta_d,
    phi_d, C) for layout 3."""

    layout: int
    f: np.ndarray
    description: str
    nodata_filled: int


def read_table(path: PathLike, verify: bool = True) -> Table:
    """Any layout. ``verify`` checks the payload checksum (pure Python, about 0.1 s per MB)."""
    d = Path(path).read_bytes()
    magic, version, off, layout, C, flags, units, *n = struct.unpack_from("<8s10I", d, 0)
    nbytes, checksum, filled, dlen, reserved = struct.unpack_from("<3Q2I", d, 80)
    if magic != MAGIC or version != 1 or units != 1 or len(d) != off + nbytes or layout not in (1, 2, 3):
        raise ValueError(f"{path}: not a version-1 .brdf table")
    description = d[112:112 + dlen].decode("utf-8", "replace")
    payload = d[off:off + nbytes]
    if verify and fnv1a64(payload) != checksum:
        raise ValueError(f"{path}: checksum mismatch")
    v = np.frombuffer(payload, dtype="<f4")
    if layout == ANISOTROPIC:
        f = v.reshape(n[0], n[1], n[2], n[3], C)
    elif layout == HALFDIFF:
        f = v.reshape(n[0], n[1], n[2], C)
    elif flags & 1:
        i, r = np.triu_indices(n[0])
        half = v.reshape(len(i), n[2], C)
        f = np.empty((n[0], n[1], n[2], C), dtype="<f4")
        f[i, r], f[r, i] = half, half
    else:
        f = v.reshape(n[0], n[1], n[2], C)
    return Table(layout, f, description, filled)


def read_brdf(path: PathLike, verify: bool = True) -> tuple[np.ndarray, str]:
    """``(f, description)`` of :func:`read_table` (the layout follows from the file)."""
    t = read_table(path, verify)
    return t.f, t.description


def halfdiff_node_angles(nh: int, nd: int, nphi: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node angles in degrees of a half/difference table: the centres of MERL's bins,
    theta_h = ((i + 1/2)/nh)^2 * 90, theta_d = (j + 1/2) * 90/nd, phi_d = (k + 1/2) * 180/nphi."""
    return (((np.arange(nh) + 0.5) / nh) ** 2 * 90.0, (np.arange(nd) + 0.5) * 90.0 / nd,
            (np.arange(nphi) + 0.5) * 180.0 / nphi)


def halfdiff_angles(wi: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rusinkiewicz's (theta_h, theta_d, phi_d) in radians of local direction pairs (N, 3) each
    (normal +z): h = normalize(wi + wo); d = wi in the frame of h with phi_h = 0 (rotations
    about z by -phi_h, then about y by -theta_h); phi_d in [0, pi) (period pi: reciprocity)."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    th = np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2])
    ph = np.arctan2(h[:, 1], h[:, 0])
    c, s = np.cos(-ph), np.sin(-ph)
    x, y, z = wi[:, 0] * c - wi[:, 1] * s, wi[:, 0] * s + wi[:, 1] * c, wi[:, 2]
    c, s = np.cos(-th), np.sin(-th)
    dx, dy, dz = x * c + z * s, y, -x * s + z * c
    td = np.arctan2(np.hypot(dx, dy), dz)
    pd = np.mod(np.arctan2(dy, dx), np.pi)
    return th, td, pd


def halfdiff_lookup(f: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """Trilinear lookup (N, C) of a half/difference table ``f`` (theta_h, theta_d, phi_d, C) at
    local direction pairs, both above the horizon, as ``brdf_data/README.md`` specifies."""
    nh, nd, nphi, C = f.shape
    th, td, pd = halfdiff_angles(np.asarray(wi, float), np.asarray(wo, float))
    # positions in node units: node k at k; the virtual pole (theta = 0) at -1/2
    x = np.sqrt(np.clip(th, 0, np.pi / 2) / (np.pi / 2)) * nh - 0.5
    y = np.clip(td, 0, np.pi / 2) / (np.pi / 2) * nd - 0.5
    z = np.mod(pd / np.pi * nphi - 0.5, nphi)
    ff = f.astype(np.float64)
    pole_h = ff[0].mean(axis=1)      # (nd, C): theta_h = 0, per theta_d node
    pole_d = ff[:, 0].mean(axis=1)   # (nh, C): theta_d = 0, per theta_h node

    def axis(x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        lo = np.where(x < 0, -1, np.minimum(np.floor(x), n - 1)).astype(int)
        t = np.where(x < 0, 2 * (x + 0.5), x - lo)
        t = np.where(x >= n - 1, 0.0, t)
        return lo, np.minimum(lo + 1, n - 1), t

    i0, i1, ti = axis(x, nh)
    j0, j1, tj = axis(y, nd)
    k0 = np.floor(z).astype(int) % nphi
    k1, tk = (k0 + 1) % nphi, z - np.floor(z)

    def value(i: np.ndarray, j: np.ndarray, k: np.ndarray) -> np.ndarray:
        out = ff[np.maximum(i, 0), np.maximum(j, 0), k]
        out = np.where(((i < 0) & (j >= 0))[:, None], pole_h[np.maximum(j, 0)], out)
        out = np.where(((j < 0) & (i >= 0))[:, None], pole_d[np.maximum(i, 0)], out)
        return np.where(((i < 0) & (j < 0))[:, None], pole_h[0], out)

    acc = np.zeros((len(x), C))
    for i, wi_ in ((i0, 1 - ti), (i1, ti)):
        for j, wj in ((j0, 1 - tj), (j1, tj)):
            for k, wk in ((k0, 1 - tk), (k1, tk)):
                acc += (wi_ * wj * wk)[:, None] * value(i, j, k)
    return acc


def write_brdf(path: PathLike, f: np.ndarray, description: str = "", nodata_filled: int = 0) -> Path:
    """Write an unfolded isotropic table ``f`` of shape (n, n, 2n-1, C), C in {1, 3}, in 1/sr.

    NaN values are written as they are (no-data). Negative values and Inf are refused.
    """
    f = np.asarray(f, dtype="<f4")
    if f.ndim != 4 or f.shape[3] not in (1, 3):
        raise ValueError(f"expected (theta_i, theta_r, phi, C) with C 1 or 3, got {f.shape}")
    n0, n1, n2, C = f.shape
    if np.isinf(f).any() or (f < 0).any():
        raise ValueError("values must be finite and >= 0 (NaN marks no data)")
    desc = description.encode("utf-8")[:4096]
    off = (112 + len(desc) + 15) & ~15
    payload = f.tobytes(order="C")
    flags = 2 if nodata_filled else 0
    head = struct.pack("<8s10I", MAGIC, 1, off, 1, C, flags, 1, n0, n1, n2, 1)
    head += struct.pack("<4d", 90.0 / (n0 - 1), 90.0 / (n1 - 1), 180.0 / (n2 - 1), 0.0)
    head += struct.pack("<3Q2I", len(payload), fnv1a64(payload), nodata_filled, len(desc), 0)
    data = head + desc + b"\0" * (off - 112 - len(desc)) + payload
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    tmp.replace(path)
    return path


def node_angles(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Node angles in degrees of an isotropic table with n theta nodes: (theta, phi)."""
    return np.linspace(0.0, 90.0, n), np.linspace(0.0, 180.0, 2 * n - 1)
