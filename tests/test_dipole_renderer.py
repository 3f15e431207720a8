"""The dipole finish where real scenes put it (issue 15, part A): shadow edges at default
settings, the same image from any number of threads, no rings, the scene's own scale.

The edge scene is :mod:`harness.reports.dipole_bench`'s (a marble slab under a plate casting a
sharp shadow edge, against the closed-form half-plane dipole); the fast test looks at a
[-8, 8]^2 mm window of it (128^2 pixels, the same 0.125 mm pixels), the slow one at the full
[-16, 16]^2 mm.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from harness.core import runner
from harness.reports import dipole_bench


def edge_render(fork, extra="", half=8.0, width=128, threads=1):
    r = runner.render(dipole_bench.edge_fork_scene(extra, half=half), fork, width=width, height=width,
                      float_exr=True, threads=threads)
    assert np.isfinite(r.image).all() and (r.image >= 0).all()
    return r


#: Issue 15's shadow-edge scene at default settings against the closed form: the worst pixel
#: (relative) and the rms over the image. Stock subsurface at its defaults: 13 % worst.
EDGE_MAX_TOL = 0.03
EDGE_RMS_TOL = 0.005


def test_shadow_edge_at_default_settings_within_three_percent(fork):
    # Measured: 0.98 % max, 0.16 % rms (0.36 % max at 5 edge levels). Without refinement
    # (refine_levels 0: one spacing everywhere, 1 mm here, as before issue 15) the pixels next
    # to the edge are 28 % off: the near field takes x's own light over 3 spacings.
    r = edge_render(fork)
    mx, rms, err = dipole_bench.edge_errors(r.image, half=8.0)
    print(f"default: max {mx:.2%}, rms {rms:.2%}")
    assert mx < EDGE_MAX_TOL
    assert rms < EDGE_RMS_TOL
    assert "Dipole refinement:" in r.stderr
    flat = edge_render(fork, "refine_levels 0")
    mx0, _, _ = dipole_bench.edge_errors(flat.image, half=8.0)
    print(f"refine_levels 0: max {mx0:.2%}")
    assert mx0 > 0.2
    assert "Dipole refinement:" not in flat.stderr


def test_shadow_edge_with_the_exact_profile_at_default_settings(fork):
    # The same window with the finish's defaults (the exact profile, single scattering on)
    # against the half-plane integral of the exact profile's own Rd (dipole_bench.
    # edge_reference_exact): the sampling, refinement and octree integrate any profile.
    # Measured (full scene, 256^2): 0.79 % max, 0.16 % rms; without refinement far off.
    # `directional off` (the default): the closed form is the radial profile's; with the entry
    # shifts the same edge under this 45-degree light is 8 % of the total away from it, as exact
    # transport is (tests/test_directional.py).
    r = runner.render(dipole_bench.edge_exact_scene("directional off", half=8.0), fork, width=128, height=128,
                      float_exr=True, threads=1)
    mx, rms, _ = dipole_bench.edge_errors(r.image, half=8.0, exact=True)
    print(f"exact profile, default: max {mx:.2%}, rms {rms:.2%}")
    assert mx < EDGE_MAX_TOL
    assert rms < EDGE_RMS_TOL
    flat = runner.render(dipole_bench.edge_exact_scene("refine_levels 0 directional off", half=8.0), fork, width=128, height=128,
                         float_exr=True, threads=1)
    mx0, _, _ = dipole_bench.edge_errors(flat.image, half=8.0, exact=True)
    print(f"exact profile, refine_levels 0: max {mx0:.2%}")
    assert mx0 > 0.1


@pytest.mark.slow
def test_shadow_edge_full_scene_at_default_settings(fork):
    # The scene exactly: 256^2 pixels over [-16, 16]^2 mm. Measured 0.98 % max, 0.14 % rms.
    r = edge_render(fork, half=dipole_bench.EDGE_HALF, width=dipole_bench.EDGE_WIDTH)
    mx, rms, _ = dipole_bench.edge_errors(r.image)
    print(f"max {mx:.2%}, rms {rms:.2%}, trace {r.trace_seconds} s")
    assert mx < EDGE_MAX_TOL
    assert rms < EDGE_RMS_TOL


SEVERAL = """#version 3.7;
global_settings { assumed_gamma 1.0 mm_per_unit 10 }
#include "dipole_media.inc"
camera { location <0, 2, -6> look_at <0, 0.6, 0> angle 40 }
light_source { <-4, 6, -3> rgb 0.8 area_light x * 1.5, z * 1.5, 3, 3 circular orient }
light_source { <3, 2, 4> rgb 0.6 }
plane { y, 0 pigment { rgb 0.4 } finish { diffuse 0.8 } }
box { <-1.6, 1.5, -0.8>, <-1.2, 1.6, 0.8> pigment { rgb 0 } }
sphere { <-1.5, 0.6, 0>, 0.6 finish { F_Dipole_Marble } }
sphere { <0, 0.5, 0.5>, 0.5 finish { F_Dipole_Skin1 specular 0.3 roughness 0.02 } }
box { <1, 0, -0.5>, <2, 1.2, 0.5> rotate y * 30 finish { dipole { "Ketchup" } } }
"""


def test_several_objects_area_light_same_image_from_any_number_of_threads(fork):
    # Three objects sampled (and refined at their shadows and terminators) by whichever threads
    # ask first, taking chunks of each other's work: the images must be equal to the bit.
    a = runner.render(SEVERAL, fork, width=96, height=72, float_exr=True, threads=1)
    b = runner.render(SEVERAL, fork, width=96, height=72, float_exr=True, threads=1)
    c = runner.render(SEVERAL, fork, width=96, height=72, float_exr=True, threads=2, extra_args=("+BS8",))
    assert a.image.max() > 0.05
    assert "Dipole objects:                   3" in a.stderr
    assert "Dipole refinement:" in a.stderr
    assert np.array_equal(a.image, b.image)
    assert np.array_equal(a.image, c.image), f"{np.count_nonzero((a.image != c.image).any(-1))} pixels differ"
    assert a.stderr.count("Points:") == c.stderr.count("Points:")


def test_a_cloud_lit_by_an_area_light_is_the_same_from_run_to_run(fork):
    # Which thread lights which samples varies from run to run: with POV's shadow cache (the
    # object that last shadowed a light, tested first with other tolerances) carried into the
    # cloud, the Skin1 sphere under SEVERAL's area light differed by ~1e-7 in 9 of 30 runs at 4
    # threads (patch 0026); 16 runs miss that with a probability of 0.3 %.
    scene = "\n".join(line for line in SEVERAL.splitlines() if "Marble" not in line and "Ketchup" not in line)
    a = runner.render(scene, fork, width=96, height=72, float_exr=True, threads=1)
    assert a.image.max() > 0.05
    for run in range(16):
        d = runner.render(scene, fork, width=96, height=72, float_exr=True, threads=4, extra_args=("+BS8",))
        assert np.array_equal(a.image, d.image), f"run {run}: {np.count_nonzero((a.image != d.image).any(-1))} pixels differ"


RING_SPHERE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 0, -10> direction <0, 0, 1> right <2.2, 0, 0> up <0, 2.2, 0> }}
light_source {{ <0, 0, -100> rgb 1 parallel point_at <0, 0, 0> }}
sphere {{ 0, 1 finish {{ ambient 0 dipole {{ sigma_s_prime <2.19, 2.62, 3.00> sigma_a <0.0021, 0.0041, 0.0071>
  ior 1.5 mm_per_unit {mpu} single_scatter off }} }} }}
"""


def ring_amplitude(image: np.ndarray, inner: float = 0.6) -> float:
    """Largest departure of the green channel from a smooth radial profile (an even polynomial
    of degree 12 in the distance from the sphere's centre) inside `inner` of its radius, as a
    fraction of the brightest pixel. The light comes from the camera: the image is radially
    symmetric and smooth, apart from rings."""
    w = image.shape[0]
    g = image[..., 1].astype(np.float64)
    c = (w - 1) / 2
    yy, xx = np.mgrid[0:w, 0:w]
    rho = np.hypot(xx - c, yy - c) / (w / 2.2)  # in sphere radii
    sel = rho < inner
    basis = np.stack([rho[sel] ** (2 * k) for k in range(7)], axis=1)
    coef, *_ = np.linalg.lstsq(basis, g[sel], rcond=None)
    return float(np.abs(g[sel] - basis @ coef).max() / g.max())


@pytest.mark.parametrize("mpu", [10, 100])
def test_no_rings_around_the_point_facing_the_camera(fork, mpu):
    # Lines along x and y graze the sphere around its point facing -z and used to count there
    # with weight |n_axis| / sum |n| on sparse circles of crossings: rings of 1-2 / 255 levels.
    # Measured before (the binary of commit 0b43ec4): 1.57 % at mm_per_unit 10, 2.25 % at 100;
    # now 0.20 % and 0.19 %, and what is left is no ring but the faint square pattern of the
    # sample grid seen through the window's ramp (the spacing is 1 mm here, about 2 mean free
    # paths).
    r = runner.render(RING_SPHERE.format(mpu=mpu), fork, width=160, height=160, float_exr=True)
    amp = ring_amplitude(r.image)
    print(f"mm_per_unit {mpu}: ring amplitude {amp:.3%} of the brightest pixel")
    assert amp < 0.005


MARBLE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 {globals} }}
camera {{ location <0, 0, -4> look_at 0 }}
light_source {{ <-3, 4, -5> rgb 1 }}
sphere {{ 0, 1 finish {{ ambient 0 dipole {{ "Marble" {dipole} }} }} }}
"""


def marble(fork, globals_="", dipole=""):
    return runner.render(MARBLE.format(globals=globals_, dipole=dipole), fork, width=48, height=48, float_exr=True)


def test_mm_per_unit_defaults_to_the_global_setting(fork):
    by_global = marble(fork, globals_="mm_per_unit 5")
    by_finish = marble(fork, dipole="mm_per_unit 5")
    assert np.array_equal(by_global.image, by_finish.image)
    # POV's own default (10), not 1
    default = marble(fork)
    assert np.array_equal(default.image, marble(fork, dipole="mm_per_unit 10").image)
    assert not np.array_equal(default.image, by_global.image)
    # the finish's own value wins over the global one
    assert np.array_equal(marble(fork, globals_="mm_per_unit 5", dipole="mm_per_unit 10").image, default.image)


def test_mm_per_unit_set_after_a_dipole_finish_is_a_warning(fork):
    text = MARBLE.format(globals="", dipole="") + "global_settings { mm_per_unit 5 }\n"
    r = runner.render(text, fork, width=16, height=16)
    assert any("mm_per_unit changed to 5 after 1 dipole finish(es) took its earlier value 10" in w
               for w in r.warnings), r.warnings


def test_small_objects_are_reported_in_scene_units(fork):
    # Marble at 10 mm per unit: the red diffusion length 1/sigma_tr = 8.51 mm = 0.851 units.
    text = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -12> look_at 0 }
light_source { <-3, 4, -5> rgb 1 }
sphere { <-2, 0, 0>, 0.5 finish { dipole { "Marble" } } }
sphere { <2.5, 0, 0>, 2 finish { dipole { "Marble" } } }
"""
    r = runner.render(text, fork, width=64, height=48)
    lines = r.stderr.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("Dipole warning: sphere at <-2, 0, 0> "))
    assert "(extent 1 units)" in lines[at]
    assert "is smaller than 3 diffusion lengths (1/sigma_tr = 8.51 mm = 0.851 units" in lines[at + 1]
    # the ball (1 unit = 10 mm) is below marble's slab threshold (36 mm in red): thin geometry
    # carries light through it, and the note says so (with thin_geometry off: "... is lost")
    assert "at mm_per_unit 10): light through it follows slab profiles" in lines[at + 2]
    assert "(thinnest 1 units)" in lines[at + 3]
    assert len(re.findall(r"Dipole warning: sphere at", r.stderr)) == 1  # the 4-unit ball is not small


def test_a_sample_spacing_far_below_the_object_is_an_error_not_a_hang(fork):
    # 1e-5 units on a 2-unit ball: 1.2e11 lines. The render stops at once with the reason.
    text = MARBLE.format(globals="", dipole="sample_spacing 0.00001")
    with pytest.raises(runner.RenderError) as e:
        runner.render(text, fork, width=16, height=16, timeout=60)
    assert "dipole: a sample spacing of 1e-05 units needs" in e.value.stderr
    assert "give a larger sample_spacing" in e.value.stderr
