"""harness.core.povwriter: text structure, exact numbers, finish registry; output renders with stock."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from harness.core import povwriter, runner
from harness.core.scenes import (DistantLight, FlatSampleScene, ShadowEdgeSlabScene, SphereScene,
                                 written_finish)


def test_floats_round_trip_and_reject_nonfinite():
    for x in (0.1, 1 / 3, 1e-12, -2.5e7, math.pi):
        assert float(povwriter.fmt(x)) == x
    assert povwriter.fmt(-0.0) == "0"
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError):
            povwriter.fmt(bad)


def test_finish_defaults_and_order():
    text = povwriter.finish_block({"phong": 0.8, "phong_size": 40})
    assert text == ("finish { ambient rgb <0, 0, 0> emission rgb <0, 0, 0> diffuse 0 "
                    "phong 0.8 phong_size 40.0 }")
    assert written_finish({"diffuse": 0.6})["diffuse"] == 0.6


def test_unknown_finish_keyword_is_an_error_and_registry_extends():
    with pytest.raises(KeyError, match="shiny"):
        povwriter.finish_block({"shiny": 1.0})
    reg = dict(povwriter.FINISH_KEYWORDS)
    try:
        povwriter.FINISH_KEYWORDS["shiny"] = povwriter.string_keyword
        povwriter.FINISH_KEYWORDS["ward"] = povwriter.block_keyword
        text = povwriter.finish_block({"shiny": "t.brdf", "ward": {"alpha": 0.2, "rho_s": (0.1, 0.2, 0.3)}})
        assert 'shiny "t.brdf"' in text
        assert "ward { alpha 0.2 rho_s <0.1, 0.2, 0.3> }" in text
    finally:
        povwriter.FINISH_KEYWORDS.clear()
        povwriter.FINISH_KEYWORDS.update(reg)


def test_model_keywords():
    text = povwriter.finish_block({"brdf_table": {"file": "g.brdf", "interpolate": 0, "scale": (1, 0.5, 0.25),
                                                  "use_color": True, "direction": (0, 1, 0)}})
    assert 'brdf_table { "g.brdf" interpolate 0 scale rgb <1.0, 0.5, 0.25> use_color on direction <0, 1.0, 0> }' in text
    assert 'brdf_model { "lambert rho=0.5" }' in povwriter.finish_block({"brdf_model": {"spec": "lambert rho=0.5"}})
    with pytest.raises(KeyError, match="bogus"):
        povwriter.finish_block({"brdf_table": {"file": "g.brdf", "bogus": 1}})


def test_sphere_text_is_explicit_and_linear():
    s = SphereScene(lights=(DistantLight(45, 30, (1.0, 0.5, 0.25)),), finish={"diffuse": 0.6})
    text = povwriter.scene_to_pov(s)
    assert "assumed_gamma 1.0" in text and "look_at" not in text
    assert "orthographic" in text and "parallel" in text and "point_at <0, 0, 0>" in text
    assert "fade" not in text
    # the light location written is exactly far along the scene's light direction
    m = re.search(r"light_source \{\s*<([^>]*)>", text)
    loc = np.array([float(v) for v in m.group(1).split(",")])
    assert np.allclose(loc / np.linalg.norm(loc), s.world_lights()[0].direction, rtol=0, atol=1e-15)
    assert np.linalg.norm(loc) > 100 * s.extent()


def test_flat_sample_camera_is_orthonormal_and_above():
    s = FlatSampleScene(theta_i_deg=30, theta_r_deg=85, phi_deg=135)
    cam = s.camera()
    d, r, u = (np.asarray(v) for v in (cam.direction, cam.right, cam.up))
    assert abs(np.dot(d, r)) < 1e-15 and abs(np.dot(d, u)) < 1e-15 and abs(np.dot(r, u)) < 1e-15
    assert u[2] > 0  # the sample's normal points up in the image
    assert np.all(cam.ray_origins(s.width, s.height)[..., 2] > 0)


@pytest.mark.parametrize("scene", [
    SphereScene(width=16, height=16, finish={"diffuse": 0.5, "phong": 0.3, "specular": 0.2,
                                            "roughness": 0.1, "brilliance": 2, "emission": (0.1, 0, 0)}),
    FlatSampleScene(theta_i_deg=10, theta_r_deg=20, phi_deg=30),
    ShadowEdgeSlabScene(width=16, height=4),
], ids=["sphere", "flat", "slab"])
def test_written_scenes_parse_and_render_with_stock(stock, scene):
    res = runner.render(scene, stock)
    assert res.image.shape == (scene.height, scene.width, 3)
    assert res.warnings == []
    assert res.image.max() > 0
