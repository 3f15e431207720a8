"""Scene dataclass → POV-Ray 3.7 scene text.

Everything written is linear: ``global_settings { assumed_gamma 1.0 }`` makes POV's working
gamma 1, and POV 3.7's EXR writer ignores ``File_Gamma`` (``openexr.cpp`` encodes with
``TranscodingGammaCurve(workingGamma, Neutral)``), so EXR pixels are the linear values POV
computed. ``tests/test_harness_sphere.py`` checks this by rendering with ``File_Gamma=2.2``.

Finishes are written from dicts through :data:`FINISH_KEYWORDS`; a new finish (``brdf_table``,
``ward``, ``dipole``…) is one more entry there::

    FINISH_KEYWORDS["brdf_table"] = string_keyword
"""

from __future__ import annotations

import math
from functools import singledispatch
from typing import Any, Callable, Mapping, Sequence, Union

import numpy as np

from harness.core.scenes import (FlatSampleScene, OrthoCamera, Scene, ShadowEdgeSlabScene, SphereScene,
                                 WorldLight, light_distance, rgb, written_finish)

#: Writes one finish item: ``(keyword, value) -> text``.
FinishWriter = Callable[[str, Any], str]


def fmt(x: float) -> str:
    """A float as POV text that round-trips exactly (shortest repr); rejects NaN/Inf."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write non-finite number {x!r} to a scene")
    if x == 0.0:
        return "0"
    return repr(x)


def vec(v: Union[Sequence[float], np.ndarray]) -> str:
    """A 3-vector as ``<x, y, z>``."""
    a = [fmt(c) for c in np.asarray(v, dtype=np.float64).ravel()]
    if len(a) != 3:
        raise ValueError(f"expected 3 components, got {len(a)}")
    return f"<{a[0]}, {a[1]}, {a[2]}>"


def colour(c: Any) -> str:
    """A grey level or RGB triple as ``rgb <r, g, b>``."""
    return f"rgb {vec(rgb(c))}"


def float_keyword(name: str, value: Any) -> str:
    """``name value`` for a scalar parameter."""
    return f"{name} {fmt(value)}"


def colour_keyword(name: str, value: Any) -> str:
    """``name rgb <r, g, b>`` (a scalar becomes grey)."""
    return f"{name} {colour(value)}"


def string_keyword(name: str, value: Any) -> str:
    """``name "value"`` for a file name or word; refuses embedded quotes."""
    s = str(value)
    if '"' in s or "\n" in s:
        raise ValueError(f"{name}: string {s!r} contains a quote or newline")
    return f'{name} "{s}"'


def block_keyword(name: str, value: Mapping[str, Any]) -> str:
    """``name { k v … }``: nested keyword block; numbers, triples, strings and sub-blocks."""
    parts = []
    for k, v in value.items():
        if isinstance(v, Mapping):
            parts.append(block_keyword(k, v))
        elif isinstance(v, str):
            parts.append(f"{k} {v}" if v.isidentifier() else string_keyword(k, v))
        elif isinstance(v, (list, tuple, np.ndarray)):
            parts.append(f"{k} {vec(v)}")
        elif isinstance(v, bool):
            parts.append(f"{k} {'on' if v else 'off'}")
        else:
            parts.append(float_keyword(k, v))
    return f"{name} {{ " + " ".join(parts) + " }"


def model_keyword(name: str, value: Mapping[str, Any]) -> str:
    """``brdf_table { "file" … }`` / ``brdf_model { "spec" … }`` from a dict.

    The dict holds ``file`` (brdf_table) or ``spec`` (brdf_model), and optionally
    ``interpolate`` (0|1), ``scale`` (grey or RGB), ``use_color`` (bool), ``direction``,
    ``samples`` (glossy reflection rays).
    """
    v = dict(value)
    head = v.pop("file" if name == "brdf_table" else "spec")
    if '"' in str(head) or "\n" in str(head):
        raise ValueError(f"{name}: {head!r} contains a quote or newline")
    parts = [f'"{head}"'] + model_options(v)
    if v:
        raise KeyError(f"{name}: unknown keys {sorted(v)}")
    return f"{name} {{ " + " ".join(parts) + " }"


def model_options(v: dict[str, Any]) -> list[str]:
    """The options of a brdf_table/brdf_model block, popped from ``v`` (what is left is unknown):
    ``interpolate`` (0|1), ``scale`` (grey or RGB), ``use_color`` (bool), ``direction``, ``samples``."""
    parts = []
    if "interpolate" in v:
        parts.append(f"interpolate {int(v.pop('interpolate'))}")
    if "scale" in v:
        parts.append(f"scale {colour(v.pop('scale'))}")
    if "use_color" in v:
        parts.append(f"use_color {'on' if v.pop('use_color') else 'off'}")
    if "direction" in v:
        parts.append(f"direction {vec(v.pop('direction'))}")
    if "samples" in v:
        parts.append(f"samples {int(v.pop('samples'))}")
    return parts


#: Finish keyword → writer. Stock POV 3.7 keywords the harness models analytically; extend
#: here for new finishes (one entry each).
FINISH_KEYWORDS: dict[str, FinishWriter] = {
    "ambient": colour_keyword,
    "emission": colour_keyword,
    "diffuse": float_keyword,
    "brilliance": float_keyword,
    "phong": float_keyword,
    "phong_size": float_keyword,
    "specular": float_keyword,
    "roughness": float_keyword,
    "metallic": float_keyword,
    "brdf_table": model_keyword,
    "brdf_model": model_keyword,
}


def finish_block(spec: Mapping[str, Any]) -> str:
    """``finish { … }`` for finish dict ``spec`` (harness defaults ambient/emission/diffuse 0 first).

    Raises ``KeyError`` naming the known keywords when ``spec`` has an unknown one.
    """
    items = []
    for k, v in written_finish(spec).items():
        try:
            writer = FINISH_KEYWORDS[k]
        except KeyError:
            raise KeyError(f"unknown finish keyword {k!r}; known: {sorted(FINISH_KEYWORDS)}") from None
        items.append(writer(k, v))
    return "finish { " + " ".join(items) + " }"


def texture_block(pigment: Any, finish: Mapping[str, Any]) -> str:
    """``texture { pigment { rgb … } finish { … } }``."""
    return f"texture {{\n    pigment {{ {colour(pigment)} }}\n    {finish_block(finish)}\n  }}"


def camera_block(cam: OrthoCamera) -> str:
    """An orthographic camera with explicit vectors (no ``look_at``: it is left-handed)."""
    return ("camera {\n  orthographic\n"
            f"  location  {vec(cam.location)}\n  direction {vec(cam.direction)}\n"
            f"  right     {vec(cam.right)}\n  up        {vec(cam.up)}\n}}")


def light_block(light: WorldLight, extent: float) -> str:
    """A ``parallel`` light towards ``light.direction``: exactly directional, no fading."""
    loc = light_distance(extent) * np.asarray(light.direction, dtype=np.float64)
    return (f"light_source {{\n  {vec(loc)}\n  color {colour(light.colour)}\n"
            f"  parallel\n  point_at <0, 0, 0>\n}}")


def header(label: str, global_extra: str = "") -> str:
    """``#version``, linear ``global_settings`` and a black background."""
    extra = f"\n  {global_extra}" if global_extra else ""
    return (f"// generated by harness.core.povwriter: {label}\n#version 3.7;\n"
            f"global_settings {{\n  assumed_gamma 1.0{extra}\n}}\nbackground {{ rgb 0 }}\n")


def _common(scene: Scene, global_extra: str) -> list[str]:
    parts = [header(scene.label(), global_extra), camera_block(scene.camera())]
    parts += [light_block(lt, scene.extent()) for lt in scene.world_lights()]
    return parts


@singledispatch
def scene_to_pov(scene: Any, global_extra: str = "") -> str:
    """Scene text for ``scene``. ``global_extra`` goes inside ``global_settings``."""
    raise TypeError(f"no .pov writer for {type(scene).__name__}")


@scene_to_pov.register
def _(scene: SphereScene, global_extra: str = "") -> str:
    obj = f"sphere {{\n  <0, 0, 0>, {fmt(scene.radius)}\n  {texture_block(scene.pigment, scene.finish)}\n}}"
    return "\n".join(_common(scene, global_extra) + [obj]) + "\n"


@scene_to_pov.register
def _(scene: FlatSampleScene, global_extra: str = "") -> str:
    h = scene.half_size()
    obj = (f"box {{\n  {vec((-h, -h, -1.0))}, {vec((h, h, 0.0))}\n"
           f"  {texture_block(scene.pigment, scene.finish)}\n}}")
    return "\n".join(_common(scene, global_extra) + [obj]) + "\n"


@scene_to_pov.register
def _(scene: ShadowEdgeSlabScene, global_extra: str = "") -> str:
    h = scene.half_size()
    slab = (f"box {{\n  {vec((-h, -h, -scene.thickness))}, {vec((h, h, 0.0))}\n"
            f"  {texture_block(scene.pigment, scene.finish)}\n}}")
    zb = scene.blade_height
    blade = (f"box {{  // invisible blade: casts the shadow edge onto x = 0\n"
             f"  {vec((-2.0 * h, -2.0 * h, zb))}, {vec((scene.blade_edge(), 2.0 * h, zb + 0.01))}\n"
             f"  no_image\n  texture {{ pigment {{ rgb 0 }} {finish_block({})} }}\n}}")
    return "\n".join(_common(scene, global_extra) + [slab, blade]) + "\n"
