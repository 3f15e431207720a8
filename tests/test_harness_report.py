"""harness.reports.report: the finish report's tables and plots, on synthetic
numbers (no renders; ``make report`` renders)."""

from __future__ import annotations

import json

import numpy as np

from harness.reports import report


def entries(tmp_path):
    m = tmp_path / "m.png"
    m.write_bytes(b"\x89PNG\r\n\x1a\n")
    out = [{"kind": "model", "label": "lambert", "spec": "lambert rho=0.6", "errors": [2e-8] * 4,
            "rel_rmse": 2e-8, "map": m, "ratio": 1.1, "ratio_min": 1.0, "ratio_max": 1.2}]
    for mat in ("a (x)", "b (y)"):
        for step in (0.5, 1.0, 2.0, 5.0):
            for interp in ("nearest", "trilinear"):
                out.append({"kind": "table", "label": f"{mat}, {step:g}° {interp}", "material": mat,
                            "step": step, "interp": interp, "rel_rmse": 1e-4 * step ** 2,
                            "max_rel_bright": 1e-3 * step, "bytes": 1000, "map": m,
                            "ratio": 1.2 if interp == "trilinear" else None,
                            "ratio_min": 1.2, "ratio_max": 1.2})
    for eb in (0.3, 0.7):
        out.append({"kind": "dipole", "label": f"dipole, error_bound {eb:g}", "error_bound": eb, "rel_rmse": 1e-2,
                    "rms_lit": 9e-3, "max_lit": 3e-2, "nodes": 300.0, "profile": np.zeros(80), "map": m,
                    "ratio": 20.0 / eb, "ratio_min": 19.0, "ratio_max": 21.0})
    out.append({"kind": "stock subsurface", "label": "stock subsurface, samples 25, 5", "error_bound": None,
                "rel_rmse": 0.1, "rms_lit": 0.09, "max_lit": 0.2, "nodes": None, "profile": np.zeros(80),
                "map": m, "ratio": 30.0, "ratio_min": 30.0, "ratio_max": 30.0})
    return out


def test_headline_has_every_finish_once(tmp_path):
    rows = report.headline_rows(entries(tmp_path))
    assert [r["kind"] for r in rows].count("table") == 8  # trilinear only
    assert len(rows) == 1 + 8 + 3
    assert rows[0]["trace / stock phong"] == "1.10 (1.00..1.20)"
    assert rows[1]["trace / stock phong"] == "1.20"  # one round: no range
    assert "| model | lambert | 2.0e-08 |" in report.markdown(entries(tmp_path))


def test_plots_are_pngs(tmp_path):
    e = entries(tmp_path)
    for p in (report.plot_speed_error(e, tmp_path / "s.png"), report.plot_table_steps(e, tmp_path / "t.png"),
              report.plot_dipole(e, 80, tmp_path / "d.png")):
        assert p is not None and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert report.plot_speed_error([], tmp_path / "none.png") is None


def test_layout_plot_is_a_png(tmp_path):
    rows = [{"material": m, "spec": "s", "layout": lay, "resolution": res, "bytes": b, "rel_rmse": e}
            for m in ("a", "b")
            for lay, res, b, e in (("isotropic", "1°", 9.1e6, 1e-2), ("isotropic", "0.5°", 71e6, 3e-3),
                                   ("halfdiff", "90×90×180", 17.5e6, 7e-3), ("halfdiff", "256×128×32", 12.6e6, 9e-4))]
    p = report.plot_layouts(rows, tmp_path / "l.png")
    assert p is not None and p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert report.plot_layouts([], tmp_path / "none.png") is None


def test_jsonable_round_trips(tmp_path):
    d = report.jsonable({"a": np.float32(1.5), "b": np.arange(3), "c": float("nan"), "p": tmp_path, "t": (1, 2)})
    assert json.loads(json.dumps(d, allow_nan=False)) == {"a": 1.5, "b": [0, 1, 2], "c": None, "p": str(tmp_path),
                                                          "t": [1, 2]}


def test_recording_sees_only_its_own_thread(monkeypatch):
    from concurrent.futures import ThreadPoolExecutor
    from harness.core import runner

    monkeypatch.setattr(runner, "render", lambda scene, *a, **kw: f"result {scene}")
    orig = runner.render

    def work(k):
        with report.recording() as seen:
            for i in range(50):
                runner.render(f"{k}-{i}")
        return seen

    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(work, range(4)))
    for k, seen in enumerate(got):
        assert [s for s, _ in seen] == [f"{k}-{i}" for i in range(50)]
    assert runner.render is orig  # unwrapped when the last block ends


def _geometry_rows():
    """walk_bench rows of each scene the report's geometry section draws (synthetic numbers)."""
    xs = list(np.linspace(-4.75, 4.75, 20))
    prof = [list(np.clip((np.array(xs) + 5) / 10, 0, 1))] * 3
    method = lambda err, **kw: {"max_diff": err, "plateau": 0.01, "edge": [0.5] * 3, "seconds": 0.2,
                                "profile": prof, **kw}
    edge = {"scene": "edge", "medium": "Skin1", "eta": 1.3, "g": 0.0, "angle": 45, "xs": xs, "ref_profile": prof,
            "profile": method(0.2), "radial": method(0.03), "walk": method(0.05),
            "auto": method(0.2, chose="profile")}
    img = (np.ones((3, 4, 4)) * 0.3).tolist()
    sm = lambda flux, **kw: {"flux": flux, "rms": 0.1, "seconds": 0.1, "image": img, **kw}
    sphere = {"scene": "sphere", "medium": "Skin1", "eta": 1.0, "g": 0.0, "lengths": 3.0, "ref_image": img,
              "profile": sm(0.06), "radial": sm(0.09), "traced": sm(0.04), "walk": sm(0.01),
              "auto": sm(0.01, chose="walk")}
    ch = {"r_mfp": [1.2, 2.0, 11.0], "rel": [0.1, 0.05, 0.5], "judged": [True, True, False],
          "worst_to_10": 0.1, "worst_to_30": None, "judged_to": 2.0, "ref_noise": [0.01, 0.02, 0.1]}
    rd = {"scene": "rd", "medium": "Skin1", "eta": 1.3, "g": 0.0, "seconds": 0.6, "channels": [ch] * 3}
    return [edge, rd, sphere]


def test_geometry_section_summary_and_plots(tmp_path):
    from harness.reports import walk_bench
    rows = _geometry_rows()
    table = walk_bench.summary(rows)
    # every method of the edge and the sphere once, and the Rd row
    assert len(table) == 4 + 5 + 1
    assert {r["method"] for r in table} >= {"profile (default)", "random_walk", "method auto"}
    auto = [r for r in table if r["method"] == "method auto"]
    assert any("chose the walk" in r["other"] for r in auto) and any("chose the profile" in r["other"] for r in auto)
    assert [r["error"] for r in table if r["scene"].startswith("Rd(r)")] == [0.1]
    for name, fn in (("e.png", walk_bench.plot_edges), ("s.png", walk_bench.plot_spheres), ("r.png", walk_bench.plot_rd)):
        path = fn(rows, tmp_path / name)
        assert path is not None and (tmp_path / name).read_bytes().startswith(b"\x89PNG")
    assert walk_bench.plot_spheres([rows[0]], tmp_path / "none.png") is None  # no sphere with an image
    json.dumps(report.jsonable(rows), allow_nan=False)
