"""Reference scenes: the single source of the numbers that define them.

The ``.pov`` writer (:mod:`harness.core.povwriter`) and the analytic model (:mod:`harness.reference.expect`)
both read these dataclasses, so a scene cannot say one thing to POV-Ray and another to the
expectation.

Conventions (all checked against stock POV-Ray 3.7.0.10 renders by the tests):

* **Cameras** are orthographic with explicit ``location/direction/right/up`` and no
  ``look_at`` (POV's ``look_at`` camera is left-handed and mirrors x). With ``-A`` POV shoots
  exactly one ray per pixel, through the pixel centre (``tracepixel.cpp``: ``x += 0.5``), from
  ``location + x0*right + y0*up`` along ``direction`` where, for column ``c`` and row ``r``
  (row 0 at the top), ``x0 = (c + 0.5)/W - 0.5`` and ``y0 = 0.5 - (r + 0.5)/H``.
* **Lights** are ``parallel`` light sources with ``point_at`` the origin. For a parallel light
  POV replaces the per-point direction by the constant ``normalize(location - point_at)``
  (``Trace::ComputeOneWhiteLightRay``), and applies no distance attenuation unless
  ``fade_distance/fade_power`` are given (they never are here), so the light is exactly
  directional and its colour is the irradiance at normal incidence. The location only
  sets how far shadow rays travel, so it is put far beyond the geometry.
* **Finishes** are dicts of POV finish keywords (see :data:`HARNESS_FINISH_DEFAULTS`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence, Union

import numpy as np

RGB = tuple[float, float, float]
Vec3 = tuple[float, float, float]
Colour = Union[float, Sequence[float]]

#: Written into every finish unless the dict names the keyword. Unlike POV's own defaults
#: (ambient 0.1, diffuse 0.6) only what a finish dict names contributes light.
HARNESS_FINISH_DEFAULTS: Mapping[str, Any] = {"ambient": 0.0, "emission": 0.0, "diffuse": 0.0}

#: POV-Ray's own defaults (``Create_Finish`` in texture.cpp) for parameters the harness does
#: not write unless asked; the analytic model needs them.
POV_FINISH_DEFAULTS: Mapping[str, Any] = {
    "brilliance": 1.0,
    "phong_size": 40.0,
    "roughness": 0.05,
    "metallic": 0.0,
}


def written_finish(spec: Mapping[str, Any]) -> dict[str, Any]:
    """The keywords the ``.pov`` file will contain for finish ``spec`` (harness defaults first)."""
    return {**HARNESS_FINISH_DEFAULTS, **spec}


def resolved_finish(spec: Mapping[str, Any]) -> dict[str, Any]:
    """Every parameter POV will use for finish ``spec``: POV defaults < harness defaults < spec."""
    return {**POV_FINISH_DEFAULTS, **HARNESS_FINISH_DEFAULTS, **spec}


def rgb(c: Colour) -> RGB:
    """A grey level or an RGB triple as an RGB tuple of floats."""
    if isinstance(c, (int, float)):
        return (float(c),) * 3
    t = tuple(float(x) for x in c)
    if len(t) != 3:
        raise ValueError(f"colour must be a float or 3 floats, got {c!r}")
    return t  # type: ignore[return-value]


def unit(v: Sequence[float]) -> np.ndarray:
    """``v`` normalised, as a float64 array."""
    a = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(a)
    if n == 0.0:
        raise ValueError("cannot normalise a zero vector")
    return a / n


def spherical(theta_deg: float, phi_deg: float) -> np.ndarray:
    """Unit vector at polar angle ``theta`` from +z and azimuth ``phi`` from +x towards +y."""
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


@dataclass(frozen=True)
class OrthoCamera:
    """POV ``camera { orthographic location direction right up }``, vectors given explicitly.

    ``right`` and ``up`` are the full width and height of the view window (scene units).
    """

    location: Vec3
    direction: Vec3
    right: Vec3
    up: Vec3

    def ray_origins(self, width: int, height: int) -> np.ndarray:
        """Origins (H, W, 3) of POV's ``-A`` rays, one through each pixel centre."""
        x0 = (np.arange(width) + 0.5) / width - 0.5
        y0 = 0.5 - (np.arange(height) + 0.5) / height
        loc, right, up = (np.asarray(v, dtype=np.float64) for v in (self.location, self.right, self.up))
        return loc + x0[None, :, None] * right + y0[:, None, None] * up

    def ray_direction(self) -> np.ndarray:
        """The common unit direction of all primary rays."""
        return unit(self.direction)


@dataclass(frozen=True)
class WorldLight:
    """A directional light in world coordinates: unit vector towards the light, RGB colour."""

    direction: np.ndarray
    colour: RGB


@dataclass(frozen=True)
class DistantLight:
    """A light at polar angle ``theta_deg`` from a scene's reference axis, azimuth ``phi_deg``.

    ``colour`` is POV's light colour: the irradiance on a surface facing the light.
    Each scene documents its reference axis.
    """

    theta_deg: float
    phi_deg: float = 0.0
    colour: RGB = (1.0, 1.0, 1.0)


def light_distance(extent: float) -> float:
    """How far to put a parallel light: far beyond geometry of size ``extent`` (see module doc)."""
    return 1000.0 * max(extent, 1.0)


@dataclass(frozen=True)
class SphereScene:
    """A sphere of ``radius`` at the origin, seen by an orthographic camera that frames it exactly.

    The camera sits on -z looking along +z (POV's usual view): image +x is world +x, image up is
    world +y, and the view window is ``2 radius`` square, so pixel centres map analytically to
    points of the sphere (a non-square image gets non-square pixels, still exact). Light angles are measured from the direction *towards the camera*
    (world -z): ``theta 0`` is a headlight; ``phi`` is the azimuth from image +x towards image up.
    """

    lights: tuple[DistantLight, ...] = (DistantLight(0.0),)
    finish: Mapping[str, Any] = field(default_factory=lambda: {"diffuse": 0.6})
    pigment: RGB = (1.0, 1.0, 1.0)
    width: int = 64
    height: int = 64
    radius: float = 1.0
    camera_distance: float = 10.0

    def camera(self) -> OrthoCamera:
        """The exact-framing orthographic camera."""
        r = self.radius
        return OrthoCamera(location=(0.0, 0.0, -self.camera_distance), direction=(0.0, 0.0, 1.0),
                           right=(2.0 * r, 0.0, 0.0), up=(0.0, 2.0 * r, 0.0))

    def world_lights(self) -> list[WorldLight]:
        """Lights as world directions: ``theta`` from world -z, ``phi`` from +x towards +y."""
        out = []
        for lt in self.lights:
            v = spherical(lt.theta_deg, lt.phi_deg)
            out.append(WorldLight(np.array([v[0], v[1], -v[2]]), rgb(lt.colour)))
        return out

    def extent(self) -> float:
        """Size of the geometry, for placing lights."""
        return max(self.radius, self.camera_distance)

    def label(self) -> str:
        """Short description for reports."""
        ls = ", ".join(f"θ={lt.theta_deg:g}° φ={lt.phi_deg:g}°" for lt in self.lights)
        return f"sphere {dict(self.finish)} light {ls}"


@dataclass(frozen=True)
class FlatSampleScene:
    """A virtual gonioreflectometer: a flat square sample filling the frame.

    The sample's top face is the plane z = 0 with normal +z, so world coordinates *are* the
    local shading frame (normal +z, tangent +x). The light is at ``(theta_i, phi_i = 0)``;
    the orthographic camera looks along ``-w_r`` with ``w_r = (theta_r, phi)``, so every pixel
    sees the same pair of directions and ``pixel = pi f(w_r, w_i) cos(theta_i) E`` in POV units.
    The camera's ``up`` is the projection of the normal (sample "up" appears up in the image).
    """

    theta_i_deg: float = 0.0
    theta_r_deg: float = 0.0
    phi_deg: float = 0.0
    light_colour: RGB = (1.0, 1.0, 1.0)
    finish: Mapping[str, Any] = field(default_factory=lambda: {"diffuse": 0.5})
    pigment: RGB = (1.0, 1.0, 1.0)
    width: int = 8
    height: int = 8
    window: float = 1.0

    def __post_init__(self) -> None:
        for name in ("theta_i_deg", "theta_r_deg"):
            v = getattr(self, name)
            if not 0.0 <= v < 90.0:
                raise ValueError(f"{name} must be in [0, 90), got {v}")

    def wi(self) -> np.ndarray:
        """Unit vector towards the light (local = world frame)."""
        return spherical(self.theta_i_deg, 0.0)

    def wo(self) -> np.ndarray:
        """Unit vector towards the camera (local = world frame)."""
        return spherical(self.theta_r_deg, self.phi_deg)

    def half_size(self) -> float:
        """Half the sample's side: the view window's footprint on z = 0, with margin."""
        return 2.0 * (0.5 + 0.5 / math.cos(math.radians(self.theta_r_deg))) * self.window + 1.0

    def camera(self) -> OrthoCamera:
        """Orthographic camera along ``-w_r``; ``right`` horizontal, ``up`` = direction x right."""
        wo = self.wo()
        p = math.radians(self.phi_deg)
        right = np.array([math.sin(p), -math.cos(p), 0.0])
        direction = -wo
        up = np.cross(direction, right)
        dist = 10.0 + math.tan(math.radians(self.theta_r_deg)) * self.window
        return OrthoCamera(location=tuple(dist * wo), direction=tuple(direction),
                           right=tuple(self.window * right), up=tuple(self.window * up))

    def world_lights(self) -> list[WorldLight]:
        """The single light, as a world direction."""
        return [WorldLight(self.wi(), rgb(self.light_colour))]

    def extent(self) -> float:
        """Size of the geometry, for placing lights."""
        return self.half_size() + 20.0

    def label(self) -> str:
        """Short description for reports."""
        return (f"flat {dict(self.finish)} θi={self.theta_i_deg:g}° θr={self.theta_r_deg:g}° "
                f"φ={self.phi_deg:g}°")


@dataclass(frozen=True)
class ShadowEdgeSlabScene:
    """Placeholder for subsurface tests: a thick slab with a straight shadow edge on its face.

    The slab's top face is z = 0 (normal +z, units: whatever ``mm_per_unit`` later says). An
    invisible (``no_image``) blade at height ``blade_height`` casts a shadow over x < 0 of the
    face: it covers x < ``blade_height * tan(theta_i)`` so the edge lands exactly on x = 0.
    The orthographic camera looks straight down (-z), image +x = world +x, image up = world +y.
    The light is at ``(theta_i, phi = 0)`` from the normal. Without subsurface transport the
    face is ``d cos(theta_i) E`` for x > 0 and 0 for x < 0; with it, light bleeds across.
    """

    theta_i_deg: float = 0.0
    light_colour: RGB = (1.0, 1.0, 1.0)
    finish: Mapping[str, Any] = field(default_factory=lambda: {"diffuse": 0.6})
    pigment: RGB = (1.0, 1.0, 1.0)
    width: int = 64
    height: int = 16
    view_width: float = 8.0
    thickness: float = 50.0
    blade_height: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 <= self.theta_i_deg < 90.0:
            raise ValueError(f"theta_i_deg must be in [0, 90), got {self.theta_i_deg}")

    def view_height(self) -> float:
        """Height of the view window (square pixels)."""
        return self.view_width * self.height / self.width

    def half_size(self) -> float:
        """Half side of the slab: much larger than the view so its sides do not matter."""
        return 10.0 * max(self.view_width, self.view_height()) + self.thickness

    def blade_edge(self) -> float:
        """x of the blade's edge, chosen so the shadow edge on the face is at x = 0."""
        return self.blade_height * math.tan(math.radians(self.theta_i_deg))

    def camera(self) -> OrthoCamera:
        """Orthographic camera looking down -z."""
        return OrthoCamera(location=(0.0, 0.0, 10.0 + self.blade_height), direction=(0.0, 0.0, -1.0),
                           right=(self.view_width, 0.0, 0.0), up=(0.0, self.view_height(), 0.0))

    def world_lights(self) -> list[WorldLight]:
        """The single light, as a world direction."""
        return [WorldLight(spherical(self.theta_i_deg, 0.0), rgb(self.light_colour))]

    def extent(self) -> float:
        """Size of the geometry, for placing lights."""
        return self.half_size() + self.thickness

    def label(self) -> str:
        """Short description for reports."""
        return f"slab edge {dict(self.finish)} θi={self.theta_i_deg:g}°"


Scene = Union[SphereScene, FlatSampleScene, ShadowEdgeSlabScene]
