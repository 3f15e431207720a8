"""OpenEXR reading/writing with the ``OpenEXR`` (>= 3.3) Python bindings, and PNG previews.

Stock POV-Ray 3.7 writes half-float RGB (``Imf::Rgba``); the fork writes float32 with
``+FE32``. :func:`read_exr` accepts both and reports which one it found.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Union

import numpy as np
import OpenEXR

PathLike = Union[str, os.PathLike]


@dataclass(frozen=True)
class ExrImage:
    """Pixels (H, W, 3) plus the storage type found in the file (``float16`` or ``float32``)."""

    pixels: np.ndarray
    stored_dtype: np.dtype


def read_exr_full(path: PathLike, dtype: type = np.float32) -> ExrImage:
    """Read the R, G, B channels of a scanline EXR as an (H, W, 3) array of ``dtype``.

    A single ``Y`` channel is expanded to grey. Raises ``ValueError`` naming the channels
    found when neither R/G/B nor Y is present.
    """
    f = OpenEXR.File(str(path), separate_channels=True)
    ch = f.channels()
    if all(c in ch for c in "RGB"):
        planes = [ch[c].pixels for c in "RGB"]
    elif "Y" in ch:
        planes = [ch["Y"].pixels] * 3
    else:
        raise ValueError(f"{path}: no R,G,B or Y channels (found {sorted(ch)})")
    stored = np.result_type(*[p.dtype for p in planes])
    img: np.ndarray = np.stack([np.asarray(p, dtype=dtype) for p in planes], axis=-1)
    return ExrImage(img, np.dtype(stored))


def read_exr(path: PathLike, dtype: type = np.float32) -> np.ndarray:
    """Read an EXR's RGB as an (H, W, 3) array of ``dtype`` (half or float32 files)."""
    return read_exr_full(path, dtype).pixels


def write_exr(path: PathLike, image: np.ndarray, half: bool = False) -> Path:
    """Write an (H, W, 3) or (H, W) image as a ZIP-compressed scanline EXR (float32 or half)."""
    img = np.asarray(image)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=-1)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"expected (H, W, 3) or (H, W), got shape {img.shape}")
    dt = np.float16 if half else np.float32
    channels = {c: np.ascontiguousarray(img[..., i], dtype=dt) for i, c in enumerate("RGB")}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(str(path))
    return Path(path)


def to_display(image: np.ndarray, exposure: float = 1.0, srgb: bool = True) -> np.ndarray:
    """Linear image → displayable float RGB in [0, 1]: scale, clip, optional sRGB encoding.

    NaN and Inf become 0 (a separate count reports them; see :mod:`harness.core.compare`).
    """
    img = np.nan_to_num(np.asarray(image, dtype=np.float64) * exposure, nan=0.0, posinf=0.0, neginf=0.0)
    img = np.clip(img, 0.0, 1.0)
    if srgb:
        img = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(img, 1.0 / 2.4) - 0.055)
    return img


def write_png_preview(path: PathLike, image: np.ndarray, exposure: float = 1.0,
                      srgb: bool = True, scale: Optional[int] = None) -> Path:
    """Save a PNG preview of a linear image (sRGB-encoded, clipped); ``scale`` repeats pixels."""
    import matplotlib.image as mpimg

    img = to_display(image, exposure, srgb)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=-1)
    if scale and scale > 1:
        img = np.repeat(np.repeat(img, scale, axis=0), scale, axis=1)
    mpimg.imsave(str(path), img)
    return Path(path)
