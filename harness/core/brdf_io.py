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

from harness.core.files import write_whole

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


class TableFormatError(ValueError):
    """A ``.brdf`` file the reader refuses. The message has the C++ loader's form
    ``PATH: offset N: expected X, found Y`` (N: the byte offset of the offending field or value,
    or the file size when it ends too soon), then what to do about it."""

    def __init__(self, path: PathLike, offset: int, expected: str, found: str, todo: str):
        self.path, self.offset, self.expected, self.found = str(path), int(offset), expected, found
        super().__init__(f"{path}: offset {offset}: expected {expected}, found {found}. {todo}")


#: The loader's limits (shading/src/tables/table_io.cpp and table.cpp; brdf_data/README.md, "Header").
HEADER_BYTES = 112
MAX_DESCRIPTION = 4096
MAX_PAYLOAD_BYTES = 2 << 30           # the C++ loader's default (LoadOptions::max_payload_bytes)
MAX_THETA_NODES, MAX_ISO_PHI_NODES, MAX_ANISO_PHI_NODES = 9001, 18001, 36000
MAX_HD_THETA_NODES, MAX_HD_PHI_NODES = 9000, 18000
FLAG_FOLDED, FLAG_NODATA_FILLED = 1, 2
#: The largest value a table may hold, 1/sr: the loader's kMaxTableValue (shading/table.h,
#: brdf_data/README.md "Largest value"). Above it (and at +-Inf) a value is an error in every
#: layout and under every no-data policy; a sharp lobe peaks far below it, and 1e38 rendered inf.
MAX_VALUE = 1e10

_REMAKE = ("The file is not a table this reader can use: remake it with `brdftool tabulate`, `convert` "
           "or harness.core.brdf_io.write_brdf (format: brdf_data/README.md).")
_DAMAGED = ("The file is damaged (cut short, appended to or changed after it was written): "
            "write it again from its source.")
_VALUES = ("The table holds a value no render can use: rebuild it from its source "
           "(`brdftool check FILE` lists every bad value).")
_NODATA = ("The table has no-data cells: fill them with `brdftool fill FILE -o FILLED.brdf`, "
           "or read it with nodata='keep' to see them as NaN.")


def _quoted(b: bytes) -> str:
    return '"' + "".join(chr(c) if 0x20 <= c < 0x7F and c not in (0x22, 0x5C) else f"\\x{c:02x}" for c in b) + '"'


def _axis_names(layout: int) -> tuple[str, ...]:
    return {ISOTROPIC: ("theta_i", "theta_r", "phi", "unused"), ANISOTROPIC: ("theta_i", "phi_i", "theta_r", "phi_r"),
            HALFDIFF: ("theta_h", "theta_d", "phi_d", "unused")}[layout]


def _is_phi(layout: int, a: int) -> bool:
    return a in (1, 3) if layout == ANISOTROPIC else a == 2


def _max_nodes(layout: int, a: int) -> int:
    if layout == HALFDIFF:
        return MAX_HD_PHI_NODES if a == 2 else MAX_HD_THETA_NODES
    if not _is_phi(layout, a):
        return MAX_THETA_NODES
    return MAX_ANISO_PHI_NODES if layout == ANISOTROPIC else MAX_ISO_PHI_NODES


def _step_deg(layout: int, n: list[int], a: int) -> float:
    if layout == HALFDIFF:
        return (180.0 if a == 2 else 90.0) / n[a]
    if not _is_phi(layout, a):
        return 90.0 / (n[a] - 1)
    return 360.0 / n[a] if layout == ANISOTROPIC else 180.0 / (n[a] - 1)


def _axis_deg(layout: int, n: list[int], a: int, k: int) -> float:
    if layout == HALFDIFF:
        u = (k + 0.5) / n[a]
        return 90.0 * u * u if a == 0 else (90.0 if a == 1 else 180.0) * u
    if layout == ISOTROPIC or not _is_phi(layout, a):
        if k + 1 == n[a]:
            return 180.0 if _is_phi(layout, a) else 90.0
    return k * _step_deg(layout, n, a)


def _value_label(layout: int, n: list[int], C: int, folded: bool, k: int) -> str:
    """'theta_i=5 theta_r=5 phi=25 deg, channel 1' for payload value k (the loader's wording)."""
    cell, axes = k // C, 4 if layout == ANISOTROPIC else 3
    idx = [0, 0, 0, 0]
    if folded:
        pair, idx[2] = divmod(cell, n[2])
        i = 0
        while pair >= n[0] - i:
            pair -= n[0] - i
            i += 1
        idx[0], idx[1] = i, i + pair
    else:
        for a in range(axes - 1, -1, -1):
            cell, idx[a] = divmod(cell, n[a])
    names = _axis_names(layout)
    return " ".join(f"{names[a]}={_axis_deg(layout, n, a, idx[a]):.9g}" for a in range(axes)) + f" deg, channel {k % C}"


def _float_text(v: float) -> str:
    return "nan" if v != v else f"{v:.9g}"


def read_table(path: PathLike, verify: bool = True, nodata: str = "reject") -> Table:
    """Any layout, checked as the C++ loader checks it (brdf_data/README.md, "What the loader
    checks", in its order), else :class:`TableFormatError` naming the byte offset.

    ``verify`` checks the payload checksum (pure Python, about 0.1 s per MB). ``nodata``:
    "reject" (the loader's default) refuses NaN and negative values; "keep" returns them as NaN
    (a sparse table from :func:`write_brdf`). Inf and values above :data:`MAX_VALUE` (1e10 1/sr)
    are always refused."""
    if nodata not in ("reject", "keep"):
        raise ValueError(f"nodata must be 'reject' or 'keep', not {nodata!r}")
    d = Path(path).read_bytes()
    size = len(d)

    def bad(offset: int, expected: str, found: str, todo: str = _REMAKE) -> TableFormatError:
        return TableFormatError(path, offset, expected, found, todo)

    if size >= 8 and d[:8] != MAGIC:
        raise bad(0, 'magic "PVBRDF\\x00\\x00"', _quoted(d[:8]))
    if size < HEADER_BYTES:
        raise bad(size, f"{HEADER_BYTES}-byte header", f"end of data after {size} bytes", _DAMAGED)
    version, off, layout, C, flags, units, *n = struct.unpack_from("<10I", d, 8)
    if version != 1:
        raise bad(8, "version 1", str(version))
    if layout not in (ISOTROPIC, ANISOTROPIC, HALFDIFF):
        raise bad(16, "layout 1 (isotropic), 2 (anisotropic) or 3 (half/difference)", str(layout))
    if C not in (1, 3):
        raise bad(20, "1 or 3 channels", str(C))
    if flags & ~(FLAG_FOLDED | FLAG_NODATA_FILLED):
        raise bad(24, "flags within 0x3", f"0x{flags:016x}")
    folded = bool(flags & FLAG_FOLDED)
    if folded and layout != ISOTROPIC:
        what = "an anisotropic table" if layout == ANISOTROPIC else "a half/difference table (reciprocal by construction)"
        raise bad(24, f"no reciprocity-folded flag on {what}", f"0x{flags:016x}")
    if units != 1:
        raise bad(28, "units 1 (1/sr)", str(units))
    axes = 4 if layout == ANISOTROPIC else 3
    names = _axis_names(layout)
    for a in range(4):
        if a == 3 and layout != ANISOTROPIC:
            if n[3] != 1:
                kind = "isotropic" if layout == ISOTROPIC else "half/difference"
                raise bad(44, f"1 ({kind} tables have three axes)", str(n[3]))
            continue
        hi = _max_nodes(layout, a)
        if not 2 <= n[a] <= hi:
            raise bad(32 + 4 * a, f"{names[a]} node count in [2, {hi}]", str(n[a]))
    if folded and n[1] != n[0]:
        raise bad(36, f"theta_r node count = theta_i node count ({n[0]}) in a reciprocity-folded table", str(n[1]))
    steps = struct.unpack_from("<4d", d, 48)
    for a in range(4):
        want = 0.0 if a == 3 and layout != ANISOTROPIC else _step_deg(layout, n, a)
        if not abs(steps[a] - want) <= 1e-9 * max(1.0, want):
            raise bad(48 + 8 * a, f"{names[a]} step {want:.9g} deg (from {n[a]} nodes)", f"{steps[a]:.9g}")
    cells = (n[0] * (n[0] + 1) // 2 * n[2]) if folded else int(np.prod(n[:axes], dtype=object))
    want_bytes = 4 * cells * C
    if want_bytes > MAX_PAYLOAD_BYTES:
        raise bad(32, f"a payload of at most {MAX_PAYLOAD_BYTES} bytes", f"{want_bytes} bytes")
    nbytes, checksum, filled, dlen, reserved = struct.unpack_from("<3Q2I", d, 80)
    if nbytes != want_bytes:
        raise bad(80, f"payload size {want_bytes} bytes", str(nbytes))
    measured = n[0] * n[1] * n[2] * n[3]
    if filled > measured:
        raise bad(96, f"at most {measured} filled no-data cells", str(filled))
    if dlen > MAX_DESCRIPTION:
        raise bad(104, f"description of at most {MAX_DESCRIPTION} bytes", str(dlen))
    if reserved != 0:
        raise bad(108, "reserved field 0", str(reserved))
    want_off = (HEADER_BYTES + dlen + 15) & ~15
    if off != want_off:
        raise bad(12, f"payload offset {want_off} (112-byte header + {dlen}-byte description, 16-aligned)", str(off))
    total = want_off + want_bytes
    if size < total:
        raise bad(size, f"{total} bytes ({want_bytes}-byte payload at offset {want_off})", "end of data", _DAMAGED)
    if size > total:
        raise bad(total, "end of data", f"{size - total} trailing bytes", _DAMAGED)
    pad = d[HEADER_BYTES + dlen:want_off]
    if pad.strip(b"\0"):
        k = next(i for i, c in enumerate(pad) if c)
        raise bad(HEADER_BYTES + dlen + k, "zero padding", str(pad[k]), _DAMAGED)
    description = d[HEADER_BYTES:HEADER_BYTES + dlen].decode("utf-8", "replace")
    payload = d[want_off:]
    if verify:
        sum_ = fnv1a64(payload)
        if sum_ != checksum:
            raise bad(88, f"payload FNV-1a-64 0x{checksum:016x} (header)",
                      f"0x{sum_:016x} (computed over bytes {want_off}..{total})", _DAMAGED)
    v = np.frombuffer(payload, dtype="<f4")
    # The loader's value loop: the first value (in payload order) that is +-Inf, above MAX_VALUE,
    # or (reject) NaN or negative is the error; -1e38 is no data, not an overflow.
    over = np.isinf(v) | (v > MAX_VALUE)
    nodata_mask = ~(v >= 0)
    first = np.flatnonzero(over | nodata_mask if nodata == "reject" else over)
    if first.size:
        k = int(first[0])
        label = _value_label(layout, n, C, folded, k)
        if np.isinf(v[k]):
            raise bad(want_off + 4 * k, f"a finite value at {label}", "inf" if v[k] > 0 else "-inf", _VALUES)
        if over[k]:
            raise bad(want_off + 4 * k, f"a value <= {MAX_VALUE:g} (1/sr) at {label} (larger is a unit or scale "
                      "error, or damage: brdf_data/README.md)", _float_text(float(v[k])), _VALUES)
        raise bad(want_off + 4 * k, f"a value >= 0 at {label} (no-data policy: reject)", _float_text(float(v[k])),
                  _NODATA)
    if nodata_mask.any():
        v = np.where(nodata_mask, np.float32(np.nan), v).astype("<f4")
    if layout == ANISOTROPIC:
        f = v.reshape(n[0], n[1], n[2], n[3], C)
    elif layout == HALFDIFF:
        f = v.reshape(n[0], n[1], n[2], C)
    elif folded:
        i, r = np.triu_indices(n[0])
        half = v.reshape(len(i), n[2], C)
        f = np.empty((n[0], n[1], n[2], C), dtype="<f4")
        f[i, r], f[r, i] = half, half
    else:
        f = v.reshape(n[0], n[1], n[2], C)
    return Table(layout, f, description, filled)


def read_brdf(path: PathLike, verify: bool = True, nodata: str = "reject") -> tuple[np.ndarray, str]:
    """``(f, description)`` of :func:`read_table` (the layout follows from the file)."""
    t = read_table(path, verify, nodata)
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

    NaN values are written as they are (no-data). Negative values, Inf and values above
    :data:`MAX_VALUE` are refused.
    """
    f = np.asarray(f, dtype="<f4")
    if f.ndim != 4 or f.shape[3] not in (1, 3):
        raise ValueError(f"expected (theta_i, theta_r, phi, C) with C 1 or 3, got {f.shape}")
    n0, n1, n2, C = f.shape
    if np.isinf(f).any() or (f < 0).any() or (f > MAX_VALUE).any():
        raise ValueError(f"values must be finite, >= 0 and <= {MAX_VALUE:g} 1/sr (NaN marks no data), as the "
                         "loader reads them")
    desc = description.encode("utf-8")[:4096]
    off = (112 + len(desc) + 15) & ~15
    payload = f.tobytes(order="C")
    flags = 2 if nodata_filled else 0
    head = struct.pack("<8s10I", MAGIC, 1, off, 1, C, flags, 1, n0, n1, n2, 1)
    head += struct.pack("<4d", 90.0 / (n0 - 1), 90.0 / (n1 - 1), 180.0 / (n2 - 1), 0.0)
    head += struct.pack("<3Q2I", len(payload), fnv1a64(payload), nodata_filled, len(desc), 0)
    data = head + desc + b"\0" * (off - 112 - len(desc)) + payload
    path = Path(path)
    write_whole(path, data)
    return path


def node_angles(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Node angles in degrees of an isotropic table with n theta nodes: (theta, phi)."""
    return np.linspace(0.0, 90.0, n), np.linspace(0.0, 180.0, 2 * n - 1)
