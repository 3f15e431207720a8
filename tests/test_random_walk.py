"""`method random_walk` of the dipole finish, checked on the rendered pixel (+FE32) against exact
transport computed without the library:

* a thick index-matched isotropic slab under straight light: Chandrasekhar's exact half-space
  radiance, omega H(1)^2 / 8 per channel (three channels of different albedo in one render);
* a 1 mm sheet with eta 1.3 and forward scattering (g 0.9), light at 45 degrees and view at
  30 degrees: the harness Monte Carlo's exact radiance estimator (mc_subsurface, a numpy photon
  tracer that shares no code with the library) for the same slab;
* a blob (the study's shape) with marble: no patches or steps. The residual of the image against
  its own smoothed version is white noise for the walk (independent walks per pixel) and
  spatially correlated where a method leaves patches; the profile method's render of the same
  blob fails the same check.

Tolerances are stated before measuring: 4 combined standard errors plus 0.5 % (the walk and the
references are exact; only noise separates them).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.core import runner
from harness.reference import dipole_ref, mc_subsurface

SLAB = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location {loc} direction {dir} right {right} up {up} }}
light_source {{ {light} * 1000 rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-60, -60, {bottom}>, <60, 60, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ {dipole} }} }} }} }}
"""


def vec(v) -> str:
    return "<" + ", ".join(f"{x:.12g}" for x in v) + ">"


def slab_scene(bottom: float, light, view, dipole: str, size: float = 2.0) -> str:
    """An orthographic camera looking along -view at the slab's top face, size mm across."""
    view = np.asarray(view, float) / np.linalg.norm(view)
    right = np.cross([0.0, 1.0, 0.0], view)
    if np.linalg.norm(right) < 1e-9:
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(view, right)
    light = np.asarray(light, float) / np.linalg.norm(light)
    return SLAB.format(loc=vec(50 * view), dir=vec(-view), right=vec(size * right), up=vec(size * up),
                       light=vec(light), bottom=bottom, dipole=dipole)


def pixels(r) -> np.ndarray:
    img = r.image[..., :3].astype(np.float64).reshape(-1, 3)
    assert np.isfinite(img).all() and (img >= 0).all(), "NaN or negative pixels"
    return img


def test_thick_slab_is_chandrasekhars_half_space(fork):
    sp, sa = np.array([0.74, 0.88, 1.01]), np.array([0.032, 0.17, 0.48])  # Skin1, g = 0
    scene = slab_scene(-60, [0, 0, 1], [0, 0, 1], "\"Skin1\" ior 1.0 mm_per_unit 1 method random_walk samples 256")
    px = pixels(runner.render(scene, fork, width=16, height=16, float_exr=True, threads=2))
    mean, se = px.mean(0), px.std(0) / math.sqrt(len(px))
    for c in range(3):
        w = sp[c] / (sp[c] + sa[c])
        exact = w * dipole_ref.chandrasekhar_h(np.array([1.0]), w)[0] ** 2 / 8
        print(f"channel {c}: albedo {w:.4f} pixel {mean[c]:.5f} +- {se[c]:.5f}, exact {exact:.5f} "
              f"({100 * (mean[c] / exact - 1):+.2f} %)")
        assert abs(mean[c] - exact) < 4 * se[c] + 0.005 * exact


def test_forward_scattering_sheet_under_slanted_light(fork):
    sigma_s, sigma_a, g, eta, d = 2.0, 0.5, 0.9, 1.3, 1.0  # 1/mm, mm: 2.5 mean free paths
    theta_l, theta_v = math.radians(45), math.radians(30)
    to_light = [-math.sin(theta_l), 0.0, math.cos(theta_l)]  # the beam travels toward +x
    view = [math.sin(theta_v), 0.0, math.cos(theta_v)]      # seen from the side it travels to
    medium = f"sigma_s {sigma_s} sigma_a {sigma_a} anisotropy {g} ior {eta} mm_per_unit 1"
    scene = slab_scene(-d, to_light, view, medium + " method random_walk samples 2048")
    px = pixels(runner.render(scene, fork, width=12, height=12, float_exr=True, threads=2))[:, 0]
    got, got_se = px.mean(), px.std() / math.sqrt(len(px))
    sigma_t = sigma_s + sigma_a
    mc = mc_subsurface.simulate(sigma_s / sigma_t, sigma_a / sigma_t, g, eta, n_photons=200000, seed=3,
                                thickness=d * sigma_t, cos_incidence=math.cos(theta_l),
                                views=np.array([view]))
    # pi L / E_entering, times what enters per unit light colour: cos_i Ft(cos_i)
    enter = math.cos(theta_l) * (1.0 - float(dipole_ref.fresnel_dielectric(math.cos(theta_l), eta)))
    want = enter * float(mc.radiance_single[0] + mc.radiance_multiple[0])
    want_se = enter * math.hypot(float(mc.radiance_single_err[0]), float(mc.radiance_multiple_err[0]))
    print(f"sheet g {g} eta {eta}: pixel {got:.5f} +- {got_se:.5f}, Monte Carlo {want:.5f} +- {want_se:.5f} "
          f"({100 * (got / want - 1):+.2f} %)")
    assert abs(got - want) < 4 * math.hypot(got_se, want_se) + 0.005 * want


BLOB = """#version 3.7;
global_settings {{ assumed_gamma 1.0 mm_per_unit 10 }}
camera {{ location <0, 2.3, -5.2> look_at <0, 1, 0> angle 32 }}
light_source {{ <-4, 6, -5> rgb 1 }}
blob {{ threshold 0.55 sphere {{ <-0.45, 0.9, 0>, 0.85, 1 }} sphere {{ <0.5, 1.15, 0.1>, 0.75, 1 }}
  sphere {{ <0.05, 0.6, -0.35>, 0.7, 1 }} cylinder {{ <-0.6, 1.5, 0>, <0.6, 1.6, 0>, 0.35, 1 }}
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ "Marble" {method} }} }} }} }}
"""


def patchiness(img: np.ndarray) -> float:
    """Correlation of the residual (image minus its 5x5 box mean) between horizontal neighbours,
    inside the object (pixels whose whole 7x7 neighbourhood is lit): ~0 for independent noise
    about a smooth image, large where the image has patches or steps."""
    y = img[..., :3].astype(np.float64).mean(-1)
    lit = y > 0
    k = 2
    pad = np.pad(y, k, mode="edge")
    smooth = sum(pad[k + i: k + i + y.shape[0], k + j: k + j + y.shape[1]]
                 for i in range(-k, k + 1) for j in range(-k, k + 1)) / (2 * k + 1) ** 2
    res = y - smooth
    inside = lit.copy()
    for i in range(-3, 4):
        for j in range(-3, 4):
            inside &= np.roll(np.roll(lit, i, 0), j, 1)
    a, b = res[:, :-1][inside[:, :-1] & inside[:, 1:]], res[:, 1:][inside[:, :-1] & inside[:, 1:]]
    return float(np.corrcoef(a, b)[0, 1])


def test_blob_has_no_patches(fork):
    walk = runner.render(BLOB.format(method="method random_walk samples 4"), fork, width=96, height=80,
                         float_exr=True, threads=2)
    profile = runner.render(BLOB.format(method="method profile"), fork, width=96, height=80, float_exr=True,
                            threads=2)
    pixels(walk)
    cw, cp = patchiness(walk.image), patchiness(profile.image)
    print(f"blob residual neighbour correlation: random walk {cw:+.3f}, profile {cp:+.3f}")
    # the smoothing itself correlates neighbours' residuals by about -1/25; stated before
    # measuring: the walk below 0.15, and the check must see the profile's patches (above 0.3)
    assert cw < 0.15
    assert cp > 0.3
