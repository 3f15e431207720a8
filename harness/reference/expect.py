"""Closed-form expected POV-Ray pixels, as pure numpy functions of the scene constants.

POV-Ray 3.7 units (no 1/pi anywhere): a light's colour ``E`` is the irradiance on a surface
facing it, and a pixel is pi x radiance. For a BRDF ``f(wo, wi)`` in 1/sr (cos(theta_i)
*excluded*, as in ``shading/include/shading/brdf/brdf.h``) one light contributes
``pi f cos(theta_i) E``, so a Lambert BRDF rho/pi renders exactly like ``diffuse rho``.

The stock terms reproduce ``source/backend/render/trace.cpp`` of 3.7.0.10 exactly:

* a light contributes nothing where ``N.L < 1e-10`` (``ComputeOneDiffuseLight``: "light on
  far side of surface", EPSILON = 1e-10; ``diffuse_back`` and ``double_illuminate`` unused);
* ``diffuse d``: ``d |N.L|^brilliance E pigment`` (``ComputeDiffuseColour``);
* ``phong P phong_size n``: with ``D`` the primary ray direction (camera → surface) and
  ``R = D - 2 (D.N) N`` its mirror image, ``P (R.L)^n E`` where ``R.L > 0``, and 0 when
  ``n >= 60`` and ``R.L <= 0.0008`` (``ComputePhongColour``); no cosine, no pigment;
* ``specular S roughness r``: ``H = (V + L)/2`` with ``V = -D``, ``S (N.H/|H|)^(1/r) E`` where
  ``N.H > 0`` (``ComputeSpecularColour``); no cosine, no pigment;
* ``ambient a``: ``a pigment ambient_light`` (ambient_light = 1), ``emission e``: ``e pigment``,
  once per pixel, independent of lights;
* ``metallic`` is not modelled (``NotImplementedError``).

New finishes add a :data:`Term` to :data:`FINISH_TERMS` (or pass ``extra_terms`` to
:func:`expected_image`); a tabulated or analytic BRDF ``f(wo, wi)`` becomes a term with
:func:`harness.reference.terms.brdf_term`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import singledispatch
from typing import Any, Mapping, Optional, Sequence

import numpy as np

from harness.core.scenes import (FlatSampleScene, ShadowEdgeSlabScene, SphereScene, WorldLight, rgb,
                                 resolved_finish)
from harness.reference import models
from harness.reference.terms import ShadingInputs, Term, dot

#: POV's EPSILON: lights with N.L below this are skipped entirely.
POV_EPSILON = 1.0e-10
#: Finish keywords that are parameters of another term, not terms themselves.
PARAMETER_KEYWORDS = frozenset({"phong_size", "roughness", "brilliance", "metallic"})
#: Keywords that add light-independent colour (handled by :func:`pov_pixels` itself).
EMISSIVE_KEYWORDS = frozenset({"ambient", "emission"})
#: POV's global ``ambient_light`` default.
AMBIENT_LIGHT = 1.0


@dataclass(frozen=True)
class SurfaceSamples:
    """What each pixel's primary ray hits.

    ``mask`` (H, W) is True where the ray hits the surface of interest; ``position`` and
    ``normal`` (H, W, 3) are valid there (zero elsewhere); ``ray`` (H, W, 3) is the unit primary
    ray direction (camera → surface); ``lit`` holds one (H, W) bool per light, False where a
    shadow is expected (None: nothing casts shadows).
    """

    mask: np.ndarray
    position: np.ndarray
    normal: np.ndarray
    ray: np.ndarray
    lit: Optional[tuple[np.ndarray, ...]] = None


# ---------------------------------------------------------------- stock terms

def diffuse_term(finish: Mapping[str, Any], s: ShadingInputs) -> np.ndarray:
    """``diffuse d``: ``d |N.L|^brilliance pigment`` (0 for ``d <= 0``, as POV)."""
    d = float(finish.get("diffuse", 0.0))
    if d <= 0.0:
        return np.zeros(len(s.n))
    c = np.abs(dot(s.n, s.l))
    b = float(finish.get("brilliance", 1.0))
    w = c if b == 1.0 else np.power(c, b)
    return (d * w)[:, None] * s.pigment


def phong_term(finish: Mapping[str, Any], s: ShadingInputs) -> np.ndarray:
    """``phong P phong_size n``: ``P (R.L)^n`` with R the mirrored primary ray (no cos, no pigment)."""
    p = float(finish.get("phong", 0.0))
    if p <= 0.0:
        return np.zeros(len(s.n))
    _no_metallic(finish)
    size = float(finish.get("phong_size", 40.0))
    r = s.ray - 2.0 * dot(s.ray, s.n)[:, None] * s.n
    c = dot(r, s.l)
    keep = c > 0.0
    if size >= 60.0:
        keep &= c > 0.0008
    return np.where(keep, p * np.power(np.maximum(c, 0.0), size), 0.0)


def specular_term(finish: Mapping[str, Any], s: ShadingInputs) -> np.ndarray:
    """``specular S roughness r``: ``S (N.H/|H|)^(1/r)``, ``H = (V + L)/2`` (no cos, no pigment)."""
    spec = float(finish.get("specular", 0.0))
    if spec <= 0.0:
        return np.zeros(len(s.n))
    _no_metallic(finish)
    rough = float(finish.get("roughness", 0.05))
    expo = 1.0 / rough if rough != 0.0 else 0.0  # parstxtr.cpp stores 1/roughness unless 0
    h = 0.5 * (s.v + s.l)
    hl = np.linalg.norm(h, axis=-1)
    c = np.where(hl > 0.0, dot(h, s.n) / np.where(hl > 0.0, hl, 1.0), 0.0)
    return np.where(c > 0.0, spec * np.power(np.maximum(c, 0.0), expo), 0.0)


def _no_metallic(finish: Mapping[str, Any]) -> None:
    if float(finish.get("metallic", 0.0)) > 0.0:
        raise NotImplementedError("metallic highlights are not modelled by harness.reference.expect")


def brdf_model_term(finish: Mapping[str, Any], s: ShadingInputs) -> np.ndarray:
    """``brdf_model { "spec" … }``: the model re-derived in numpy (:mod:`harness.reference.models`)."""
    return models.expect_term(finish, s)


#: Finish keyword → term. Keywords in PARAMETER_KEYWORDS/EMISSIVE_KEYWORDS are not terms.
FINISH_TERMS: dict[str, Term] = {
    "diffuse": diffuse_term,
    "phong": phong_term,
    "specular": specular_term,
    "brdf_model": brdf_model_term,
}


# ---------------------------------------------------------------- geometry per scene

@singledispatch
def surface_samples(scene: Any) -> SurfaceSamples:
    """Where each pixel-centre ray of ``scene`` hits the surface."""
    raise TypeError(f"no analytic geometry for {type(scene).__name__}")


@surface_samples.register
def _(scene: SphereScene) -> SurfaceSamples:
    cam = scene.camera()
    o = cam.ray_origins(scene.width, scene.height)
    d = cam.ray_direction()
    r = scene.radius
    # Rays are parallel to z: the hit is where the sphere's near half lies over (x, y).
    r2 = o[..., 0] ** 2 + o[..., 1] ** 2
    mask = r2 < r * r
    z = -np.sqrt(np.maximum(r * r - r2, 0.0))
    p = np.stack([o[..., 0], o[..., 1], z], axis=-1) * mask[..., None]
    ray = np.broadcast_to(d, o.shape).copy()
    return SurfaceSamples(mask, p, p / r, ray)


def _plane_hits(o: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Points where rays ``o + t d`` meet the plane z = 0."""
    t = -o[..., 2] / d[2]
    return o + t[..., None] * d


@surface_samples.register
def _(scene: FlatSampleScene) -> SurfaceSamples:
    cam = scene.camera()
    o = cam.ray_origins(scene.width, scene.height)
    d = cam.ray_direction()
    p = _plane_hits(o, d)
    h = scene.half_size()
    mask = (np.abs(p[..., 0]) < h) & (np.abs(p[..., 1]) < h)
    n = np.zeros_like(p)
    n[..., 2] = 1.0
    return SurfaceSamples(mask, p, n, np.broadcast_to(d, o.shape).copy())


@surface_samples.register
def _(scene: ShadowEdgeSlabScene) -> SurfaceSamples:
    cam = scene.camera()
    o = cam.ray_origins(scene.width, scene.height)
    d = cam.ray_direction()
    p = _plane_hits(o, d)
    n = np.zeros_like(p)
    n[..., 2] = 1.0
    mask = np.ones(p.shape[:2], dtype=bool)
    lit = p[..., 0] > 0.0  # the blade's shadow covers x < 0 exactly (see the scene's doc)
    return SurfaceSamples(mask, p, n, np.broadcast_to(d, o.shape).copy(), lit=(lit,))


# ---------------------------------------------------------------- pixels

def pov_pixels(samples: SurfaceSamples, lights: Sequence[WorldLight], finish: Mapping[str, Any],
               pigment: Any = 1.0, extra_terms: Optional[Mapping[str, Term]] = None) -> np.ndarray:
    """Expected POV pixels (H, W, 3), float64, for ``finish`` under directional ``lights``.

    Pixels outside ``samples.mask`` are 0 (black background). Raises ``NotImplementedError``
    for a finish keyword with no term.
    """
    fin = resolved_finish(finish)
    terms = {**FINISH_TERMS, **(extra_terms or {})}
    active_terms = []
    for k in fin:
        if k in PARAMETER_KEYWORDS or k in EMISSIVE_KEYWORDS:
            continue
        if k not in terms:
            raise NotImplementedError(f"no analytic term for finish keyword {k!r}")
        active_terms.append(terms[k])
    pig = np.asarray(rgb(pigment))
    mask = samples.mask
    out = np.zeros(mask.shape + (3,))
    n_all, ray_all = samples.normal[mask], samples.ray[mask]
    for i, lt in enumerate(lights):
        ldir = np.asarray(lt.direction, dtype=np.float64)
        on = dot(n_all, ldir) >= POV_EPSILON
        if samples.lit is not None:
            on &= samples.lit[i][mask]
        if not on.any():
            continue
        s = ShadingInputs(n_all[on], ray_all[on], np.broadcast_to(ldir, (int(on.sum()), 3)), pig)
        acc = np.zeros((len(s.n), 3))
        for term in active_terms:
            w = np.asarray(term(fin, s), dtype=np.float64)
            acc += w[:, None] if w.ndim == 1 else w
        vals = out[mask]
        vals[on] += acc * np.asarray(lt.colour)
        out[mask] = vals
    emit = np.asarray(rgb(fin["ambient"])) * AMBIENT_LIGHT + np.asarray(rgb(fin["emission"]))
    out[mask] += emit * pig
    return out


def expected_image(scene: Any, extra_terms: Optional[Mapping[str, Term]] = None) -> np.ndarray:
    """Expected POV pixels (H, W, 3) for a :mod:`harness.core.scenes` scene."""
    return pov_pixels(surface_samples(scene), scene.world_lights(), scene.finish, scene.pigment,
                      extra_terms)


def measured_brdf(image: np.ndarray, scene: FlatSampleScene) -> np.ndarray:
    """Invert POV units for a gonioreflectometer render: ``f = mean pixel / (pi cos_i E)`` (RGB, 1/sr).

    Uses every pixel (all see the same pair of directions); NaN where ``cos_i E`` is 0.
    """
    e = np.asarray(rgb(scene.light_colour))
    denom = math.pi * math.cos(math.radians(scene.theta_i_deg)) * e
    mean = np.asarray(image, dtype=np.float64).reshape(-1, 3).mean(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(denom > 0.0, mean / np.where(denom > 0.0, denom, 1.0), np.nan)
