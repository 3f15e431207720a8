"""harness.core.compare, harness.core.exr, harness.reports.report, harness.core.paths: no renders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.core import compare, exr, page, paths


def test_rel_rmse_definition():
    b = np.array([[[1.0, 1.0, 1.0], [3.0, 3.0, 3.0]]])
    a = b + np.array([[[0.1, 0.1, 0.1], [0.0, 0.0, 0.0]]])
    # sqrt(mean(d^2)) / sqrt(mean(b^2)) = sqrt(0.03/6) / sqrt(30/6)
    assert compare.rel_rmse(a, b) == pytest.approx(math.sqrt(0.005) / math.sqrt(5.0), rel=1e-12)
    mask = np.array([[True, False]])
    assert compare.rel_rmse(a, b, mask) == pytest.approx(0.1, rel=1e-12)
    assert compare.max_abs_error(a, b) == pytest.approx(0.1)
    assert compare.max_rel_error(a, b) == pytest.approx(0.1)
    assert math.isnan(compare.rel_rmse(a, np.zeros_like(b)))


def test_max_rel_floor_ignores_near_black():
    b = np.array([1.0, 1e-6])
    a = np.array([1.0, 2e-6])
    assert compare.max_rel_error(a, b) == 0.0
    assert compare.max_rel_error(a, b, rel_floor=0.0) == pytest.approx(1.0)


def test_half_rounding_bound():
    rng = np.random.default_rng(1)
    b = rng.uniform(1e-3, 4.0, size=(32, 32, 3))
    a = b.astype(np.float16).astype(np.float64)
    assert compare.rel_rmse(a, b) <= compare.HALF_REL_EPS
    assert compare.max_half_ulps(a, b) <= 0.5
    assert compare.ulp_half(1.0) == 2.0 ** -10 and compare.ulp_half(1e-6) == 2.0 ** -24


def test_compare_counts_and_worst_pixel():
    b = np.ones((4, 5, 3))
    a = b.copy()
    a[1, 2, 0] = np.nan
    a[3, 4, 1] = -np.inf
    a[0, 0, 2] = -0.5
    st = compare.compare(a, b)
    assert (st.n_nan, st.n_inf, st.n_negative) == (1, 1, 2)
    assert st.worst_pixel in {(1, 2), (3, 4)}
    a2 = b.copy()
    a2[2, 3] = 1.5
    st2 = compare.compare(a2, b)
    assert st2.worst_pixel == (2, 3) and st2.max_abs == pytest.approx(0.5)
    assert "rel-RMSE" in str(st2) and st2.as_dict()["n_samples"] == 60


def test_exr_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    img = rng.uniform(0, 5, size=(7, 9, 3)).astype(np.float32)
    exr.write_exr(tmp_path / "f.exr", img)
    back = exr.read_exr_full(tmp_path / "f.exr")
    assert back.stored_dtype == np.float32 and np.array_equal(back.pixels, img)
    exr.write_exr(tmp_path / "h.exr", img, half=True)
    back = exr.read_exr_full(tmp_path / "h.exr")
    assert back.stored_dtype == np.float16
    assert np.array_equal(back.pixels, img.astype(np.float16).astype(np.float32))
    assert exr.read_exr(tmp_path / "f.exr", dtype=np.float64).dtype == np.float64


def test_pngs_and_report(tmp_path):
    b = np.linspace(0, 1, 48).reshape(4, 4, 3)
    a = b * 1.01
    a[0, 0] = np.nan
    p1 = exr.write_png_preview(tmp_path / "a.png", a, scale=4)
    p2 = compare.error_map_png(tmp_path / "err.png", a, b, title="signed")
    p3 = compare.error_map_png(tmp_path / "rel.png", a, b, mask=b[..., 0] > 0.2, relative=True)
    for p in (p1, p2, p3):
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    out = page.write_report(tmp_path / "rep" / "index.html", "Sphere <diffuse>",
                              [{"case": "θ=45°", "rel_rmse": 2.1e-4, "ok": True, "map": p2},
                               {"case": "θ=89°", "rel_rmse": 0.5, "ok": False}],
                              images=[("relative error", p3)], notes="First.\n\nSecond.")
    html = out.read_text()
    assert "Sphere &lt;diffuse&gt;" in html and "0.00021" in html and "FAIL" in html
    assert 'href="../err.png"' in html and 'src="../rel.png"' in html
    assert html.count("<tr>") == 3 and html.count("<p>") == 2


def test_binary_discovery(monkeypatch, tmp_path):
    monkeypatch.setenv("POVRAY_BRDF", str(tmp_path / "nope"))
    with pytest.raises(paths.BinaryNotFound, match="POVRAY_BRDF"):
        paths.fork_binary()
    fake = tmp_path / "povray-brdf"
    fake.write_text("#!/bin/sh\n")
    fake.chmod(0o755)
    monkeypatch.setenv("POVRAY_BRDF", str(fake))
    assert paths.fork_binary() == paths.Binary(fake, "fork")
    assert paths.resolve_binary(fake).flavour == "fork"
    assert paths.resolve_binary("stock").flavour == "stock"
    monkeypatch.setenv("POVRAY_STOCK", str(tmp_path / "missing"))
    with pytest.raises(paths.BinaryNotFound, match="POVRAY_STOCK"):
        paths.stock_binary()
    assert (paths.repo_root() / "harness" / "core" / "paths.py").is_file()
