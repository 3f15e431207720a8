"""Photographs of a sphere for :mod:`harness.tools.sphere_sampling`: the description file, the
camera's rays, and which surface point each pixel sees.

A photograph (an HDR/EXR image, linear) of a sphere under one distant light, plus a small
TOML file that says how it was taken, gives a BRDF sample per pixel of the sphere. The file
(all lengths in one unit of your choice, "scene units"; angles in degrees)::

    [image]                      # what the pixel values are
    values = "radiance"          # "radiance": pixel = L = f E cos(theta_i)   (a calibrated camera)
                                 # "pov": pixel = pi L (POV-Ray's renders: light colour = E)
    width = 256                  # optional: the photograph must have this size
    height = 256

    [camera]
    type = "orthographic"        # or "perspective"
    position = [0, 0, -10]
    look = [0, 0, 1]             # viewing direction (any length)
    up = [0, 1, 0]               # image up (made orthogonal to look)
    # right = [1, 0, 0]          # image right; default up x look (POV-Ray's left-handed axes)
    width = 2.2                  # orthographic: view width, or pixel_size = 0.0086 (per pixel)
    # fov = 30                   # perspective: horizontal field of view

    [sphere]
    centre = [0, 0, 0]           # scene units, or (orthographic camera only) in pixels:
    radius = 1                   # centre_px = [128, 128] (x from the left edge, y from the top
                                 # edge; pixel (c, r) spans c..c+1, r..r+1) and radius_px = 116

    [light]                      # the light of the photograph(s) named on the command line
    direction = [-1, 1, -1]      # towards the light (any length)
    irradiance = 1.0             # E on a surface facing the light: one value or [r, g, b]

    [mask]                       # optional: an image the size of the photograph (PNG or EXR);
    file = "ball-mask.png"       # pixels whose mean is > 0.5 are used

    [[photo]]                    # optional: photographs listed here instead of on the command
    file = "ball-30.exr"         # line, each with its own light (paths relative to this file)
    light = { direction = [0.5, 0, -1], irradiance = 1.0 }

Every problem is a :class:`PhotoError` naming the file and the key (or the image and what is
wrong with it).

A pixel counts only when all four of its corners see the sphere (no pixel straddles the
limb) and the mask keeps it; its normal n and view direction v (towards the camera) are those
of the ray through its centre. :mod:`harness.tools.sphere_sampling` then drops pixels with
cos(theta_i) or cos(theta_r) below ``min_cos`` and turns the rest into samples.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence, Union

import numpy as np

PathLike = Union[str, os.PathLike]


class PhotoError(ValueError):
    """A description or image that cannot be used: the message names the file and what to fix."""


@dataclass
class Camera:
    kind: str                  # "orthographic" | "perspective"
    position: np.ndarray
    forward: np.ndarray        # unit
    right: np.ndarray          # unit, orthogonal to forward
    up: np.ndarray             # unit, orthogonal to both
    view_width: float = 0.0    # orthographic: scene units across the image
    pixel_size: float = 0.0    # orthographic: scene units per pixel (one of the two)
    fov_deg: float = 0.0       # perspective: horizontal field of view

    def rays(self, width: int, height: int, ox: float = 0.5, oy: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        """Origins and unit directions (H, W, 3) of the rays through the points (c + ox, r + oy)
        of the pixels (c, r); (0.5, 0.5) is the centre, 0 and 1 the corners."""
        x0 = (np.arange(width) + ox) / width - 0.5
        y0 = 0.5 - (np.arange(height) + oy) / height
        X, Y = x0[None, :, None], y0[:, None, None]
        if self.kind == "orthographic":
            w = self.view_width if self.view_width > 0 else self.pixel_size * width
            h = w * height / width  # square pixels
            o = self.position + X * w * self.right + Y * h * self.up
            return o, np.broadcast_to(self.forward, o.shape).copy()
        t = math.tan(math.radians(self.fov_deg) / 2)
        d = self.forward + X * 2 * t * self.right + Y * 2 * t * (height / width) * self.up
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        return np.broadcast_to(self.position, d.shape).copy(), d


@dataclass
class Light:
    direction: np.ndarray      # unit, towards the light
    irradiance: np.ndarray     # (3,)


@dataclass
class Photo:
    path: Path
    light: Light


@dataclass
class Description:
    path: Path
    camera: Camera
    centre: np.ndarray
    radius: float
    values: str                # "radiance" | "pov"
    width: Optional[int] = None
    height: Optional[int] = None
    mask: Optional[Path] = None
    photos: list[Photo] = field(default_factory=list)

    def pixel_scale(self) -> float:
        """What divides pixel / (E cos theta_i) to give f: 1 for radiance, pi for POV units."""
        return math.pi if self.values == "pov" else 1.0


# ---------------------------------------------------------------- reading the description

class _Table:
    """One TOML table with key lookups that raise :class:`PhotoError` naming file and key."""

    def __init__(self, data: Any, file: Path, name: str) -> None:
        if not isinstance(data, dict):
            raise PhotoError(f"{file}: [{name}] must be a table (a section), found {data!r}")
        self.data, self.file, self.name = data, file, name

    def where(self, key: str) -> str:
        return f"{self.file}: [{self.name}] {key}"

    def has(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, what: str) -> Any:
        if key not in self.data:
            raise PhotoError(f"{self.where(key)}: missing ({what})")
        return self.data[key]

    def number(self, key: str, what: str, positive: bool = True, default: Optional[float] = None) -> float:
        if default is not None and key not in self.data:
            return default
        v = self.get(key, what)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or (positive and v <= 0):
            raise PhotoError(f"{self.where(key)}: expected a {'positive ' if positive else ''}number ({what}), "
                             f"found {v!r}")
        return float(v)

    def vector(self, key: str, what: str, n: int = 3, unit: bool = False) -> np.ndarray:
        v = self.get(key, what)
        if not (isinstance(v, list) and len(v) == n and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                             and math.isfinite(x) for x in v)):
            raise PhotoError(f"{self.where(key)}: expected {n} numbers ({what}), found {v!r}")
        a = np.asarray(v, dtype=np.float64)
        if unit:
            norm = np.linalg.norm(a)
            if norm == 0:
                raise PhotoError(f"{self.where(key)}: a direction cannot be zero")
            a = a / norm
        return a

    def colour(self, key: str, what: str) -> np.ndarray:
        v = self.get(key, what)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v] * 3
        if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                             and math.isfinite(x) and x > 0 for x in v)):
            raise PhotoError(f"{self.where(key)}: expected a positive number or [r, g, b] ({what}), found {v!r}")
        return np.asarray(v, dtype=np.float64)

    def section(self, key: str) -> "_Table":
        return _Table(self.get(key, f"a [{self.name}.{key}] table" if self.name else f"a [{key}] section"),
                      self.file, f"{self.name}.{key}" if self.name else key)


def _light(t: _Table) -> Light:
    return Light(t.vector("direction", "towards the light, e.g. direction = [-1, 1, -1]", unit=True),
                 t.colour("irradiance", "E on a surface facing the light, e.g. irradiance = 1.0"))


def _camera(t: _Table) -> Camera:
    kind = t.get("type", 'type = "orthographic" or "perspective"')
    if kind not in ("orthographic", "perspective"):
        raise PhotoError(f"{t.where('type')}: expected \"orthographic\" or \"perspective\", found {kind!r}")
    position = t.vector("position", "the camera's position in scene units, e.g. position = [0, 0, -10]")
    forward = t.vector("look", "the viewing direction, e.g. look = [0, 0, 1]", unit=True)
    up = t.vector("up", "image up, e.g. up = [0, 1, 0]", unit=True)
    up = up - (up @ forward) * forward
    if np.linalg.norm(up) < 1e-6:
        raise PhotoError(f"{t.where('up')}: parallel to look; image up must differ from the viewing direction")
    up = up / np.linalg.norm(up)
    if t.has("right"):
        right = t.vector("right", "image right", unit=True)
        right = right - (right @ forward) * forward - (right @ up) * up
        if np.linalg.norm(right) < 1e-6:
            raise PhotoError(f"{t.where('right')}: must not lie in the plane of look and up")
        right = right / np.linalg.norm(right)
    else:
        right = np.cross(up, forward)  # POV-Ray's left-handed axes: x = y cross z
    cam = Camera(kind, position, forward, right, up)
    if kind == "orthographic":
        if t.has("width") == t.has("pixel_size"):
            raise PhotoError(f"{t.where('width')}: an orthographic camera needs exactly one of width (scene units "
                             "across the image) and pixel_size (scene units per pixel)")
        if t.has("width"):
            cam.view_width = t.number("width", "scene units across the image")
        else:
            cam.pixel_size = t.number("pixel_size", "scene units per pixel")
    else:
        cam.fov_deg = t.number("fov", "the horizontal field of view in degrees, e.g. fov = 30")
        if cam.fov_deg >= 179:
            raise PhotoError(f"{t.where('fov')}: must be below 179 degrees, found {cam.fov_deg:g}")
    return cam


def load_description(path: PathLike, photos: Sequence[PathLike] = ()) -> Description:
    """Read and check a description; ``photos`` named on the command line use its ``[light]``."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise PhotoError(f"{path}: no such description file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise PhotoError(f"{path}: not valid TOML: {e}") from None
    top = _Table(data, path, "")
    image = top.section("image")
    values = image.get("values", '"radiance" (pixel = f E cos theta_i) or "pov" (POV-Ray renders: pi times that)')
    if values not in ("radiance", "pov"):
        raise PhotoError(f"{image.where('values')}: expected \"radiance\" or \"pov\", found {values!r}")
    size = {}
    for key in ("width", "height"):
        if image.has(key):
            v = image.get(key, "pixels")
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise PhotoError(f"{image.where(key)}: expected a whole number of pixels, found {v!r}")
            size[key] = v
    cam = _camera(top.section("camera"))
    sph = top.section("sphere")
    if sph.has("centre_px") or sph.has("radius_px"):
        if cam.kind != "orthographic":
            raise PhotoError(f"{sph.where('centre_px')}: a sphere given in pixels needs an orthographic camera; "
                             "give centre and radius in scene units for a perspective one")
        if "width" not in size or "height" not in size:
            raise PhotoError(f"{image.where('width')}: a sphere given in pixels needs the image's width and height "
                             "under [image]")
        cx, cy = sph.vector("centre_px", "the sphere's centre in pixels from the top left corner", n=2)
        rpx = sph.number("radius_px", "the sphere's radius in pixels")
        # One scene unit per pixel, the camera at the origin: where the centre pixel lands.
        w, h = size["width"], size["height"]
        cam.view_width, cam.pixel_size, cam.position = float(w), 0.0, np.zeros(3)
        centre = (cx - w / 2) * cam.right + (h / 2 - cy) * cam.up + 10 * rpx * cam.forward
        radius = rpx
    else:
        centre = sph.vector("centre", "the sphere's centre in scene units, e.g. centre = [0, 0, 0]")
        radius = sph.number("radius", "the sphere's radius in scene units")
    desc = Description(path, cam, centre, radius, values, size.get("width"), size.get("height"))
    if top.has("mask"):
        m = top.section("mask")
        f = m.get("file", "the mask image, e.g. file = \"ball-mask.png\"")
        if not isinstance(f, str) or not f:
            raise PhotoError(f"{m.where('file')}: expected a file name, found {f!r}")
        desc.mask = (path.parent / f).resolve()
    listed = data.get("photo", [])
    if listed and photos:
        raise PhotoError(f"{path}: lists [[photo]] entries; do not also name photographs on the command line")
    if photos:
        light = _light(top.section("light"))
        desc.photos = [Photo(Path(p), light) for p in photos]
    else:
        if not isinstance(listed, list) or not listed:
            raise PhotoError(f"{path}: no photographs: name them on the command line (they use [light]) or list "
                             "them as [[photo]] entries with file and light")
        for k, entry in enumerate(listed):
            t = _Table(entry, path, f"photo {k + 1}")
            f = t.get("file", "the photograph, relative to this file")
            if not isinstance(f, str) or not f:
                raise PhotoError(f"{t.where('file')}: expected a file name, found {f!r}")
            desc.photos.append(Photo((path.parent / f).resolve(), _light(t.section("light"))))
    return desc


# ---------------------------------------------------------------- images and geometry

def read_image(path: PathLike, what: str = "photograph") -> np.ndarray:
    """An EXR (linear) or PNG image as float64 (H, W, 3); a clear error for anything else."""
    from harness.core import exr

    path = Path(path)
    if not path.is_file():
        raise PhotoError(f"{path}: no such {what}")
    if path.suffix.lower() == ".png":
        import matplotlib.image as mpimg

        try:
            img = np.asarray(mpimg.imread(str(path)), dtype=np.float64)
        except (OSError, ValueError, SyntaxError) as e:
            raise PhotoError(f"{path}: not a readable PNG image ({e})") from None
        img = img[..., :3] if img.ndim == 3 else np.repeat(img[..., None], 3, axis=-1)
        return img
    try:
        return exr.read_exr(path, dtype=np.float64)
    except Exception as e:  # noqa: BLE001 - OpenEXR raises plain RuntimeError/OSError with C++ text
        raise PhotoError(f"{path}: not a readable OpenEXR image ({e}); give the {what} as linear EXR") from None


def _hit(o: np.ndarray, d: np.ndarray, centre: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Where rays o + t d first meet the sphere (t > 0): (hit mask, points)."""
    oc = o - centre
    b = np.einsum("...k,...k", d, oc)
    c = np.einsum("...k,...k", oc, oc) - radius * radius
    disc = b * b - c
    sq = np.sqrt(np.maximum(disc, 0.0))
    t = -b - sq
    t = np.where(t > 0, t, -b + sq)  # a camera inside the sphere sees its far side (useless, but defined)
    ok = (disc > 0) & (t > 0)
    return ok, o + np.where(ok, t, 0.0)[..., None] * d


@dataclass
class Geometry:
    """What each pixel (H, W) sees: ``inside`` (all four corners on the sphere), the unit normal
    and the unit direction towards the camera at the ray through its centre."""

    inside: np.ndarray
    normal: np.ndarray
    view: np.ndarray
    covered: int                # pixels whose centre sees the sphere


def sphere_geometry(desc: Description, width: int, height: int) -> Geometry:
    cam = desc.camera
    inside = np.ones((height, width), dtype=bool)
    for ox, oy in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)):
        o, d = cam.rays(width, height, ox, oy)
        inside &= _hit(o, d, desc.centre, desc.radius)[0]
    o, d = cam.rays(width, height)
    ok, p = _hit(o, d, desc.centre, desc.radius)
    n = (p - desc.centre) / desc.radius
    return Geometry(inside & ok, n, -d, int(ok.sum()))


def check_size(desc: Description, photo: Path, image: np.ndarray) -> None:
    h, w = image.shape[:2]
    if desc.width is not None and desc.height is not None and (w, h) != (desc.width, desc.height):
        raise PhotoError(f"{photo}: {w}x{h} pixels, but {desc.path} [image] says {desc.width}x{desc.height} "
                         "(width x height)")


def load_mask(desc: Description, width: int, height: int, photo: Path) -> Optional[np.ndarray]:
    """The mask as booleans (H, W), or None without one."""
    if desc.mask is None:
        return None
    m = read_image(desc.mask, "mask image")
    if m.shape[:2] != (height, width):
        raise PhotoError(f"{desc.mask}: {m.shape[1]}x{m.shape[0]} pixels, but the photograph {photo} is "
                         f"{width}x{height}; the mask must have the photograph's size")
    return m.mean(axis=-1) > 0.5
