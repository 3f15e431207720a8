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
