"""Virtual gonioreflectometer (FlatSampleScene) and the shadow-edge slab placeholder.

POV units: pixel = pi f(w_r, w_i) cos(theta_i) E, so diffuse 0.5 must re-measure f = 0.5/pi.
Every pixel sees the same direction pair, so all pixels must be identical; the half-float
EXR of stock then bounds the relative error by 2^-11 = 4.88e-4 (measured below that).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.core import compare, runner
from harness.reference import expect
from harness.core.scenes import FlatSampleScene, ShadowEdgeSlabScene

GEOMETRIES = [(0, 0, 0), (30, 60, 90), (60, 20, 180), (75, 80, 45), (85, 10, 0), (10, 89, 270)]


@pytest.mark.parametrize("ti,tr,phi", GEOMETRIES)
def test_lambert_remeasures_rho_over_pi(renderer, ti, tr, phi):
    s = FlatSampleScene(theta_i_deg=ti, theta_r_deg=tr, phi_deg=phi, light_colour=(1.0, 2.0, 0.5),
                        finish={"diffuse": 0.5})
    res = runner.render(s, renderer.binary, float_exr=renderer.float_exr)
    img = res.image
    assert np.all(img == img[0, 0]), "every pixel must see the sample under the same angles"
    f = expect.measured_brdf(img, s)
    rel = np.abs(f / (0.5 / math.pi) - 1.0)
    assert rel.max() <= renderer.sample_rel, f"f = {f}, relative error {rel}"


@pytest.mark.parametrize("ti,tr,phi", [(30, 30, 180), (45, 40, 170), (20, 60, 90)])
def test_phong_specular_geometry(renderer, ti, tr, phi):
    """Highlights depend on the full (w_i, w_r) geometry: checks the camera/light placement."""
    s = FlatSampleScene(theta_i_deg=ti, theta_r_deg=tr, phi_deg=phi,
                        finish={"diffuse": 0.2, "phong": 0.6, "phong_size": 8, "specular": 0.3,
                                "roughness": 0.1})
    res = runner.render(s, renderer.binary, float_exr=renderer.float_exr)
    want = expect.expected_image(s)
    st = compare.compare(res.image, want)
    assert st.rel_rmse < renderer.rel_tol, str(st)


@pytest.mark.parametrize("theta", [0.0, 40.0])
def test_shadow_edge_slab_diffuse(renderer, theta):
    """Without subsurface the edge is sharp at x = 0: lit d cos(theta) E, shadow 0."""
    s = ShadowEdgeSlabScene(theta_i_deg=theta, finish={"diffuse": 0.6}, width=64, height=8)
    res = runner.render(s, renderer.binary, float_exr=renderer.float_exr)
    want = expect.expected_image(s)
    assert np.all(res.image[:, :32] == 0.0) and np.all(res.image[:, 32:] > 0.0)
    st = compare.compare(res.image, want)
    assert st.rel_rmse < renderer.rel_tol, str(st)
