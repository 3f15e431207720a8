"""Subsurface test shapes shared by the tests and ``make bench``: the study's blob (the shape of
``studies/example.toml``), a CSG difference with concave edges and inner faces, and a smooth
mesh2 with creases, each with a sphere of about its size in the same camera and light (what a
shape's render time is compared with).

Each scene is a ``str.format`` template: ``{preset}`` names the medium (a preset of the dipole
finish), ``{extra}`` adds to its block (``method random_walk samples 4``), ``{mesh}`` is the
mesh's text (:func:`bumpy_mesh`; the other scenes ignore it). Lengths in scene units,
``mm_per_unit 10``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["BLOB", "DIFFERENCE", "MESH", "SHAPES", "SMOOTH_MESH_SPHERE", "SPHERES", "bumpy_mesh", "scene",
           "smooth_sphere_mesh"]

_HEAD = """#version 3.7;
global_settings {{ assumed_gamma 1.0 mm_per_unit 10 }}
camera {{ location CAMERA look_at LOOK_AT angle 32 }}
light_source {{ <-4, 6, -5> rgb 1 }}
"""
_TEXTURE = 'texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ "{preset}" {extra} }} }} }}'
_BLOB_HEAD = _HEAD.replace("CAMERA", "<0, 2.3, -5.2>").replace("LOOK_AT", "<0, 1, 0>")
_CENTRE_HEAD = _HEAD.replace("CAMERA", "<0, 1.3, -4.2>").replace("LOOK_AT", "<0, 0, 0>")

#: the study's blob: three spheres and a cylinder, threshold 0.55
BLOB = _BLOB_HEAD + """blob {{ threshold 0.55 sphere {{ <-0.45, 0.9, 0>, 0.85, 1 }} sphere {{ <0.5, 1.15, 0.1>, 0.75, 1 }}
  sphere {{ <0.05, 0.6, -0.35>, 0.7, 1 }} cylinder {{ <-0.6, 1.5, 0>, <0.6, 1.6, 0>, 0.35, 1 }}
  """ + _TEXTURE + """ }}
"""
#: a sphere with a box and a cylinder cut out: concave edges and inner faces
DIFFERENCE = _CENTRE_HEAD + """difference {{ sphere {{ 0, 0.9 }} box {{ <-0.3, 0.2, -1.2>, <1, 1, 0.3> }}
  cylinder {{ <-1, -0.3, -0.2>, <1, -0.3, -0.2>, 0.25 }}
  """ + _TEXTURE + """ }}
"""
#: the mesh of bumpy_mesh(), given as {mesh}
MESH = _CENTRE_HEAD + "{mesh} " + _TEXTURE + """ }}
"""
SHAPES = {"blob": BLOB, "difference": DIFFERENCE, "mesh": MESH}
#: per shape, a sphere of about its size where it stands, in the same camera and light
SPHERES = {
    "blob": _BLOB_HEAD + "sphere {{ <0, 1, 0>, 0.9 " + _TEXTURE + " }}\n",
    "difference": _CENTRE_HEAD + "sphere {{ 0, 0.9 " + _TEXTURE + " }}\n",
}
SPHERES["mesh"] = SPHERES["difference"]
#: the sphere smooth_sphere_mesh() stands for (radius 0.8), in the mesh's camera and light
SMOOTH_MESH_SPHERE = _CENTRE_HEAD + "sphere {{ 0, 0.8 " + _TEXTURE + " }}\n"


def bumpy_mesh(nu: int = 48, nv: int = 24) -> str:
    """A smooth mesh2 with vertex normals: a sphere of radius 0.8 with three lobes and two
    creases (r = 0.8 (1 + 0.15 sin 3 phi sin 2 theta)), as a POV object (its closing brace is
    the scene's, after the texture)."""
    th = np.pi * np.arange(nv + 1) / nv
    ph = 2 * np.pi * np.arange(nu) / nu
    T, P = np.meshgrid(th, ph, indexing="ij")
    r = 0.8 * (1 + 0.15 * np.sin(3 * P) * np.sin(2 * T))
    v = np.stack([r * np.sin(T) * np.cos(P), r * np.cos(T), r * np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    faces = []
    for i in range(nv):
        for j in range(nu):
            a, b, c, d = i * nu + j, i * nu + (j + 1) % nu, (i + 1) * nu + j, (i + 1) * nu + (j + 1) % nu
            if i > 0:
                faces.append((a, b, c))
            if i < nv - 1:
                faces.append((b, d, c))
    f = np.array(faces)
    n = np.zeros_like(v)
    for k in range(3):
        np.add.at(n, f[:, k], np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]))
    n /= np.linalg.norm(n, axis=1)[:, None]
    if (n * v).sum() < 0:
        n = -n
    vec = lambda a: ", ".join("<%.6f, %.6f, %.6f>" % tuple(x) for x in a)
    return (f"mesh2 {{ vertex_vectors {{ {len(v)}, {vec(v)} }} normal_vectors {{ {len(n)}, {vec(n)} }} "
            f"face_indices {{ {len(f)}, " + ", ".join("<%d, %d, %d>" % tuple(t) for t in f) + " } inside_vector y ")


def smooth_sphere_mesh(radius: float = 0.8, nu: int = 48, nv: int = 24) -> str:
    """A mesh2 sphere of `radius` with its exact normals at the vertices (one vertex at each
    pole): what a modelling program exports for a smooth ball, as a POV object (its closing
    brace is the caller's, after the texture)."""
    th = np.pi * np.arange(1, nv) / nv
    ph = 2 * np.pi * np.arange(nu) / nu
    T, P = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(T) * np.cos(P), np.cos(T), np.sin(T) * np.sin(P)], -1).reshape(-1, 3)
    n = np.vstack([[0.0, 1.0, 0.0], ring, [0.0, -1.0, 0.0]])
    top, bottom = 0, len(n) - 1
    at = lambda i, j: 1 + i * nu + j % nu  # ring i (from the top), meridian j
    faces = [(top, at(0, j + 1), at(0, j)) for j in range(nu)]
    for i in range(nv - 2):
        for j in range(nu):
            faces += [(at(i, j), at(i, j + 1), at(i + 1, j)), (at(i, j + 1), at(i + 1, j + 1), at(i + 1, j))]
    faces += [(at(nv - 2, j), at(nv - 2, j + 1), bottom) for j in range(nu)]
    vec = lambda a: ", ".join("<%.6f, %.6f, %.6f>" % tuple(x) for x in a)
    return (f"mesh2 {{ vertex_vectors {{ {len(n)}, {vec(radius * n)} }} normal_vectors {{ {len(n)}, {vec(n)} }} "
            f"face_indices {{ {len(faces)}, " + ", ".join("<%d, %d, %d>" % t for t in faces) + " } inside_vector y ")


def scene(shape: str, preset: str, extra: str = "", sphere: bool = False) -> str:
    """The scene text of ``shape`` (a key of SHAPES) in ``preset``, or of its sphere."""
    template = (SPHERES if sphere else SHAPES)[shape]
    return template.format(preset=preset, extra=extra, mesh=bumpy_mesh() if shape == "mesh" and not sphere else "")
