"""Image comparison: error statistics with precise definitions, and error-map PNGs.

Definitions, for a test image ``a`` and a reference ``b`` over the pixels of ``mask`` (all
pixels if None; every colour channel of a masked pixel counts as one sample):

* ``rel_rmse   = sqrt(mean((a - b)^2)) / sqrt(mean(b^2))``
* ``max_abs    = max |a - b|``
* ``max_rel    = max |a - b| / |b|`` over samples with ``|b| >= rel_floor``; ``rel_floor``
  defaults to ``1e-3 * max |b|`` so near-black pixels do not dominate
* ``half_ulps  = max |a - b| / ulp_half(b)``: error in units of the float16 spacing at ``b``
  (stock POV writes half-float EXR: an exact render rounds to within 0.5 ulp)
* ``n_nan``, ``n_inf``, ``n_negative``: counts of NaN, ±Inf and negative samples in ``a``
  (over the whole image, not only the mask).

Half-float bound: round-to-nearest to 11 significant bits changes a value by at most
``2^-11 = 4.88e-4`` relative (normal range, ``|x| >= 6.1e-5``), so an exact render written
as half has ``rel_rmse <= 4.88e-4`` (see :data:`HALF_REL_EPS`).
"""

from __future__ import annotations

import os
import textwrap
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional, Union

import numpy as np

from harness.core import plotting

#: Largest relative rounding error of float16 in its normal range (round to nearest).
HALF_REL_EPS: float = 2.0 ** -11
#: Largest relative rounding error of float32 (round to nearest).
FLOAT_REL_EPS: float = 2.0 ** -24


def _samples(a: np.ndarray, b: np.ndarray, mask: Optional[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise ValueError(f"shape mismatch: {a.shape} vs {b.shape}")
    if mask is None:
        return a.ravel(), b.ravel()
    m = np.asarray(mask, dtype=bool)
    if m.shape != a.shape[: m.ndim]:
        raise ValueError(f"mask shape {m.shape} does not match image {a.shape}")
    return a[m].ravel(), b[m].ravel()


def rel_rmse(a: np.ndarray, b: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """``sqrt(mean((a-b)^2)) / sqrt(mean(b^2))`` over the mask; NaN if the reference is all 0."""
    x, y = _samples(a, b, mask)
    den = np.sqrt(np.mean(y * y)) if y.size else 0.0
    return float(np.sqrt(np.mean((x - y) ** 2)) / den) if den > 0 else float("nan")


def max_abs_error(a: np.ndarray, b: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """``max |a - b|`` over the mask (0 for an empty mask)."""
    x, y = _samples(a, b, mask)
    return float(np.max(np.abs(x - y))) if x.size else 0.0


def max_rel_error(a: np.ndarray, b: np.ndarray, mask: Optional[np.ndarray] = None,
                  rel_floor: Optional[float] = None) -> float:
    """``max |a - b| / |b|`` over samples with ``|b| >= rel_floor`` (default ``1e-3 max|b|``)."""
    x, y = _samples(a, b, mask)
    if not y.size:
        return 0.0
    floor = 1e-3 * float(np.max(np.abs(y))) if rel_floor is None else rel_floor
    keep = np.abs(y) >= floor
    keep &= np.abs(y) > 0
    return float(np.max(np.abs(x[keep] - y[keep]) / np.abs(y[keep]))) if keep.any() else 0.0


def ulp_half(x: np.ndarray) -> np.ndarray:
    """Spacing of float16 numbers at ``|x|`` (subnormal spacing 2^-24 below 2^-14)."""
    ax = np.abs(np.asarray(x, dtype=np.float64))
    e = np.floor(np.log2(np.maximum(ax, 2.0 ** -14)))
    return np.power(2.0, e - 10.0)


def max_half_ulps(a: np.ndarray, b: np.ndarray, mask: Optional[np.ndarray] = None) -> float:
    """``max |a - b| / ulp_half(b)``: 0.5 means "b rounded correctly to half"."""
    x, y = _samples(a, b, mask)
    return float(np.max(np.abs(x - y) / ulp_half(y))) if x.size else 0.0


def nonfinite_counts(a: np.ndarray) -> dict[str, int]:
    """Counts of NaN, ±Inf and negative samples in ``a``."""
    a = np.asarray(a, dtype=np.float64)
    return {"n_nan": int(np.isnan(a).sum()), "n_inf": int(np.isinf(a).sum()),
            "n_negative": int((a < 0).sum())}


@dataclass(frozen=True)
class ErrorStats:
    """All statistics of :func:`compare` (see the module docstring for definitions)."""

    rel_rmse: float
    max_abs: float
    max_rel: float
    half_ulps: float
    mean_ref: float
    n_samples: int
    n_nan: int
    n_inf: int
    n_negative: int
    worst_pixel: tuple[int, int]

    def as_dict(self) -> dict:
        """Plain dict, for reports and JSON."""
        return asdict(self)

    def __str__(self) -> str:
        return (f"rel-RMSE {self.rel_rmse:.3e}, max abs {self.max_abs:.3e}, max rel {self.max_rel:.3e}, "
                f"{self.half_ulps:.2f} half-ulp, worst pixel (row, col) {self.worst_pixel}, "
                f"NaN {self.n_nan} Inf {self.n_inf} neg {self.n_negative}, {self.n_samples} samples")


def compare(a: np.ndarray, b: np.ndarray, mask: Optional[np.ndarray] = None,
            rel_floor: Optional[float] = None) -> ErrorStats:
    """Every statistic of image ``a`` against reference ``b`` (H, W[, C]) over ``mask`` (H, W)."""
    a64 = np.asarray(a, dtype=np.float64)
    b64 = np.asarray(b, dtype=np.float64)
    diff = np.abs(a64 - b64)
    if diff.ndim == 3:
        diff = diff.max(axis=2)
    if mask is not None:
        diff = np.where(mask, diff, -np.inf)
    worst = np.unravel_index(int(np.nanargmax(np.nan_to_num(diff, nan=np.inf))), diff.shape)
    _, y = _samples(a64, b64, mask)
    return ErrorStats(rel_rmse=rel_rmse(a64, b64, mask), max_abs=max_abs_error(a64, b64, mask),
                      max_rel=max_rel_error(a64, b64, mask, rel_floor),
                      half_ulps=max_half_ulps(a64, b64, mask),
                      mean_ref=float(np.mean(y)) if y.size else 0.0, n_samples=int(y.size),
                      worst_pixel=(int(worst[0]), int(worst[1])), **nonfinite_counts(a64))


#: Size of an error map in pixels (= CSS pixels on the pages, which show it at this size).
MAP_SIZE = (330, 260)


def error_map_png(path: Union[str, os.PathLike], a: np.ndarray, b: np.ndarray,
                  mask: Optional[np.ndarray] = None, relative: bool = False,
                  title: str = "", rel_floor: Optional[float] = None,
                  names: tuple[str, str] = ("a", "b")) -> Path:
    """Save a PNG of the per-pixel error (max over channels) with a colour bar.

    Signed ``a - b`` (diverging colours, symmetric range) or, with ``relative``,
    ``|a - b| / max(|b|, rel_floor)``. Pixels outside the mask are grey. ``names`` are what
    the colour bar calls ``a`` and ``b`` (e.g. ``("new", "golden")``).
    """
    na, nb = names
    plt = plotting.pyplot()

    a64 = np.asarray(a, dtype=np.float64)
    b64 = np.asarray(b, dtype=np.float64)
    if relative:
        floor = 1e-3 * float(np.max(np.abs(b64))) if rel_floor is None else rel_floor
        err = np.abs(a64 - b64) / np.maximum(np.abs(b64), max(floor, 1e-300))
        err = err.max(axis=2) if err.ndim == 3 else err
        cmap, label = "magma", f"|{na} - {nb}| / |{nb}|"
    else:
        d = a64 - b64
        if d.ndim == 3:
            idx = np.abs(d).argmax(axis=2)
            d = np.take_along_axis(d, idx[..., None], axis=2)[..., 0]
        err, cmap, label = d, "RdBu_r", f"{na} - {nb} (channel of largest |difference|)"
    shown = np.ma.masked_where(~np.asarray(mask, bool), err) if mask is not None else np.ma.asarray(err)
    shown = np.ma.masked_invalid(shown)
    # Made at the size the pages show it (MAP_SIZE px, natural size): every label at least
    # plotting.SMALL_PT, i.e. 10 px on screen; the title and the colour bar's label wrap.
    fig, ax = plt.subplots(figsize=(MAP_SIZE[0] / plotting.DPI, MAP_SIZE[1] / plotting.DPI), dpi=plotting.DPI)
    cm = plt.get_cmap(cmap).with_extremes(bad="0.6")
    if relative:
        im = ax.imshow(shown, cmap=cm, interpolation="nearest", vmin=0.0)
    else:
        lim = float(np.max(np.abs(shown))) if shown.count() else 1.0
        im = ax.imshow(shown, cmap=cm, interpolation="nearest", vmin=-lim or -1.0, vmax=lim or 1.0)
    cb = fig.colorbar(im, ax=ax, fraction=0.08, pad=0.03)
    cb.set_label("\n".join(textwrap.wrap(label, 34)), fontsize=plotting.SMALL_PT)
    cb.ax.tick_params(labelsize=plotting.SMALL_PT)
    cb.ax.yaxis.get_offset_text().set_fontsize(plotting.SMALL_PT)
    ax.set_title("\n".join(textwrap.wrap(title or label, 40)), fontsize=8)
    ax.set_xticks([])
    ax.set_yticks([])
    fig.tight_layout(pad=0.3)
    plotting.save(fig, path)
    return Path(path)
