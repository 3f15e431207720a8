"""The exact profile's curvature correction (`curvature on`, the default; shading/DIPOLE.md 6d),
rendered, against exact transport that shares no code with the library.

A Skin1 sphere three diffusion lengths in radius (11.0 mm), ior 1.3, lit from
normalize(1, 0.5, 1), seen along +z, the profile at default settings but `directional off` (the
correction was calibrated on the radially symmetric profile; with the entry shifts, the default
since 2026-12-07, the same sphere is tests/test_directional.py's): the image's flux (pi I)
against `volume_ref.sphere_intensity` (analog escape through the refracting sphere), with the
correction and without it. Stated before measuring: with it, each channel's error at
most CURVATURE_SHRINK of the error without it, plus 4 of the reference's standard errors
(measured: -14.4 / -9.3 / -6.0 % without, -5.8 / -4.6 / -3.5 % with, reference +-0.5-0.9 %).
The control: without it the red channel is off by at least CURVATURE_OFF (the deficit the
correction is for; what is left with it is light entering at a slant near the terminator).
"""

from __future__ import annotations

import math

import numpy as np

from harness.core import runner
from harness.reference import volume_ref
from harness.reports.walk_bench import SPHERE, vec  # an orthographic view of a sphere at the origin

#: the error with the correction, as a part of the error without it, per channel
CURVATURE_SHRINK = 0.65
#: the control: the red channel's error without the correction, relative (at least)
CURVATURE_OFF = 0.1


def test_curvature_halves_the_profiles_deficit_on_a_refracting_sphere(fork):
    sp, sa = np.array([0.74, 0.88, 1.01]), np.array([0.032, 0.17, 0.48])
    r = 3.0 / math.sqrt(3 * 0.032 * 0.772)  # three of the red channel's diffusion lengths, mm
    light, view = np.array([1.0, 0.5, 1.0]) / 1.5, np.array([0.0, 0.0, 1.0])
    span, n = 2.2 * r, 64
    ref = volume_ref.sphere_intensity(sp, sa, 0.0, 1.3, r, light, view, n_paths=1_000_000, seed=17)
    err = {}
    for name, extra in (("off", " directional off curvature off"), ("on", " directional off")):
        scene = SPHERE.format(far=10 * r, right=vec([span, 0, 0]), up=vec([0, span, 0]), light=vec(light), r=r,
                              dipole='"Skin1" ior 1.3 mm_per_unit 1' + extra)
        img = runner.render(scene, fork, width=n, height=n, float_exr=True, threads=2).image[..., :3].astype(float)
        assert np.isfinite(img).all()
        err[name] = img.reshape(-1, 3).sum(0) * (span / n) ** 2 / ref.flux - 1
    se = ref.flux_err / ref.flux
    print(f"flux error: curvature off {np.round(100 * err['off'], 2)} %, on {np.round(100 * err['on'], 2)} % "
          f"(reference +- {np.round(100 * se, 2)} %)")
    assert -err["off"][0] >= CURVATURE_OFF
    for c in range(3):
        assert abs(err["on"][c]) <= CURVATURE_SHRINK * abs(err["off"][c]) + 4 * se[c], c
