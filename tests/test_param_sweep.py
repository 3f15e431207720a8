"""Every finish parameter in range renders finite, or is refused with its range (issue 29).

A tester found ``dipole { "Marble" ior 5 profile dipole }`` rendering every pixel of the object
NaN with exit 0 and no message (Jensen's Fdr polynomial passes 1 at ior 3.87), and a table
value of 1e38 rendering inf pixels. Here the fork renders small float images (24 x 24, +FE32)
across the parameters' ranges and asserts **0 NaN and 0 inf pixels** (and no negative one), or
the parse error at the finish's line that names the valid range:

* dipole: ior 0.1 .. 10 (``profile dipole``; ``profile exact`` covers 1 .. 2), sigma_s and
  sigma_a 1e-6 .. 1e6 per mm, anisotropy -0.99 .. 0.99, mm_per_unit 1e-3 .. 1e3;
* degenerate geometry under a dipole: a zero-radius sphere, a disc, a zero-thickness box, a
  zero-area triangle, a plane;
* tables: values up to the loader's bound 1e10 1/sr (with ``scale`` up to 1e6), and above it.

The fast part (about 20 renders) takes the cases that were wrong, the ends of the ior and sigma
ranges, three degenerate shapes, the refusals and the tables; the rest and the full grid
(ior x sigma_s x sigma_a, g x sigma x both profiles, the exact profile's iors: 351 renders) are ``slow``. Each render prints its parameters and its NaN/inf counts.
"""

from __future__ import annotations

import itertools
import math
import struct

import numpy as np
import pytest

from harness.core import runner, tables
from harness.core.brdf_io import fnv1a64

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 0.5, -5> look_at 0 }}
light_source {{ <2, 5, -3> rgb 1 }}
{obj}
"""
LINE = 5  # the object (and its finish) is on line 5
SIZE = 24


def sphere(finish: str) -> str:
    return f"sphere {{ 0, 1 finish {{ ambient 0 {finish} }} }}"


def dipole(body: str) -> str:
    return sphere(f"dipole {{ {body} }}")


def render_finite(fork, obj: str, files=None, label: str = "") -> np.ndarray:
    """Render; assert no NaN, inf or negative pixel; return the image."""
    r = runner.render(SCENE.format(obj=obj), fork, width=SIZE, height=SIZE, float_exr=True, files=files)
    img = r.image
    nan, inf = int(np.isnan(img).sum()), int(np.isinf(img).sum())
    neg = int((img < 0).sum())
    print(f"{label or obj}: {nan} NaN, {inf} inf, {neg} negative; max {np.nanmax(img):.4g}")
    assert (nan, inf, neg) == (0, 0, 0), f"{label or obj}: {nan} NaN, {inf} inf, {neg} negative values"
    return img


def refusal(fork, obj: str, files=None) -> str:
    with pytest.raises(runner.RenderError) as ei:
        runner.render(SCENE.format(obj=obj), fork, width=8, height=8, files=files)
    e = ei.value
    print(f"{obj}\n  -> {e.file} line {e.line}: {e.message}")
    assert (e.file, e.line) == ("scene.pov", LINE), f"{e.file} line {e.line}: {e.message}"
    return e.message


def centre(img: np.ndarray) -> float:
    return float(img[SIZE // 2 - 2:SIZE // 2 + 2, SIZE // 2 - 2:SIZE // 2 + 2].mean())


# ---------------------------------------------------------------- dipole: the cases that were wrong

@pytest.mark.parametrize("ior", [pytest.param(3.9, marks=pytest.mark.slow), 3.99, 5, pytest.param(10, marks=pytest.mark.slow)])
def test_marble_beyond_the_fit_renders_lit_and_finite(fork, ior):
    # Was: ior 3.99 and 5 every pixel of the sphere NaN (black), rc 0, no message.
    img = render_finite(fork, dipole(f'"Marble" ior {ior} profile dipole'))
    assert centre(img) > 0.01, f"ior {ior}: the sphere is black ({centre(img)})"


def test_fdr_switch_is_continuous_in_the_image(fork):
    # ior 2 (the fit) and 2.0001 (the exact Fdr: 5e-5 apart): the images within 1e-3 relative.
    a = render_finite(fork, dipole('"Marble" ior 2 profile dipole'))
    b = render_finite(fork, dipole('"Marble" ior 2.0001 profile dipole'))
    rel = float(np.abs(a - b).max() / a.max())
    print(f"ior 2 vs 2.0001: max difference / max = {rel:.2e}")
    assert rel < 1e-3


# ---------------------------------------------------------------- dipole: the ends of every range

ENDS = [
    "sigma_s_prime 1 sigma_a 0.01 ior 0.1 profile dipole",
    "sigma_s_prime 1 sigma_a 0.01 ior 10 profile dipole",
    "sigma_s_prime 1e-6 sigma_a 1e-6 ior 1.3 profile dipole",
    "sigma_s_prime 1e6 sigma_a 1e6 ior 1.3 profile dipole",
    "sigma_s_prime 1e6 sigma_a 1e-6 ior 1.3 profile dipole",
    "sigma_s 2 anisotropy -0.99 sigma_a 0.01 ior 1.3 profile dipole",
    "sigma_s 2 anisotropy 0.99 sigma_a 0.01 ior 1.3",  # exact: clamped at 0.95 with a warning
    '"Marble" mm_per_unit 0.001 profile dipole',
    '"Marble" mm_per_unit 1000',
]


FAST_ENDS = set(ENDS[:4])


@pytest.mark.parametrize("body", [b if b in FAST_ENDS else pytest.param(b, marks=pytest.mark.slow) for b in ENDS])
def test_range_ends_render_finite(fork, body):
    render_finite(fork, dipole(body))


# ---------------------------------------------------------------- dipole: degenerate geometry

GEOMETRY = [
    'sphere { 0, 0 finish { ambient 0 dipole { "Marble" } } }',
    'sphere { 0, 1e-9 finish { ambient 0 dipole { "Marble" } } }',
    'disc { 0, -z, 1 finish { ambient 0 dipole { "Marble" } } }',
    'box { <-1, -1, 0>, <1, 1, 0> finish { ambient 0 dipole { "Marble" } } }',
    'triangle { <-1, 0, 0>, <0, 0, 0>, <1, 0, 0> finish { ambient 0 dipole { "Marble" } } }',
    'triangle { <-1, -1, 0>, <1, -1, 0>, <0, 1, 0> finish { ambient 0 dipole { "Marble" profile dipole } } }',
    'plane { y, -1 finish { ambient 0 dipole { "Marble" } } }',
]


@pytest.mark.parametrize("obj", [g if i in (0, 3, 4) else pytest.param(g, marks=pytest.mark.slow)
                                 for i, g in enumerate(GEOMETRY)])
def test_degenerate_geometry_renders_finite(fork, obj):
    render_finite(fork, obj)


# ---------------------------------------------------------------- dipole: refusals

REFUSED = [
    ('"Marble" ior 10.5 profile dipole',
     "dipole medium: ior (eta) = 10.5: expected a value in [0.1, 10] (n_medium / n_outside)"),
    ('"Marble" ior 0.05 profile dipole',
     "dipole medium: ior (eta) = 0.05: expected a value in [0.1, 10] (n_medium / n_outside)"),
    ('"Marble" ior 5',
     "dipole: exact profile: ior = 5 is outside the tables' range [1, 2]; use `profile dipole` for this medium"),
    ("sigma_s 1 anisotropy 1.5 sigma_a 0.1", "dipole medium: g.r = 1.5: expected a value in [-1, 1]"),
    # POV's colours are single floats: 1e39 reads as inf (the library's own bound, sigma x
    # mm_per_unit <= 1e100, is beyond what a scene can write)
    ("sigma_s_prime 1e39 sigma_a 0.1 profile dipole", "dipole medium: sigma_s.r = inf: expected a finite value >= 0 (1/mm)"),
    ("sigma_s_prime 1 sigma_a -1e-9", "dipole medium: sigma_a.r = -1e-09: expected a finite value >= 0 (1/mm)"),
]


@pytest.mark.parametrize("body, message", REFUSED)
def test_out_of_range_is_refused_with_the_range(fork, body, message):
    msg = refusal(fork, dipole(body))
    assert message in msg, msg


# ---------------------------------------------------------------- tables


@pytest.fixture(scope="module")
def huge_tables(tmp_path_factory):
    """A 15-degree Lambert table with one value replaced (checksum refreshed)."""
    good = tables.tabulated("lambert rho=0.5", step=15.0).read_bytes()
    off = struct.unpack_from("<I", good, 12)[0]
    d = tmp_path_factory.mktemp("huge")
    paths = {}
    for name, value in [("bound", 1e10), ("above", 1.0000001e10), ("e38", 1e38), ("fltmax", 3.4028235e38)]:
        b = bytearray(good)
        for k in range(0, 30, 3):  # one channel of ten cells, the first one at offset off
            struct.pack_into("<f", b, off + 4 * k, value)
        struct.pack_into("<Q", b, 88, fnv1a64(bytes(b[off:])))
        (d / f"{name}.brdf").write_bytes(bytes(b))
        paths[f"{name}.brdf"] = d / f"{name}.brdf"
    return paths, off


@pytest.mark.parametrize("scale", [1, 1e6])
def test_table_at_the_bound_renders_finite(fork, huge_tables, scale):
    paths, _ = huge_tables
    render_finite(fork, sphere(f'brdf_table {{ "bound.brdf" scale {scale} }}'), files=paths,
                  label=f"table value 1e10, scale {scale}")


@pytest.mark.parametrize("name, found", [("above", "found 1.0000001e+10"), ("e38", "found 9.99999968e+37"),
                                         ("fltmax", "found 3.40282347e+38")])
def test_table_above_the_bound_is_refused_with_the_offset(fork, huge_tables, name, found):
    paths, off = huge_tables
    msg = refusal(fork, sphere(f'brdf_table {{ "{name}.brdf" }}'), files=paths)
    want = (f"brdf_table: {name}.brdf: offset {off}: expected a value <= 1e+10 (1/sr) at theta_i=0 theta_r=0 "
            f"phi=0 deg, channel 0 (larger is a unit or scale error, or damage: brdf_data/README.md), {found}")
    assert want in msg, msg


# ---------------------------------------------------------------- the full grid (slow)

GRID_IOR = [0.1, 0.3, 0.5, 0.8, 1.0, 1.33, 2.0, 2.5, 3.0, 3.87, 4.0, 6.0, 10.0]
GRID_SIGMA = [1e-6, 1e-3, 1.0, 1e3, 1e6]
GRID_SIGMA_A = [1e-6, 1.0, 1e6]
GRID_G = [-0.99, -0.5, 0.0, 0.5, 0.99]


@pytest.mark.slow
def test_full_grid_renders_finite(fork):
    # ior x sigma_s x sigma_a (profile dipole, g 0), then g x sigma (both profiles, ior 1.3) and
    # the exact profile across its ior range: every render 0 NaN, 0 inf.
    bodies = [f"sigma_s_prime {s} sigma_a {a} ior {n} profile dipole"
              for n, s, a in itertools.product(GRID_IOR, GRID_SIGMA, GRID_SIGMA_A)]
    bodies += [f"sigma_s {s} anisotropy {g} sigma_a {a} ior 1.3 {p}"
               for g, s, a, p in itertools.product(GRID_G, GRID_SIGMA, GRID_SIGMA_A, ["profile dipole", ""])]
    bodies += [f'"Marble" ior {n}' for n in (1.0, 1.1, 1.33, 1.5, 1.8, 2.0)]
    jobs = [runner.RenderJob(SCENE.format(obj=dipole(b)), {"width": SIZE, "height": SIZE, "float_exr": True})
            for b in bodies]
    results = runner.render_many(jobs, binary=fork, return_exceptions=True, progress=False)
    bad = []
    for b, r in zip(bodies, results):
        if isinstance(r, Exception):
            bad.append(f"{b}: {r}")
            continue
        nan, inf, neg = int(np.isnan(r.image).sum()), int(np.isinf(r.image).sum()), int((r.image < 0).sum())
        if nan or inf or neg:
            bad.append(f"{b}: {nan} NaN, {inf} inf, {neg} negative")
    print(f"{len(bodies)} renders, {len(bad)} with NaN/inf/negative pixels or errors")
    assert not bad, "\n".join(bad[:20])
    assert len(bodies) == 13 * 5 * 3 + 5 * 5 * 3 * 2 + 6 == 351
