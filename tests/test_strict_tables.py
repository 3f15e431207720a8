"""1 deg tables, strictly: the fork's lookup against a numpy lookup of the same file, and the
table's image against the model's closed form, each with a per-pixel bound, and the negative
controls that show the bounds have power (issue 19).

References share no code with the library: the table is read by :mod:`harness.core.brdf_io`
and interpolated here in numpy (nodes at k * step, trilinear in (theta_i, theta_r, phi), as
``brdf_data/README.md`` specifies); the model is :mod:`harness.reference.models`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.core import brdf_io, runner, tables
from harness.core.compare import rel_rmse
from harness.core.scenes import DistantLight, SphereScene
from harness.reference import models
from harness.reference.expect import expected_image, surface_samples
from harness.reference.terms import brdf_term

SPEC = "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.7"
LIGHTS = (DistantLight(0.0), DistantLight(45.0, 30.0), DistantLight(80.0, 200.0))
SIZE = 96

#: The fork's trilinear lookup vs numpy's of the same file, per pixel: float32 nodes, the
#: fork's cosine-based angles (acos of float cosines: ~1e-8 rad) and POV's float colours;
#: relative to the pixel, with an absolute floor for the dark limb. Measured 1.5e-7
#: (trilinear) and 1.3e-7 (nearest node).
LOOKUP_PIXEL_REL = 2.0e-6
LOOKUP_FLOOR = 1.0e-4
#: A 1 deg trilinear table of the model vs the model's closed form: rel-RMSE over the sphere
#: (measured 1.34e-5) and the worst pixel relative to the image's peak (measured 4.7e-5).
#: The negative controls below measure: nearest node 1.1e-3 / 4.3e-3, a 5 deg table
#: 3.3e-4 / 1.3e-3, the 1 deg table scaled by 1.002: 2.0e-3 / 2.0e-3.
TABLE_1DEG_RMSE = 5.0e-5
TABLE_1DEG_PIXEL = 5.0e-4


def sphere(finish):
    return SphereScene(lights=LIGHTS, finish=finish, width=SIZE, height=SIZE)


def iso_lookup(path, nearest=False):
    """f(wo, wi) of an isotropic (theta_i, theta_r, phi) table by numpy interpolation."""
    f = brdf_io.read_brdf(path)[0].astype(np.float64)
    ni, nr, nphi, C = f.shape
    step = 90.0 / (ni - 1)
    assert abs(180.0 / (nphi - 1) - step) < 1e-9

    def pos(deg, n):
        x = np.clip(deg / step, 0.0, n - 1)
        if nearest:
            i = np.floor(x + 0.5).astype(int)
            return i, i, np.zeros_like(x)
        i0 = np.minimum(np.floor(x).astype(int), n - 2)
        return i0, i0 + 1, x - i0

    def fn(wo, wi):
        ti = np.degrees(np.arccos(np.clip(wi[:, 2], -1, 1)))
        tr = np.degrees(np.arccos(np.clip(wo[:, 2], -1, 1)))
        pi_, pr = np.arctan2(wi[:, 1], wi[:, 0]), np.arctan2(wo[:, 1], wo[:, 0])
        d = np.abs(np.degrees(pr - pi_)) % 360.0
        phi = np.where(d > 180.0, 360.0 - d, d)
        (a0, a1, ta), (b0, b1, tb), (c0, c1, tc) = pos(ti, ni), pos(tr, nr), pos(phi, nphi)
        out = np.zeros((len(wo), C))
        for a, wa in ((a0, 1 - ta), (a1, ta)):
            for b, wb in ((b0, 1 - tb), (b1, tb)):
                for c, wc in ((c0, 1 - tc), (c1, tc)):
                    out += (wa * wb * wc)[:, None] * f[a, b, c]
        return out
    return fn


def render_table(fork, path, **opts):
    finish = {"brdf_table": {"file": "t.brdf", **opts}}
    return runner.render(sphere(finish), fork, float_exr=True, files={"t.brdf": path}).image


def model_image():
    return expected_image(sphere({"brdf_model": {"spec": SPEC}}))


def pixel_error(img, want, mask):
    """Worst |img - want| over the sphere, relative to the image's peak."""
    return float(np.abs(img - want)[mask].max() / want[mask].max())


@pytest.fixture(scope="module")
def table_1deg():
    return tables.tabulated(SPEC, step=1.0)


@pytest.fixture(scope="module")
def render_1deg(fork, table_1deg):
    return render_table(fork, table_1deg)


@pytest.mark.parametrize("interpolate", [1, 0])
def test_lookup_matches_numpy_interpolation_per_pixel(fork, table_1deg, render_1deg, interpolate):
    img = render_1deg if interpolate else render_table(fork, table_1deg, interpolate=0)
    scene = sphere({"brdf_table": {}})
    want = expected_image(scene, {"brdf_table": brdf_term(iso_lookup(table_1deg, nearest=not interpolate))})
    mask = surface_samples(scene).mask
    rel = np.abs(img - want)[mask] / np.maximum(np.abs(want[mask]), LOOKUP_FLOOR)
    print(f"interpolate {interpolate}: worst pixel rel {rel.max():.2e}")
    assert want[mask].max() > 0.3
    assert rel.max() < LOOKUP_PIXEL_REL
    if interpolate:  # control: the nearest-node reference is far outside the bound
        near = expected_image(scene, {"brdf_table": brdf_term(iso_lookup(table_1deg, nearest=True))})
        assert (np.abs(img - near)[mask] / np.maximum(np.abs(near[mask]), LOOKUP_FLOOR)).max() > 50 * LOOKUP_PIXEL_REL


def test_1deg_table_matches_the_closed_form(render_1deg):
    want = model_image()
    mask = surface_samples(sphere({})).mask
    err, worst = rel_rmse(render_1deg, want, mask), pixel_error(render_1deg, want, mask)
    print(f"1 deg table vs closed form: rel-RMSE {err:.2e}, worst pixel {worst:.2e} of the peak")
    assert err < TABLE_1DEG_RMSE
    assert worst < TABLE_1DEG_PIXEL


@pytest.mark.parametrize("control", ["nearest", "5deg", "scale+0.2%"])
def test_1deg_bound_rejects_what_it_should(fork, table_1deg, control):
    # Negative controls: each of these is a worse table and must fail the 1 deg bounds.
    if control == "nearest":
        img = render_table(fork, table_1deg, interpolate=0)
    elif control == "5deg":
        img = render_table(fork, tables.tabulated(SPEC, step=5.0))
    else:
        img = render_table(fork, table_1deg, scale=1.002)
    want = model_image()
    mask = surface_samples(sphere({})).mask
    err, worst = rel_rmse(img, want, mask), pixel_error(img, want, mask)
    print(f"{control}: rel-RMSE {err:.2e}, worst pixel {worst:.2e}")
    assert err > TABLE_1DEG_RMSE or worst > TABLE_1DEG_PIXEL
    assert err > 2 * TABLE_1DEG_RMSE  # not a near miss
