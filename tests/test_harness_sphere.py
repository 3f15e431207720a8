"""Sphere renders against the closed forms of harness.reference.expect (stock terms, pixel-centre rays).

Tolerances (conftest.py): stock writes half-float EXR, so an exact render has rel-RMSE at
most 2^-11 = 4.88e-4 and every sample within 0.5 half-ulp of the closed form; measured
rel-RMSE 1.9e-4 .. 2.2e-4. The fork writes float32 (+FE32): rel-RMSE <= 1e-5.
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.core import compare, runner
from harness.reference import expect, terms
from harness.core.scenes import DistantLight, SphereScene

SIZE = 96  # even: no pixel centre lies exactly on the silhouette


def check(scene: SphereScene, r, extra_terms=None) -> compare.ErrorStats:
    """Render ``scene`` with renderer ``r`` and assert it matches the closed form."""
    res = runner.render(scene, r.binary, float_exr=r.float_exr)
    if r.float_exr:
        assert res.exr_dtype == np.float32, "fork with +FE32 must write float32 EXR"
    want = expect.expected_image(scene, extra_terms)
    st = compare.compare(res.image, want)
    assert st.n_nan == st.n_inf == st.n_negative == 0, str(st)
    assert st.rel_rmse < r.rel_tol, str(st)
    # every sample within rounding of the stored format (+1e-7 absolute for half subnormals):
    # catches single wrong pixels (silhouette, terminator, cutoffs) that rel-RMSE would average
    bad = np.abs(res.image - want) > r.sample_rel * np.abs(want) + 1e-7
    assert not bad.any(), f"{int(bad.any(axis=2).sum())} pixels off, first at {np.argwhere(bad)[0]}; {st}"
    return st


@pytest.mark.parametrize("theta,phi", [(0, 0), (45, 30), (80, 120), (89, 200)])
def test_diffuse(renderer, theta, phi):
    s = SphereScene(lights=(DistantLight(theta, phi),), finish={"diffuse": 0.6}, width=SIZE, height=SIZE)
    check(s, renderer)


def test_diffuse_coloured_hdr_back_light(renderer):
    """Coloured light and pigment, values above 1 (not clipped), light behind the terminator."""
    s = SphereScene(lights=(DistantLight(120, 45, (3.0, 1.0, 0.25)),), finish={"diffuse": 0.7},
                    pigment=(0.9, 0.6, 0.3), width=SIZE, height=SIZE)
    st = check(s, renderer)
    assert st.mean_ref > 0


@pytest.mark.parametrize("theta,phi,size", [(0, 0, 40), (45, 30, 10), (80, 120, 80), (89, 200, 200)])
def test_phong(renderer, theta, phi, size):
    s = SphereScene(lights=(DistantLight(theta, phi, (1.0, 0.5, 2.0)),),
                    finish={"phong": 0.8, "phong_size": size}, pigment=(0.2, 0.4, 0.6),
                    width=SIZE, height=SIZE)
    check(s, renderer)


@pytest.mark.parametrize("theta,phi,rough", [(0, 0, 0.05), (45, 30, 0.2), (80, 120, 0.01), (89, 200, 0.1)])
def test_specular(renderer, theta, phi, rough):
    s = SphereScene(lights=(DistantLight(theta, phi, (1.0, 0.5, 2.0)),),
                    finish={"specular": 0.7, "roughness": rough}, pigment=(0.2, 0.4, 0.6),
                    width=SIZE, height=SIZE)
    check(s, renderer)


def test_two_lights_all_terms_and_emission(renderer):
    s = SphereScene(lights=(DistantLight(30, 0, (1.0, 1.0, 1.0)), DistantLight(70, 150, (0.5, 0.8, 1.2))),
                    finish={"diffuse": 0.5, "phong": 0.3, "phong_size": 20, "specular": 0.4,
                            "roughness": 0.08, "emission": 0.05, "ambient": 0.1, "brilliance": 1.5},
                    pigment=(0.8, 0.7, 0.6), width=SIZE, height=SIZE)
    check(s, renderer)


def test_lambert_brdf_term_matches_diffuse(renderer):
    """pi f cos with f = rho/pi through the local-frame BRDF path equals POV's diffuse rho."""
    s = SphereScene(lights=(DistantLight(50, 70, (1.0, 0.5, 0.25)),), finish={"diffuse": 0.6},
                    pigment=(0.5, 0.75, 1.0), width=SIZE, height=SIZE)
    term = terms.brdf_term(terms.lambert(0.6), times_pigment=True)
    check(s, renderer, extra_terms={"diffuse": term})


def test_output_is_linear_whatever_file_gamma(stock):
    """POV 3.7 ignores File_Gamma for EXR: same pixels with 2.2 and 1.0, equal to the closed form."""
    s = SphereScene(lights=(DistantLight(45, 30),), finish={"diffuse": 0.6}, width=32, height=32)
    a = runner.render(s, stock, extra_args=["File_Gamma=2.2"]).image
    b = runner.render(s, stock, extra_args=["File_Gamma=1.0"]).image
    assert np.array_equal(a, b)
    assert compare.rel_rmse(a, expect.expected_image(s)) < 5e-4


def test_model_is_sensitive_to_mirroring_and_scale(stock):
    """Negative controls: a mirrored light (phi -> -phi) or diffuse 0.61 must fail the tolerance."""
    s = SphereScene(lights=(DistantLight(45, 30),), finish={"diffuse": 0.6}, width=64, height=64)
    img = runner.render(s, stock).image
    mirrored = SphereScene(lights=(DistantLight(45, -30),), finish={"diffuse": 0.6}, width=64, height=64)
    brighter = SphereScene(lights=(DistantLight(45, 30),), finish={"diffuse": 0.61}, width=64, height=64)
    assert compare.rel_rmse(img, expect.expected_image(s)) < 5e-4
    assert compare.rel_rmse(img, expect.expected_image(mirrored)) > 0.1
    assert compare.rel_rmse(img, expect.expected_image(brighter)) > 0.01


@pytest.mark.slow
def test_sweep_all_terms_with_report(renderer, tmp_path):
    """Sweep of light directions at 256x256, all stock terms at once, with error maps and a report."""
    from harness.core import page
    from harness.core.runner import RenderJob, render_many

    fin = {"diffuse": 0.5, "phong": 0.4, "phong_size": 30, "specular": 0.3, "roughness": 0.04}
    angles = [(0, 0), (20, 300), (40, 45), (60, 135), (75, 225), (85, 10), (100, 90), (135, 180)]
    scenes = [SphereScene(lights=(DistantLight(t, p, (1.0, 0.8, 0.6)),), finish=fin,
                          pigment=(0.6, 0.7, 0.8), width=256, height=256) for t, p in angles]
    results = render_many([RenderJob(s) for s in scenes], binary=renderer.binary,
                          float_exr=renderer.float_exr, max_workers=2, progress=False)
    rows = []
    for (t, p), s, res in zip(angles, scenes, results):
        want = expect.expected_image(s)
        st = compare.compare(res.image, want)
        png = compare.error_map_png(tmp_path / f"err_{t}_{p}.png", res.image, want,
                                    mask=expect.surface_samples(s).mask, title=f"θ={t}° φ={p}°")
        rows.append({"theta": t, "phi": p, "rel_rmse": st.rel_rmse, "max_abs": st.max_abs,
                     "trace_s": res.trace_seconds, "ok": st.rel_rmse < renderer.rel_tol, "error map": png})
    out = page.write_report(tmp_path / "index.html", f"Sphere sweep ({renderer.name})", rows)
    assert out.is_file()
    assert all(r["ok"] for r in rows), rows
