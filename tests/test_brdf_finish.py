"""The brdf_table / brdf_model finishes rendered by the fork.

Closed forms where there are any (a Lambert table is POV's ``diffuse``), otherwise the
same model evaluated directly (brdf_model) as the reference for its table.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from harness.core import runner, tables
from harness.core.compare import rel_rmse
from harness.reference.expect import expected_image, surface_samples
from harness.core.scenes import DistantLight, SphereScene

LIGHTS = (DistantLight(0.0), DistantLight(45.0, 30.0), DistantLight(80.0, 200.0))
FLOAT_TOL = 1e-5


def sphere(finish, lights=LIGHTS, size=96, pigment=(1.0, 1.0, 1.0)):
    return SphereScene(lights=lights, finish=finish, pigment=pigment, width=size, height=size)


def render(scene, fork, files=None, **kw):
    return runner.render(scene, fork, float_exr=True, files=files, **kw)


@pytest.mark.parametrize("interpolate", [0, 1])
def test_lambert_table_renders_like_diffuse(fork, interpolate):
    # POV's missing 1/pi: a table of rho/pi must give exactly `diffuse rho` (rho cos E).
    path = tables.tabulated("lambert rho=0.2,0.5,0.8", step=1.0)
    scene = sphere({"brdf_table": {"file": "lam.brdf", "interpolate": interpolate}})
    img = render(scene, fork, files={"lam.brdf": path}).image
    want = expected_image(sphere({"diffuse": 1.0}, pigment=(0.2, 0.5, 0.8)))
    mask = surface_samples(scene).mask
    print(f"interpolate {interpolate}: rel-RMSE {rel_rmse(img, want, mask):.2e}, max abs {np.abs(img - want)[mask].max():.2e}")
    assert rel_rmse(img, want, mask) < FLOAT_TOL
    assert np.abs(img - want)[mask].max() < 1e-5


def test_lambert_table_equals_stock_diffuse_render(fork, stock):
    path = tables.tabulated("lambert rho=0.6", step=2.0)
    a = render(sphere({"brdf_table": {"file": "lam.brdf"}}), fork, files={"lam.brdf": path}).image
    b = runner.render(sphere({"diffuse": 0.6}), stock).image  # half EXR
    # stock's half output is within half an ulp (2^-11 relative) of the exact value
    assert (np.abs(a - b) <= np.abs(b) * 2.0 ** -11 + 1e-6).all()


def test_table_matches_the_model_it_tabulates(fork):
    # 1 deg trilinear table of a rough dielectric lobe vs the same model evaluated directly.
    spec = "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.7"
    path = tables.tabulated(spec, step=1.0)
    direct = render(sphere({"brdf_model": {"spec": spec}}), fork).image
    table = render(sphere({"brdf_table": {"file": "t.brdf"}}), fork, files={"t.brdf": path}).image
    mask = surface_samples(sphere({})).mask
    err = rel_rmse(table, direct, mask)
    print(f"1 deg trilinear rel-RMSE {err:.2e}")
    # Measured 1.3e-5 (trilinear interpolation error of this lobe at 1 deg); the bound was 3e-3,
    # which a nearest-node or 5 deg table would pass. The independent version (numpy model,
    # per-pixel bound, negative controls) is tests/test_strict_tables.py.
    assert err < 5e-5
    assert direct[mask].max() > 0.1


def test_scale_and_use_color(fork):
    path = tables.tabulated("lambert rho=0.5", step=5.0)
    files = {"t.brdf": path}
    base = render(sphere({"brdf_table": {"file": "t.brdf"}}, pigment=(0.2, 0.4, 1.0)), fork, files=files).image
    scaled = render(sphere({"brdf_table": {"file": "t.brdf", "scale": (2.0, 1.0, 0.5)}}, pigment=(0.2, 0.4, 1.0)),
                    fork, files=files).image
    tinted = render(sphere({"brdf_table": {"file": "t.brdf", "use_color": True}}, pigment=(0.2, 0.4, 1.0)),
                    fork, files=files).image
    np.testing.assert_allclose(scaled, base * np.array([2.0, 1.0, 0.5], dtype=np.float32), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(tinted, base * np.array([0.2, 0.4, 1.0], dtype=np.float32), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(base[..., 0], base[..., 2], rtol=0, atol=0)  # pigment ignored


def test_model_replaces_phong_and_default_diffuse(fork):
    # phong/specular in a finish with a model are dropped; diffuse only counts when written.
    spec = "lambert rho=0.4"
    only = render(sphere({"brdf_model": {"spec": spec}}), fork).image
    with_phong = runner.render(
        """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0,0,-10> direction z right 2*x up 2*y }
light_source { <0,0,-1000> rgb 1 parallel point_at 0 }
sphere { 0, 1 pigment { rgb 1 } finish { ambient 0 phong 0.9 specular 0.5 brdf_model { "lambert rho=0.4" } } }
""", fork, width=96, height=96, float_exr=True).image
    single = render(sphere({"brdf_model": {"spec": spec}}, lights=(DistantLight(0.0),)), fork).image
    np.testing.assert_array_equal(with_phong, single)
    assert only.max() > 0.3


def test_shared_table_is_read_once(fork):
    path = tables.tabulated("lambert rho=0.5", step=2.0)
    text = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -6> look_at 0 }
light_source { <-3, 4, -5> rgb 1 }
#declare F = finish { brdf_table { "t.brdf" } }
sphere { <-1.2, 0, 0>, 1 pigment { rgb 1 } finish { F } }
sphere { <1.2, 0, 0>, 1 pigment { rgb 1 } finish { brdf_table { "t.brdf" interpolate 0 } } }
sphere { <0, 1.5, 1>, 0.5 pigment { rgb 1 } finish { brdf_table { "t.brdf" scale 0.5 } } }
"""
    res = runner.render(text, fork, width=64, height=48, files={"t.brdf": path})
    m = re.search(r"BRDF tables:\s+(\d+)\s+Files read:\s+(\d+)\s+Shared:\s+(\d+)", res.stderr)
    assert m, res.stderr[-2000:]
    assert (int(m[1]), int(m[2]), int(m[3])) == (1, 1, 2)
    mem = re.search(r"BRDF table memory:\s+(\d+) bytes", res.stderr)
    payload = 46 * 46 * 91 * 3 * 4  # 2 deg isotropic RGB float32, one copy for three finishes
    assert mem and payload <= int(mem[1]) < 1.01 * payload


BROKEN_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location -3*z look_at 0 }}
sphere {{ 0, 1
  finish {{ {finish} }}
}}
"""


@pytest.mark.parametrize("finish, needle", [
    ('brdf_table { "missing.brdf" }', "cannot read 'missing.brdf'"),
    ('brdf_table { "bad.brdf" }', "offset 0"),
    ('brdf_table { "short.brdf" }', "offset"),
    ('brdf_table { "t.brdf" interpolate 2 }', "interpolate must be 0"),
    ('brdf_model { "microfacet d=ggx" }', "unknown value 'ggx'"),
    ('brdf_model { "lambert rho=0.5" interpolate 1 }', "applies to brdf_table only"),
])
def test_bad_input_is_a_parse_error_at_the_line(fork, tmp_path, finish, needle):
    good = tables.tabulated("lambert rho=0.5", step=5.0)
    (tmp_path / "bad.brdf").write_bytes(b"this is not a table" * 10)
    (tmp_path / "short.brdf").write_bytes(good.read_bytes()[:5000])
    files = {"t.brdf": good, "bad.brdf": tmp_path / "bad.brdf", "short.brdf": tmp_path / "short.brdf"}
    with pytest.raises(runner.RenderError) as ei:
        runner.render(BROKEN_SCENE.format(finish=finish), fork, width=8, height=8, files=files)
    e = ei.value
    assert e.line == 5, e.stderr[-1500:]
    assert needle in e.message, e.message


def test_radiosity_lambert_table_matches_diffuse(fork):
    # Indirect light reaches a table finish through its directional albedo: a Cornell-like
    # box of Lambert tables renders like the same box with `diffuse`.
    path = tables.tabulated("lambert rho=0.7", step=2.0)
    box = """#version 3.7;
global_settings {{ assumed_gamma 1.0 radiosity {{ count 60 error_bound 0.5 recursion_limit 2 nearest_count 5 }} }}
camera {{ location <0, 0, -0.95> look_at 0 angle 90 }}
light_source {{ <0, 0.9, -0.5> rgb 1 }}
#declare F = finish {{ ambient 0 {finish} }}
box {{ -1, 1 inverse pigment {{ rgb 1 }} finish {{ F }} }}
sphere {{ <0.3, -0.6, 0.2>, 0.4 pigment {{ rgb 1 }} finish {{ F }} }}
"""
    files = {"t.brdf": path}
    a = runner.render(box.format(finish='brdf_table { "t.brdf" }'), fork, width=64, height=48,
                      float_exr=True, files=files).image
    b = runner.render(box.format(finish="diffuse 0.7"), fork, width=64, height=48, float_exr=True).image
    assert b.mean() > 0.05 and np.isfinite(a).all()
    err = rel_rmse(a, b)
    print(f"radiosity table vs diffuse rel-RMSE {err:.2e}")
    assert err < 1e-3


def test_copied_finish_keeps_its_diffuse(fork):
    # The block that names the model decides about diffuse; `finish { F }` keeps F's values.
    text = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0,0,-10> direction z right 2*x up 2*y }}
light_source {{ <0,0,-1000> rgb 1 parallel point_at 0 }}
#declare F = finish {{ ambient 0 brdf_model {{ "lambert rho=0.1" }} diffuse 0.6 }}
sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ {finish} }} }}
"""
    direct = runner.render(text.format(finish='ambient 0 brdf_model { "lambert rho=0.1" } diffuse 0.6'),
                           fork, width=16, height=16, float_exr=True).image
    copied = runner.render(text.format(finish="F"), fork, width=16, height=16, float_exr=True).image
    np.testing.assert_array_equal(copied, direct)
    # headlight at the sphere's centre: 0.1 (model) + 0.6 (diffuse), cos ~ 1
    assert abs(float(direct[8, 8, 0]) - 0.7) < 0.01


def test_layered_texture_under_a_clear_layer(fork):
    # A fully transparent top layer (transmit 1) leaves the table layer below untouched;
    # a half-transparent one lets half of it through (POV's layer opacity).
    path = tables.tabulated("lambert rho=0.5", step=5.0)
    text = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0,0,-10> direction z right 2*x up 2*y }}
light_source {{ <0,0,-1000> rgb 1 parallel point_at 0 }}
sphere {{ 0, 1
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 brdf_table {{ "t.brdf" }} }} }}
  {top}
}}
"""
    files = {"t.brdf": path}
    opts = dict(width=32, height=32, float_exr=True, files=files)
    alone = runner.render(text.format(top=""), fork, **opts).image
    clear = runner.render(text.format(top="texture { pigment { rgbt <1, 0, 0, 1> } finish { ambient 0 diffuse 0 } }"),
                          fork, **opts).image
    half = runner.render(text.format(top="texture { pigment { rgbt <0, 0, 0, 0.5> } finish { ambient 0 diffuse 0 } }"),
                         fork, **opts).image
    np.testing.assert_array_equal(clear, alone)
    np.testing.assert_allclose(half, 0.5 * alone, rtol=1e-6, atol=1e-7)
    assert alone.max() > 0.45


def test_photons_reach_a_table_finish(fork):
    # A glass sphere focuses a spot light into a caustic on a floor whose finish is a
    # Lambert table: the photon path (ComputePhotonDiffuseLight) must light it like
    # `diffuse` (same photons, same weights).
    path = tables.tabulated("lambert rho=0.7", step=2.0)
    text = """#version 3.7;
global_settings {{ assumed_gamma 1.0 photons {{ count 20000 }} }}
camera {{ location <0, 4, -0.01> look_at 0 angle 50 }}
light_source {{ <0, 6, 0> rgb 1 spotlight point_at 0 radius 10 falloff 12 photons {{ refraction on }} }}
plane {{ y, 0 pigment {{ rgb 1 }} finish {{ ambient 0 {floor} }} }}
sphere {{ <0, 1.2, 0>, 0.6 pigment {{ rgbf 1 }} interior {{ ior 1.5 }} photons {{ target refraction on }} }}
"""
    opts = dict(width=48, height=48, float_exr=True)
    table = runner.render(text.format(floor='brdf_table { "t.brdf" }'), fork, files={"t.brdf": path}, **opts).image
    diffuse = runner.render(text.format(floor="diffuse 0.7"), fork, **opts).image
    assert diffuse.max() > 1.0  # the caustic is there
    np.testing.assert_allclose(table, diffuse, rtol=1e-5, atol=1e-6)
