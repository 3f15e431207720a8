"""The fork pipeline: the binary says what it is, float EXR round-trips, and unmodified
scenes render as stock renders them (the stock guard).

Stock is Debian's binary package 1:3.7.0.10-2 (built with Debian's -O3 and hardening
flags); the fork is the same source plus our series, built -O2 -fno-fast-math. The guard
compares both through the same half-float EXR writer (+FE), so the only differences left
are the compilers' floating-point choices: the tolerance below is stated per sample.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from harness.core import runner
from harness.core.paths import repo_root

DISTRIBUTION = repo_root() / "povray" / "distribution" / "scenes"


def test_banner_names_the_fork(fork):
    out = subprocess.run([str(fork.path), "--version"], capture_output=True, text=True,
                         env={"HOME": "/nonexistent"}, timeout=30)
    text = out.stdout + out.stderr
    assert "3.7.0.10" in text
    assert "povray-brdf" in text


BACKGROUND = """#version 3.7;
global_settings { assumed_gamma 1.0 }
background { rgb <0.123456789, 0.5, 3.25> }
"""


def test_float32_exr_round_trips_exactly(fork):
    # A background colour reaches the file untouched: with +FE32 every pixel is the float32
    # nearest the scene's number (half would give 0.12347 and cap every comparison at 5e-4).
    res = runner.render(BACKGROUND, fork, width=5, height=3, float_exr=True)
    assert res.exr_dtype == np.float32
    want = np.array([0.123456789, 0.5, 3.25], dtype=np.float32)
    assert np.array_equal(res.image, np.broadcast_to(want, res.image.shape))
    assert np.float16(0.123456789) != want[0]  # the test can tell half from float


def test_plain_fe_still_writes_half(fork):
    # +FE without a bit depth keeps 3.7's half-float output: old command lines are unchanged.
    res = runner.render(BACKGROUND, fork, width=2, height=2, float_exr=False)
    assert res.exr_dtype == np.float16
    assert res.image[0, 0, 0] == np.float32(np.float16(0.123456789))


# Our own small scenes (the paths the project replaces: diffuse, phong, specular, metallic,
# mirror reflection, refraction, area lights, photons) and distribution scenes.
OWN_SCENES = {
    "finishes": """#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 6 }
camera { location <0, 2, -6> look_at <0, 0.6, 0> angle 40 }
light_source { <-4, 6, -5> rgb 1 }
light_source { <5, 3, -2> rgb <0.3, 0.35, 0.4> }
plane { y, 0 pigment { checker rgb 0.8 rgb 0.2 scale 0.5 } finish { diffuse 0.7 reflection 0.2 } }
sphere { <-1.3, 0.7, 0> 0.7 pigment { rgb <0.8, 0.2, 0.1> } finish { diffuse 0.6 phong 0.8 phong_size 40 } }
sphere { <0, 0.7, 0.5> 0.7 pigment { rgb <0.9, 0.8, 0.3> }
         finish { diffuse 0.2 specular 0.9 roughness 0.01 metallic reflection { 0.5 metallic } } }
sphere { <1.3, 0.7, 0> 0.7 pigment { rgbf <0.9, 1, 0.9, 0.9> }
         finish { diffuse 0.1 phong 0.5 } interior { ior 1.5 } }
""",
    "area_light": """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 3, -5> look_at 0 }
light_source { <2, 5, -3> rgb 1 area_light x, z, 4, 4 adaptive 1 circular orient }
plane { y, -1 pigment { rgb 0.7 } }
box { -0.8, 0.8 rotate y*30 pigment { rgb <0.2, 0.5, 0.9> } finish { phong 0.6 specular 0.3 } }
""",
}
DIST_SCENES = [
    "lights/arealit1",
    "lights/spotlite",
    "interior/iortest",
    "lights/phot_met_glass",
    "advanced/woodbox",
    "textures/finishes/metallicreflection",
    "subsurface/subsurface",
    "radiosity/cornell",
]

# The fork must render every stock scene exactly as Debian's binary does: both write POV's
# half-float EXR (+FE; stock cannot write float32) and every sample must be equal, bit for bit.
# Measured on Debian bookworm (gcc 12), both built with Debian's flags (dpkg-buildflags
# hardening=+all, -O3; the fork adds only -fno-fast-math, gcc's default): all ten scenes are.


def _guard_cases():
    for name, text in OWN_SCENES.items():
        yield pytest.param(("text", text), id=name)
    for rel in DIST_SCENES:
        yield pytest.param(("dist", rel), id=rel.replace("/", "-"))


@pytest.mark.parametrize("case", list(_guard_cases()))
def test_stock_guard(case, stock, fork):
    kind, what = case
    if kind == "dist":
        path = DISTRIBUTION / f"{what}.pov"
        if not path.is_file():
            pytest.fail(f"distribution scene missing: {path} (run make first)")
        text = path.read_text(errors="replace")
    else:
        text = what
    opts = dict(width=96, height=72, threads=1, float_exr=False)
    a = runner.render(text, stock, **opts).image
    b = runner.render(text, fork, **opts).image
    assert a.shape == b.shape == (72, 96, 3)
    assert np.isfinite(b).all()
    diff = np.abs(b.astype(np.float64) - a)
    rel = diff / np.maximum(np.abs(a), 1 / 64)
    worst = float(rel.max())
    print(f"{what if kind == 'dist' else 'own'}: max rel {worst:.3g}, mean abs {diff.mean():.3g}, "
          f"exact {np.mean(diff == 0):.4f}")
    assert float(a.max()) > 0.05, "the scene rendered black: the guard would prove nothing"
    assert np.array_equal(a, b), (f"{int(np.sum(diff != 0))} of {diff.size} samples differ from stock "
                                  f"(max rel {worst:.3g})")
