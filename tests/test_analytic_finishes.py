"""Analytic ``brdf_model`` finishes rendered by the fork vs the models re-derived in numpy.

The reference (:mod:`harness.reference.models`) shares no code with the C++ library; it follows the
published formulas (complex Fresnel amplitudes, a 2-D projected-area quadrature for the Smith
Lambda of Blinn and Gaussian, ...). Sphere renders cover every normal direction against lights
from the view direction to 89.9 deg (grazing), in float EXR.

Glossy reflection (``samples``) is checked in a white furnace: a sphere inside a uniform sky
reflects, per pixel, the glossy part of its directional albedo.
"""

from __future__ import annotations

import functools
import re

import numpy as np
import pytest

from harness.reference import models
from harness.core import runner
from harness.core.compare import max_rel_error, rel_rmse
from harness.reference.expect import expected_image, surface_samples
from harness.core.scenes import DistantLight, SphereScene

#: One render per model with four lights: headlight, 45 deg, 80 deg and 89.9 deg (grazing).
LIGHTS = (DistantLight(0.0, 0.0, (0.4, 0.4, 0.4)), DistantLight(45.0, 30.0, (0.3, 0.3, 0.3)),
          DistantLight(80.0, 150.0, (0.5, 0.5, 0.5)), DistantLight(89.9, 260.0, (0.6, 0.6, 0.6)))
#: Goal of the issue: rel-RMSE <= 1e-4 with float output. Measured 2e-8 .. 1.3e-7 (float32
#: rounding, and the numpy Smith tables of Blinn/Gaussian near grazing).
CLOSED_FORM_TOL = 1.0e-4
#: Per pixel (every channel of every sphere pixel): |render - closed form| relative to the
#: pixel, for pixels above 1e-3 of the image's peak (compare.max_rel_error). A 10 % error
#: confined to the grazing rim keeps rel-RMSE near 2e-5 but fails this. Measured 1.4e-7 ..
#: 2.0e-7, and 7.8e-6 for Blinn/Gaussian with Smith G (the numpy Smith tables at grazing).
CLOSED_FORM_PIXEL = 1.0e-4

CONDUCTOR = "f=conductor n=0.2,0.4,1.4 k=3.4,2.4,1.8"
MODEL_SPECS = [
    "lambert rho=0.2,0.5,0.8",
    "phong_pov phong=0.7 phong_size=30 diffuse=0.3",
    "blinn_pov specular=0.6 roughness=0.05 diffuse=0.2",
    "phong_normalized kd=0.3 ks=0.5 n=50",
    # every D x G in the normalised form (conductor Fresnel)
    *[f"microfacet d={d} m=0.25 g={g} {CONDUCTOR}"
      for d in ("blinn", "gaussian", "tr", "beckmann") for g in ("vcavity", "smith")],
    # every D in the survey form with its native parameter, V-cavity, on a diffuse base
    "microfacet form=survey d=blinn n1=30 g=vcavity rho_s=0.5 kd=0.4",
    "microfacet form=survey d=gaussian n2=4 g=vcavity rho_s=0.3 f=dielectric eta=1.5 kd=0.5",
    "microfacet form=survey d=tr n3=0.3 g=vcavity rho_s=0.3",
    "microfacet form=survey d=beckmann m=0.2 g=vcavity rho_s=0.2 f=schlick f0=0.05",
    # the other Fresnel terms, and hard cases: near-mirror, eta -> 1, very rough
    "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.7",
    "microfacet d=tr m=0.2 f=schlick f0=0.9,0.6,0.3",
    "microfacet d=beckmann m=0.02 f=dielectric eta=1.0001 kd=0.5 rho_s=0.5",
    "microfacet d=tr m=1 g=vcavity",
    "ward variant=original rho_d=0.3 rho_s=0.2 ax=0.1 ay=0.3",
    "ward rho_d=0.3 rho_s=0.2 ax=0.3 ay=0.1",
    "ward rho_d=0.1 rho_s=0.4 alpha=0.15",
    "oren_nayar rho=0.6 sigma=0.5",
    "lafortune kd=0.2 lobe=-1,-1,1,20,0.5 lobe=0.9,0.9,0.8,5,0.2",
]


def sphere(finish, lights=LIGHTS, size=56, sky=None):
    return SphereScene(lights=lights, finish=finish, width=size, height=size)


@pytest.mark.parametrize("spec", MODEL_SPECS)
def test_model_matches_closed_form(fork, spec):
    scene = sphere({"brdf_model": {"spec": spec, "direction": (0.3, 1.0, 0.2)}})
    img = runner.render(scene, fork, float_exr=True).image
    want = expected_image(scene)
    mask = surface_samples(scene).mask
    assert np.isfinite(img).all() and (img >= 0).all()
    assert want[mask].max() > 0.05  # the scene shows the model
    err, worst = rel_rmse(img, want, mask), max_rel_error(img, want, mask)
    print(f"{spec}: rel-RMSE {err:.2e}, worst pixel {worst:.2e}")
    assert err < CLOSED_FORM_TOL
    assert worst < CLOSED_FORM_PIXEL


def test_per_pixel_bound_catches_a_rim_error(fork):
    # Negative control: 10 % too bright only where the surface is seen at > 80 deg. The
    # image-wide rel-RMSE hardly moves; the per-pixel bound must fail.
    spec = f"microfacet d=beckmann m=0.25 g=smith {CONDUCTOR}"
    scene = sphere({"brdf_model": {"spec": spec}})
    img = runner.render(scene, fork, float_exr=True).image
    s = surface_samples(scene)
    rim = s.mask & (-s.normal[..., 2] < np.cos(np.radians(80.0)))
    bad = img.copy()
    bad[rim] *= 1.1
    want = expected_image(scene)
    assert rim.sum() > 20
    assert rel_rmse(bad, want, s.mask) < CLOSED_FORM_TOL  # the image-wide measure misses it
    assert max_rel_error(bad, want, s.mask) > 50 * CLOSED_FORM_PIXEL


def test_closed_form_check_has_power(fork):
    # The comparison detects a 1 % change of roughness in one model of the grid.
    spec = f"microfacet d=tr m=0.25 g=smith {CONDUCTOR}"
    scene = sphere({"brdf_model": {"spec": spec}})
    img = runner.render(scene, fork, float_exr=True).image
    other = sphere({"brdf_model": {"spec": spec.replace("m=0.25", "m=0.2525")}})
    assert rel_rmse(img, expected_image(other), surface_samples(scene).mask) > 50 * CLOSED_FORM_TOL


def test_anisotropic_direction_turns_the_lobe(fork):
    # The tangent is the hint projected onto the surface: its length and sign do not matter
    # (Ward is symmetric under t -> -t), its direction does. (The closed-form test above checks
    # the frame itself against harness.reference.models.tangent_frame.)
    spec = "ward rho_s=0.4 ax=0.05 ay=0.3"

    def img(direction):
        return runner.render(sphere({"brdf_model": {"spec": spec, "direction": direction}}), fork,
                             float_exr=True).image
    mask = surface_samples(sphere({})).mask
    a = img((1.0, 0.0, 0.0))
    assert rel_rmse(a, img((-2.0, 0.0, 0.0)), mask) < 1e-6
    assert rel_rmse(a, img((0.0, 1.0, 0.0)), mask) > 0.1


# ---------------------------------------------------------------- glossy reflection

FURNACE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 max_trace_level 5 ambient_light 0 }}
camera {{ orthographic location <0, 0, -10> direction z right x*2 up y*2 }}
sky_sphere {{ pigment {{ rgb {sky} }} }}
sphere {{ 0, 1 texture {{ pigment {{ rgb 0.5 }} finish {{ ambient 0 diffuse 0
  brdf_model {{ "{spec}" samples {samples} }} {extra} }} }} }}
"""


def furnace(fork, spec, samples, size=48, sky=1.0, extra="", threads=1):
    text = FURNACE.format(spec=spec, samples=samples, sky=sky, extra=extra)
    return runner.render(text, fork, width=size, height=size, float_exr=True, threads=threads)


def glossy_albedo(spec, thetas):
    """The glossy part of the directional albedo by numpy quadrature of the reference model
    (harness.reference.models, no library code; ``brdftool albedo`` would share f with the
    renderer)."""
    return models.parse(spec).glossy_albedo(thetas)


@functools.lru_cache(maxsize=None)
def _glossy_albedo_cached(spec):
    return glossy_albedo(spec, np.linspace(0.0, 90.0, 91))


def furnace_expectation(spec, size):
    scene = SphereScene(width=size, height=size)
    s = surface_samples(scene)
    theta = np.degrees(np.arccos(np.clip(-s.normal[s.mask][:, 2], 0.0, 1.0)))
    grid = np.linspace(0.0, 90.0, 91)
    a = _glossy_albedo_cached(spec)
    want = np.zeros(s.mask.shape + (3,))
    want[s.mask] = np.stack([np.interp(theta, grid, a[:, c]) for c in range(3)], -1)
    return want, s.mask, theta


#: Glossy reflection in a white furnace, 64 rays per pixel, against the numpy quadrature of
#: the reference model: the mean relative error over the ~1500 pixels with theta_o < 80 deg
#: (the bias; a weight 1 % off is 1e-2; measured +5e-5 Beckmann, -5.8e-4 GGX, +4.7e-5 Ward,
#: -9.8e-4 POV's phong lobe), the per-pixel rms there (the noise of 64 stratified rays:
#: measured 0.55 % Ward, 0.76 % Beckmann, 1.2 % GGX, 3.3 % POV's phong lobe under the default
#: sampler) and the rms over every pixel (the grazing rim mixes a steep albedo slope into
#: each pixel).
GLOSSY_BIAS_TOL = 3.0e-3
GLOSSY_NOISE_TOL = 0.045
GLOSSY_NOISE_RIM_TOL = 0.08


@pytest.mark.parametrize("spec", [
    "microfacet d=beckmann m=0.2 " + CONDUCTOR,
    "microfacet d=tr m=0.1 kd=0.5 rho_s=0.5 f=dielectric eta=1.5",
    "ward rho_d=0.2 rho_s=0.3 alpha=0.15",
    "phong_pov phong=0.5 phong_size=40 diffuse=0.4",
])
def test_glossy_reflection_white_furnace(fork, spec):
    size = 48
    img = furnace(fork, spec, 64, size).image
    want, mask, theta = furnace_expectation(spec, size)
    assert np.isfinite(img).all() and (img >= 0).all()
    rel = (img[mask] - want[mask]) / want[mask]
    inner = theta < 80.0  # the grazing rim: few pixels, each mixing a 2-degree albedo node span
    print(f"{spec}: mean rel {rel[inner].mean():+.2e}, rms rel {np.sqrt((rel[inner] ** 2).mean()):.2e}")
    assert abs(rel[inner].mean()) < GLOSSY_BIAS_TOL
    assert np.sqrt((rel[inner] ** 2).mean()) < GLOSSY_NOISE_TOL
    assert np.sqrt((rel ** 2).mean()) < GLOSSY_NOISE_RIM_TOL


def test_glossy_reflection_converges(fork):
    spec = "microfacet d=beckmann m=0.2 " + CONDUCTOR
    want, mask, _ = furnace_expectation(spec, 40)
    errs = [rel_rmse(furnace(fork, spec, n, 40).image, want, mask) for n in (4, 64)]
    print(f"rel-RMSE 4 rays {errs[0]:.2e}, 64 rays {errs[1]:.2e}")
    assert errs[1] < errs[0] / 3.0  # 16x the rays: at least 3x smaller error (1/sqrt(N) gives 4)


def test_glossy_reflection_is_repeatable_and_thread_independent(fork):
    spec = "microfacet d=beckmann m=0.3 kd=0.3 rho_s=0.6"
    a = furnace(fork, spec, 16, 40, threads=1).image
    b = furnace(fork, spec, 16, 40, threads=1).image
    c = furnace(fork, spec, 16, 40, threads=2).image
    assert np.array_equal(a, b)
    assert np.array_equal(a, c)


def test_samples_zero_is_off_and_reflects_nothing(fork):
    r = furnace(fork, "microfacet d=beckmann m=0.2", 0, 24)
    _, mask, _ = furnace_expectation("lambert", 24)
    assert r.image[mask].max() == 0.0  # no lights, no reflection rays: black in a white sky
    assert r.image[~mask].min() == 1.0
    assert r.stats.get("reflected_rays", 0) == 0


def test_samples_with_pov_reflection_warns(fork):
    r = furnace(fork, "microfacet d=beckmann m=0.2", 4, 16, extra="reflection 0.5")
    assert any("reflects the scene twice" in w for w in r.warnings)


@pytest.mark.parametrize("value, message", [
    ("-1", "samples must be a whole number from 0 (off) to 4096, found -1"),
    ("2.5", "found 2.5"),
    ("5000", "found 5000"),
])
def test_bad_samples_are_scene_errors(fork, value, message):
    with pytest.raises(runner.RenderError) as e:
        furnace(fork, "lambert", value, 8)
    assert message in str(e.value)
    assert e.value.line == 6  # the line of `samples`
