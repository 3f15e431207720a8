"""The dipole subsurface finish rendered by the fork.

The closed-form reference is a half-lit flat semi-infinite medium: a thick slab whose face is
shadowed for x < 0 by an invisible blade, lit from straight above. Every pixel is then
Ft(1) [Ft(1) E M(x)] + single scattering on the lit side, with M the dipole's radiant
exitance of a half-plane source (:func:`harness.reference.dipole_ref.half_plane_exitance`): light
bleeds into the shadow over a few diffusion lengths.
"""

from __future__ import annotations


import numpy as np
import pytest

from harness.reports import dipole_bench
from harness.core import runner

#: The medium of harness.reports.dipole_bench (its closed-form reference too): a short diffusion length
#: (1/sigma_tr = 2.5 mm) so a 50 mm slab is "semi-infinite": sigma_s' = 1/mm, sigma_a = 0.05/mm, eta 1.3.
SIGMA_S_PRIME, SIGMA_A, ETA = dipole_bench.SIGMA_S_PRIME, dipole_bench.SIGMA_A, dipole_bench.ETA

SLAB = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 0, 20> direction <0, 0, -1> right <20, 0, 0> up <0, 2.5, 0> }}
light_source {{ <0, 0, 1000> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-25, -25, -15>, <25, 25, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ {dipole} }} {extra} }} }} }}
box {{ <-100, -100, 5>, <0, 100, 5.01> no_image texture {{ pigment {{ rgb 0 }} }} }}
"""
# `profile dipole single_scatter on`: these tests check the hierarchical evaluation against the
# dipole's closed form plus single scattering (the finish's default is the exact profile, whose
# own checks are tests/test_ss_profiles.py).
DIPOLE = (f"sigma_s_prime {SIGMA_S_PRIME} sigma_a {SIGMA_A} ior {ETA} mm_per_unit 1 sample_spacing 0.25 "
          "profile dipole single_scatter on")


def slab(fork, dipole=DIPOLE, extra="", threads=1, width=160):
    return runner.render(SLAB.format(dipole=dipole, extra=extra), fork, width=width, height=20,
                         float_exr=True, threads=threads)


def expected_profile(width=160):
    return dipole_bench.reference(width)


def test_shadow_edge_profile_matches_the_dipole(fork):
    r = slab(fork)
    img = r.image
    assert np.isfinite(img).all() and (img >= 0).all()
    prof = img[..., 0].astype(np.float64).mean(axis=0)
    x, want = expected_profile()
    lit = want[-1]
    err = (prof - want) / lit
    edge = np.abs(x) < 0.5  # within the near-field radius R0 = 2 h of the edge
    print(f"profile error / lit level: rms {np.sqrt(np.mean(err[~edge] ** 2)):.2e}, "
          f"max {np.abs(err[~edge]).max():.2e}, at the edge {np.abs(err[edge]).max():.2e}")
    # measured: rms 5.6e-4, max 1.4e-3 (default error_bound 0.7), 4.7e-2 at the edge pixels
    assert np.sqrt(np.mean(err[~edge] ** 2)) < 2e-3
    assert np.abs(err[~edge]).max() < 5e-3
    assert np.abs(err[edge]).max() < 0.08
    # Light really bleeds: 2.5 mm into the shadow the dipole gives ~4 % of the lit level.
    assert prof[x < -2.4][-1] > 0.02 * lit
    # all channels equal (grey medium)
    np.testing.assert_allclose(img[..., 0], img[..., 2], rtol=1e-6, atol=1e-7)
    assert r.stats.get("reflected_rays", 0) == 0
    assert "Dipole objects:" in r.stderr and "Points:" in r.stderr


def test_hierarchy_threshold_trades_error_for_nodes(fork):
    def nodes(stderr):
        line = next(l for l in stderr.splitlines() if "Nodes/lookup" in l)
        return float(line.split()[-1])
    exact = slab(fork, DIPOLE + " error_bound 0.05", width=80)
    coarse = slab(fork, DIPOLE + " error_bound 1.0", width=80)
    lit = exact.image[..., 0].max()
    diff = np.abs(coarse.image - exact.image).max() / lit
    print(f"error_bound 1.0 vs 0.05: max diff {diff:.2e} of the lit level; nodes "
          f"{nodes(coarse.stderr):.0f} vs {nodes(exact.stderr):.0f}")
    assert diff < 0.01
    assert nodes(coarse.stderr) < nodes(exact.stderr) / 5


def test_dipole_is_repeatable_across_runs_and_threads(fork):
    a = slab(fork, width=48).image
    assert np.array_equal(a, slab(fork, width=48).image)
    assert np.array_equal(a, slab(fork, width=48, threads=2).image)


def test_coat_and_highlight_add_on_top(fork):
    # A brdf_model coat adds exactly its own light (the dipole part is unchanged).
    base = slab(fork, width=48).image
    coat = "lambert rho=0.1"
    both = slab(fork, width=48, extra=f'brdf_model {{ "{coat}" }}').image
    text = SLAB.format(dipole=DIPOLE, extra="").replace(f"dipole {{ {DIPOLE} }}", f'brdf_model {{ "{coat}" }}')
    only = runner.render(text, fork, width=48, height=20, float_exr=True).image
    np.testing.assert_allclose(both, base + only, rtol=2e-6, atol=2e-7)


def test_unbounded_object_gets_a_warning_not_a_crash(fork):
    text = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 2, -5> look_at 0 }
light_source { <2, 5, -3> rgb 1 }
plane { y, 0 finish { ambient 0 dipole { "Marble" } } }
"""
    r = runner.render(text, fork, width=32, height=24, float_exr=True)
    assert np.isfinite(r.image).all()
    assert "without a finite bounding box" in r.stderr


@pytest.mark.parametrize("body, message", [
    ('"Unobtainium"', "unknown"),
    ("sigma_s_prime 1", "expected sigma_a"),
    ("sigma_a 0.1", "expected a preset name or sigma_s"),
    ("sigma_s 1 sigma_s_prime 1 sigma_a 0.1", "not both"),
    ('sigma_a 0.1 "Marble"', "preset name must come first"),
    ('mm_per_unit 10 "Marble"', "preset name must come first"),
    ("sigma_s_prime -1 sigma_a 0.1", "sigma_s"),
    ("sigma_s_prime 1 sigma_a 0.1 ior 0", "eta"),
    ('"Marble" sample_spacing -1', "sample_spacing must be >= 0"),
    ('"Marble" error_bound 0', "error_bound must be in (0, 2]"),
    ('"Marble" refine_levels -1', "refine_levels must be a whole number from 0 to 12"),
    ('"Marble" refine_levels 2.5', "refine_levels must be a whole number from 0 to 12"),
    ('"Marble" refine_levels 13', "refine_levels must be a whole number from 0 to 12"),
    ('"Marble" single_scatter_samples -1', "single_scatter_samples must be a whole number of depths from 0"),
    ('"Marble" single_scatter_samples 2.5', "single_scatter_samples must be a whole number of depths from 0"),
    ('"Marble" single_scatter_samples 257', "16 to 32 suit most scenes"),
])
def test_bad_dipole_values_are_scene_errors(fork, body, message):
    text = f"""#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 0, -5> look_at 0 }}
sphere {{ 0, 1
  finish {{ dipole {{ {body} }} }} }}
"""
    with pytest.raises(runner.RenderError) as e:
        runner.render(text, fork, width=8, height=8)
    assert message in str(e.value)
    assert e.value.line == 5


def test_every_named_medium_renders(fork):
    # All 47 presets of dipole_media.inc parse and render finite, non-negative, lit spheres.
    import re
    from harness.core.paths import REPO_ROOT
    names = re.findall(r"^#declare\s+(F_Dipole_\w+)\s*=", (REPO_ROOT / "scenes/include/dipole_media.inc").read_text(),
                       re.MULTILINE)
    assert len(names) == 47
    cols = 8
    spheres = "\n".join(
        f"sphere {{ <{(i % cols) * 2.2}, {-(i // cols) * 2.2}, 0>, 1 finish {{ {n} }} }}" for i, n in enumerate(names))
    text = f"""#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
#declare Dipole_MM_Per_Unit = 2;
#include "dipole_media.inc"
camera {{ orthographic location <7.7, -5.5, -20> direction z right x * 17.6 up y * 13.2 }}
light_source {{ <-20, 30, -40> rgb 1 }}
{spheres}
"""
    r = runner.render(text, fork, width=8 * 16, height=6 * 16, float_exr=True)
    assert np.isfinite(r.image).all() and (r.image >= 0).all()
    # every sphere's centre pixel is lit (Coke and Pepsi scatter little: 2e-5, not 0)
    for i in range(47):
        px = r.image[(i // cols) * 16 + 8, (i % cols) * 16 + 8]
        assert px.max() > 0.0, names[i]
    assert "Dipole objects:                  47" in r.stderr


def test_thin_geometry_is_reported(fork):
    # A 0.2 mm sheet of a medium whose mean free path is ~1 mm: the statistics say what thin
    # geometry did (tests/test_dipole_thin.py checks the light); with thin_geometry off they warn
    # that the half-space dipole is outside its assumptions.
    text = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, 20> direction <0, 0, -1> right <12, 0, 0> up <0, 12, 0> }
light_source { <0, 0, 1000> rgb 1 parallel point_at <0, 0, 0> }
box { <-5, -5, -0.2>, <5, 5, 0> finish { ambient 0 dipole { sigma_s_prime 1 sigma_a 0.01 ior 1.3 mm_per_unit 1 } } }
"""
    r = runner.render(text, fork, width=24, height=24, float_exr=True)
    assert np.isfinite(r.image).all() and (r.image >= 0).all()
    assert "Dipole thin geometry: 1 object(s)" in r.stderr and "thinnest 0.2 units" in r.stderr
    assert "thinner than the mean free path" not in r.stderr
    off = runner.render(text.replace("mm_per_unit 1 }", "mm_per_unit 1 thin_geometry off }"), fork, width=24,
                        height=24, float_exr=True)
    assert "thinner than the mean free path" in off.stderr and "thin geometry" not in off.stderr
    # 100 mm in every direction is above this medium's slab threshold (~30 mm): nothing to report
    thick = runner.render(text.replace("<-5, -5, -0.2>, <5, 5, 0>", "<-50, -50, -100>, <50, 50, 0>"), fork, width=24,
                          height=24, float_exr=True)
    assert "thinner than the mean free path" not in thick.stderr and "thin geometry" not in thick.stderr
