"""Renders of non-stochastic scenes are bit-identical across runs, thread counts and tile sizes.

Nothing in the fork may depend on which render thread shades a pixel or in which order the
blocks are traced: tables are immutable and shared, models are pure functions, and the glossy
``samples`` rays are seeded by the hit point and ray direction (``finish_sample_seed``), never
by a thread-local generator. Each scene is rendered with ``+WT1``, again with ``+WT1``, and
with ``+WT2`` and small render blocks (``+BS8``: many blocks, handed to the two threads in a
different order from run to run); all three images must be equal to the bit.

(``tests/test_analytic_finishes.py`` checks the same for a sphere in a white furnace; the
scenes here add tables, shadows, POV's own reflection and other objects hit by the glossy
rays.)

One exception is upstream's and stays: POV-Ray's per-thread shadow cache makes a rare pixel
depend on the order pixels are traced (a torus beside a sphere under an area light, the last
test); the fork renders it exactly as stock does in every order.
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.core import runner, tables
from harness.core.paths import repo_root
from harness.core.scenes import DistantLight, SphereScene

LIGHTS = (DistantLight(0.0), DistantLight(50.0, 30.0), DistantLight(75.0, 200.0))
TABLE_SPEC = "microfacet d=beckmann m=0.25 f=dielectric eta=1.5 kd=0.4 rho_s=0.6"


def three_renders(scene, fork, **kw):
    """The same scene: +WT1, +WT1 again, +WT2 with 8-pixel blocks."""
    a = runner.render(scene, fork, float_exr=True, threads=1, **kw).image
    b = runner.render(scene, fork, float_exr=True, threads=1, **kw).image
    extra = tuple(kw.pop("extra_args", ())) + ("+BS8",)
    c = runner.render(scene, fork, float_exr=True, threads=2, extra_args=extra, **kw).image
    return a, b, c


def assert_identical(a, b, c):
    assert np.isfinite(a).all()
    assert a.max() > 0.05, "the scene rendered (nearly) black: nothing was compared"
    assert np.array_equal(a, b), f"two +WT1 runs differ in {np.count_nonzero((a != b).any(-1))} pixels"
    assert np.array_equal(a, c), f"+WT1 and +WT2 differ in {np.count_nonzero((a != c).any(-1))} pixels"


def test_table_sphere(fork):
    path = tables.tabulated(TABLE_SPEC, step=2.0)
    scene = SphereScene(lights=LIGHTS, finish={"brdf_table": {"file": "t.brdf"}}, width=64, height=64)
    assert_identical(*three_renders(scene, fork, files={"t.brdf": path}))


def test_model_sphere(fork):
    scene = SphereScene(lights=LIGHTS, width=64, height=64,
                        finish={"brdf_model": {"spec": "ward ax=0.08 ay=0.3 rho_d=0.2 rho_s=0.3",
                                               "direction": (1.0, 1.0, 0.0)}})
    assert_identical(*three_renders(scene, fork))


GLOSSY_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 max_trace_level 4 }}
camera {{ location <0, 1.5, -5> look_at <0, 0.6, 0> angle 45 }}
light_source {{ <-4, 6, -5> rgb 1 }}
sky_sphere {{ pigment {{ gradient y color_map {{ [0 rgb <0.6, 0.6, 0.7>] [1 rgb <0.1, 0.2, 0.4>] }} }} }}
plane {{ y, 0 pigment {{ checker rgb 0.8 rgb 0.2 scale 0.5 }} finish {{ diffuse 0.8 reflection 0.2 }} }}
sphere {{ <-0.9, 0.7, 0>, 0.7 pigment {{ rgb 1 }} finish {{ brdf_table {{ "t.brdf" samples 6 }} }} }}
sphere {{ <0.9, 0.7, 0.3>, 0.7 pigment {{ rgb <1, 0.6, 0.3> }}
  finish {{ brdf_model {{ "{spec}" samples 5 use_color }} }} }}
"""


def test_glossy_samples_scene(fork):
    # Glossy rays from a table and from a model, reflecting a checkered floor that itself
    # reflects: every secondary ray's seed comes from its own hit point.
    path = tables.tabulated(TABLE_SPEC, step=2.0)
    text = GLOSSY_SCENE.format(spec="microfacet d=tr m=0.15 f=schlick f0=0.9 rho_s=1")
    a, b, c = three_renders(text, fork, width=64, height=48, files={"t.brdf": path})
    assert_identical(a, b, c)


def test_demo_scene(fork):
    needed = ["red-plastic.brdf", "red-plastic-measured.brdf", "gold.brdf", "copper-rough.brdf"]
    data = repo_root() / "build" / "brdf_data"
    if not all((data / n).is_file() for n in needed):
        pytest.skip("the demo's tables are not built (make brdf-data)")
    text = (repo_root() / "scenes" / "demo.pov").read_text()
    assert_identical(*three_renders(text, fork, width=96, height=54))


#: Stock POV-Ray only (no fork keywords): the demo's old layout with a torus beside a sphere
#: under an area light. Issue 16's "1 of 5184 pixels differs between +WT1 and +WT2" is this.
SHADOW_CACHE_SCENE = """#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 }
camera { location <0, 4.6, -10.5> look_at <0, 0.35, 0> angle 50 right x * image_width / image_height }
light_source { <-5, 8, -6> rgb 1.0 area_light x * 1.5, z * 1.5, 4, 4 adaptive 1 circular orient area_illumination on }
light_source { <6, 4, -3> rgb <0.25, 0.28, 0.32> }
plane { y, 0 pigment { checker rgb 0.6 rgb 0.45 scale 0.8 } finish { diffuse 0.8 } }
sphere { <1.75, 0.7, 1> 0.7 pigment { rgb 0.7 } finish { diffuse 0.7 phong 0.5 } }
torus { 0.5, 0.2 rotate x * 70 translate <3.5, 0.72, 1> pigment { rgb <0.8, 0.4, 0.3> } finish { diffuse 0.7 phong 0.5 } }
"""


def test_pixel_order_dependence_is_upstream_and_the_fork_matches_it(fork, stock):
    # POV-Ray 3.7 keeps, per render thread and light, the object that last blocked a shadow
    # ray and tests it first. That cached test accepts any intersection the object's own
    # routine reports (a torus: depth > 1e-4), while the full test accepts only depths in
    # (SHADOW_TOLERANCE, distance - SHADOW_TOLERANCE), SHADOW_TOLERANCE = 1e-3 (trace.cpp,
    # TraceShadowRay). Where a shadow ray grazes its own torus between the two, the result
    # depends on whether the torus or the sphere beside it is cached, i.e. on which pixel the
    # thread shaded before: on the block size and the thread count, in stock POV-Ray alike.
    # (Checked: with the cached test given the same depth window the difference vanishes; a
    # fork that did so would no longer match stock, so the fork keeps upstream's behaviour.)
    def pair(binary):
        a = runner.render(SHADOW_CACHE_SCENE, binary, width=96, height=54, threads=1).image
        b = runner.render(SHADOW_CACHE_SCENE, binary, width=96, height=54, threads=2, extra_args=("+BS8",)).image
        return a, b
    sa, sb = pair(stock)
    fa, fb = pair(fork)
    differ = int((sa != sb).any(-1).sum())
    print(f"stock: {differ} of {sa.shape[0] * sa.shape[1]} pixels differ between +WT1 and +WT2 +BS8")
    assert sa.max() > 0.05
    np.testing.assert_array_equal(fa, sa)  # the fork is stock in either pixel order
    np.testing.assert_array_equal(fb, sb)
