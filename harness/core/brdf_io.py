"""Read and write ``.brdf`` tables in numpy (format: ``brdf_data/README.md``).

``write_brdf`` writes unfolded isotropic tables and keeps no-data values (NaN) as they are,
so a sparse table (e.g. from :mod:`harness.tools.sphere_sampling`) can be filled by
``brdftool fill`` with the format's documented rule, or fitted directly by ``brdftool fit``
(which skips no-data cells).
"""

from __future__ import annotations

import struct
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


def read_brdf(path: PathLike, verify: bool = True) -> tuple[np.ndarray, str]:
    """``(f, description)``: f in 1/sr, (theta_i, theta_r, phi, C) or (theta_i, phi_i, theta_r, phi_r, C)."""
    d = Path(path).read_bytes()
    magic, version, off, layout, C, flags, units, *n = struct.unpack_from("<8s10I", d, 0)
    nbytes, checksum, filled, dlen, reserved = struct.unpack_from("<3Q2I", d, 80)
    if magic != MAGIC or version != 1 or units != 1 or len(d) != off + nbytes:
        raise ValueError(f"{path}: not a version-1 .brdf table")
    description = d[112:112 + dlen].decode("utf-8", "replace")
    payload = d[off:off + nbytes]
    if verify and fnv1a64(payload) != checksum:
        raise ValueError(f"{path}: checksum mismatch")
    v = np.frombuffer(payload, dtype="<f4")
    if layout == 2:
        return v.reshape(n[0], n[1], n[2], n[3], C), description
    if flags & 1:
        i, r = np.triu_indices(n[0])
        half = v.reshape(len(i), n[2], C)
        full = np.empty((n[0], n[1], n[2], C), dtype="<f4")
        full[i, r], full[r, i] = half, half
        return full, description
    return v.reshape(n[0], n[1], n[2], C), description


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
