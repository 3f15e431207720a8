"""BRDF finishes under POV's conventions (issue 17): shadowless lights and transforms.

* A ``shadowless`` light (POV's fill light, which gets no highlight from ``phong`` or
  ``specular``) lights a ``brdf_table``/``brdf_model`` finish with its full BRDF: a measured
  BRDF has no separate highlight to drop. Stock finishes keep stock behaviour.
* The ``direction`` of an anisotropic finish moves with its object and with its texture's
  transforms, as a pattern does: a rotated brushed sphere is the unrotated render rotated.
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.core import runner, tables

#: A gold-like conductor table (Beckmann m = 0.2, n + ik of gold at R, G, B), 2 deg.
GOLD_SPEC = "microfacet d=beckmann m=0.2 f=conductor n=0.18,0.42,1.37 k=3.42,2.35,1.77"

SHADOWLESS_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 ambient_light 0 }}
camera {{ orthographic location <0, 0, -10> direction z right x*2.2 up y*2.2 }}
light_source {{ <-3, 4, -6> * 100 rgb <1, 0.95, 0.9> parallel point_at 0 {shadowless} }}
sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ ambient 0 diffuse 0 {finish} }} }}
"""


def render_shadowless(binary, finish, shadowless, files=None, float_exr=True):
    text = SHADOWLESS_SCENE.format(finish=finish, shadowless="shadowless" if shadowless else "")
    return runner.render(text, binary, width=64, height=64, float_exr=float_exr, files=files).image


def test_shadowless_light_gives_a_table_its_full_brdf(fork):
    # The same light with shadows off by other means (nothing occludes it) is the reference;
    # before issue 17 the shadowless render was a Lambertian surface of the table's albedo.
    files = {"gold.brdf": tables.tabulated(GOLD_SPEC, step=2.0, fold=True)}
    finish = 'brdf_table { "gold.brdf" }'
    fill = render_shadowless(fork, finish, True, files)
    key = render_shadowless(fork, finish, False, files)
    assert key.max() > 0.5  # the highlight is in the picture
    diff = float(np.abs(fill - key).max() / key.max())
    print(f"shadowless vs unshadowed: max |diff| / max {diff:.2e}")
    assert diff <= 1e-4
    # The albedo-only look (what a fill light used to give) is far from it.
    assert float(np.abs(fill - key.mean(axis=(0, 1))).max()) > 0.1


def test_shadowless_light_gives_a_model_its_full_brdf(fork):
    finish = f'brdf_model {{ "{GOLD_SPEC}" }}'
    fill, key = render_shadowless(fork, finish, True), render_shadowless(fork, finish, False)
    assert key.max() > 0.5
    assert float(np.abs(fill - key).max() / key.max()) <= 1e-4


def test_shadowless_light_keeps_stock_phong(fork, stock):
    # Stock finishes keep POV's rule (a fill light gives no phong/specular): the fork renders
    # the scene as stock does, to the bit (both half-float EXR).
    finish = "diffuse 0.6 phong 0.8 specular 0.4"
    a = render_shadowless(stock, finish, True, float_exr=False)
    b = render_shadowless(fork, finish, True, float_exr=False)
    np.testing.assert_array_equal(a, b)
    assert np.abs(render_shadowless(stock, finish, False, float_exr=False) - a).max() > 0.1  # phong dropped


# ---------------------------------------------------------------- transforms

#: Orthographic camera along +z, square image: rotating the scene by 90 deg about z maps pixel
#: centres onto pixel centres. Two parallel lights, rotated with the object (or its texture)
#: in the rotated render; the sphere's finish is anisotropic, brushed along (1, 0.2, 0).
ROTATION_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 ambient_light 0 }}
camera {{ orthographic location <0, 0, -10> direction z right x*2.2 up y*2.2 }}
light_source {{ <-2, 3, -6> * 100 rgb 0.8 parallel point_at 0 {light_turn} }}
light_source {{ <4, -1, -5> * 100 rgb 0.5 parallel point_at 0 {light_turn} }}
sphere {{ 0, 1 texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 diffuse 0 {finish} }} {texture_turn} }} {object_turn} }}
"""
ANISO_FINISHES = {
    "ward": 'brdf_model { "ward rho_d=0.1 rho_s=0.4 ax=0.04 ay=0.35" direction <1, 0.2, 0> }',
    "table": 'brdf_table { "aniso.brdf" direction <1, 0.2, 0> }',
}


def rotation_pair(fork, finish, how, files=None, size=64):
    """The unrotated render and the render rotated by 90 deg about z (object or texture)."""
    turn = "rotate z*90"
    plain = ROTATION_SCENE.format(finish=finish, light_turn="", object_turn="", texture_turn="")
    if how == "object":
        turned = ROTATION_SCENE.format(finish=finish, light_turn=turn, object_turn=turn, texture_turn="")
    else:  # the texture turns, the (round) sphere need not; the lights turn with the scene
        turned = ROTATION_SCENE.format(finish=finish, light_turn=turn, object_turn="", texture_turn=turn)
    a = runner.render(plain, fork, width=size, height=size, float_exr=True, files=files).image
    b = runner.render(turned, fork, width=size, height=size, float_exr=True, files=files).image
    return a, b


@pytest.mark.parametrize("kind", ["ward", "table"])
@pytest.mark.parametrize("how", ["object", "texture"])
def test_rotated_anisotropic_sphere_is_the_render_rotated(fork, kind, how):
    files = None
    if kind == "table":
        files = {"aniso.brdf": tables.cached(
            ["tabulate", "ward rho_d=0.1 rho_s=0.4 ax=0.1 ay=0.35", "--layout", "aniso",
             "--step", "10", "--phi-step", "10"], "aniso-ward")}
    a, b = rotation_pair(fork, ANISO_FINISHES[kind], how, files)
    # POV's rotate z*90 takes +x to +y: the pixel at (x, y) moves to (-y, x), which is numpy's
    # rot90 of the image (rows run down, columns right).
    want = np.rot90(a, 1, axes=(0, 1))
    scale = float(a.max())
    assert scale > 0.2
    err = float(np.abs(b - want).max()) / scale
    print(f"{kind}, rotated {how}: max |rotated render - render rotated| / max = {err:.2e}")
    assert err <= 1e-5
    # The brushing shows: the image is far from its own rotation (the test can fail).
    assert float(np.abs(a - want).max()) / scale > 0.05


def test_isotropic_control_rotates_too(fork):
    # The pixel map above, checked where no anisotropy is involved.
    a, b = rotation_pair(fork, 'brdf_model { "microfacet d=beckmann m=0.3 kd=0.3 rho_s=0.6" }', "object")
    assert float(np.abs(b - np.rot90(a, 1, axes=(0, 1))).max()) <= 1e-5 * float(a.max())
