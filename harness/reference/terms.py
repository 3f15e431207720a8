"""What every BRDF term of the reference shares: shading inputs, local frames, POV's pi.

A term turns a finish and the shading inputs of N lit pixels into a weight per pixel; the
pixel gains ``weight * light colour``. :func:`brdf_term` makes one from a BRDF ``f(wo, wi)``
(1/sr, cos(theta_i) excluded, local vectors), applying POV's factor ``pi f cos(theta_i)`` in
exactly one place (:func:`pov_brdf_weight`). :mod:`harness.reference.models` and
:mod:`harness.reference.expect` both build on this module; neither imports the other's
internals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from harness.core.scenes import rgb


@dataclass(frozen=True)
class ShadingInputs:
    """One light at the N masked, lit pixels: unit vectors (N, 3) and the finish parameters.

    ``n`` normal, ``ray`` primary ray direction, ``v = -ray`` towards the viewer, ``l`` towards
    the light; ``pigment`` is the RGB pigment colour (3,).
    """

    n: np.ndarray
    ray: np.ndarray
    l: np.ndarray
    pigment: np.ndarray

    @property
    def v(self) -> np.ndarray:
        """Unit vectors towards the viewer."""
        return -self.ray


#: A finish term: ``(resolved finish, inputs) -> weight`` of shape (N,) or (N, 3); the pixel
#: gains ``weight * light colour``.
Term = Callable[[Mapping[str, Any], ShadingInputs], np.ndarray]


def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (..., 3) arrays."""
    return np.einsum("...i,...i->...", a, b)


def normalize(a: np.ndarray) -> np.ndarray:
    """Row-wise normalisation of (..., 3) arrays."""
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def local_frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent and bitangent (N, 3) for unit normals ``n``: Duff et al. 2017 branchless ONB.

    (t, b, n) is right-handed in the usual mathematical sense; +z normals give t = +x, b = +y.
    Anisotropic models must use the same frame as the fork's adapter (see open problems).
    """
    x, y, z = n[:, 0], n[:, 1], n[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    bb = x * y * a
    t = np.stack([1.0 + sign * x * x * a, sign * bb, -sign * x], axis=-1)
    b = np.stack([bb, sign + y * y * a, -y], axis=-1)
    return t, b


def to_local(w: np.ndarray, t: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """World vectors (N, 3) into the local frame (t, b, n): z is the cosine with the normal."""
    return np.stack([dot(w, t), dot(w, b), dot(w, n)], axis=-1)


def pov_brdf_weight(f_value: np.ndarray, cos_i: np.ndarray) -> np.ndarray:
    """POV's contribution factor for a BRDF value: ``pi f cos(theta_i)`` (the one place pi enters)."""
    f_value = np.asarray(f_value, dtype=np.float64)
    c = np.maximum(np.asarray(cos_i, dtype=np.float64), 0.0)
    return math.pi * f_value * (c if f_value.ndim == 1 else c[:, None])


def brdf_term(f: Callable[[np.ndarray, np.ndarray], np.ndarray], times_pigment: bool = False,
              frame: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] = local_frame) -> Term:
    """Term for a BRDF ``f(wo, wi)`` in 1/sr, cos excluded, local vectors (N, 3) → (N,) or (N, 3).

    ``wo`` is towards the viewer, ``wi`` towards the light. The term is ``pi f cos_i`` (times
    the pigment if ``times_pigment``); both directions below the surface give 0.
    """
    def term(finish: Mapping[str, Any], s: ShadingInputs) -> np.ndarray:
        t, b = frame(s.n)
        wo, wi = to_local(s.v, t, b, s.n), to_local(s.l, t, b, s.n)
        val = np.asarray(f(wo, wi), dtype=np.float64)
        above = (wo[:, 2] > 0.0) & (wi[:, 2] > 0.0)
        val = np.where(above if val.ndim == 1 else above[:, None], val, 0.0)
        w = pov_brdf_weight(val, wi[:, 2])
        if times_pigment:
            w = (w[:, None] if w.ndim == 1 else w) * s.pigment
        return w
    return term


def lambert(rho: Any) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """Lambert BRDF ``rho/pi`` (grey or RGB) as an ``f(wo, wi)`` callable, for tests."""
    r = np.asarray(rgb(rho))

    def f(wo: np.ndarray, wi: np.ndarray) -> np.ndarray:
        return np.broadcast_to(r / math.pi, (len(wo), 3))
    return f
