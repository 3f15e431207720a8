"""Gonioreflectometer round trip (``harness.reports.gonio``): a 5 deg RGB table rendered on the
virtual gonioreflectometer (FlatSampleScene) at a grid of (theta_i, theta_r, phi) gives back
its stored values at the nodes and their trilinear interpolation between them.

``tests/test_harness_gonio.py`` checks the gonioreflectometer itself on closed forms
(Lambert, POV's phong and specular); this file closes the loop through a table file.
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.reports import gonio

#: float32 pixels and float32 table values: a few float ulps (6e-8 each); measured <= 1e-7.
ROUND_TRIP_TOL = 1.0e-6


def check(points):
    print(gonio.markdown(points))
    for p in points:
        assert np.all(np.isfinite(p.measured)) and np.all(p.measured > 0), p
        assert p.rel_error < ROUND_TRIP_TOL, (p.theta_i, p.theta_r, p.phi, p.measured, p.table)
    off = [p for p in points if not p.on_node]
    # The off-node points do test the interpolation: there the table differs from the model
    # it tabulates by far more than the tolerance (interpolation error at 5 deg).
    assert max(p.table_vs_model for p in off) > 1e3 * ROUND_TRIP_TOL
    # ... and from its nearest node.
    f, _ = gonio.brdf_io.read_brdf(gonio.table_path())
    p = max(off, key=lambda q: q.table_vs_model)
    near = gonio.table_lookup(f, round(p.theta_i / 5) * 5, round(p.theta_r / 5) * 5, round(p.phi / 5) * 5)
    assert np.max(np.abs(p.measured / near - 1.0)) > 1e3 * ROUND_TRIP_TOL


def test_table_round_trip_quick_grid(fork):
    pts = gonio.measure(gonio.QUICK)
    assert len(pts) == len(gonio.QUICK.geometries()) >= 25
    assert any(p.theta_i == 85.0 and p.theta_r == 85.0 and p.phi == 180.0 for p in pts)  # grazing mirror
    check(pts)


@pytest.mark.slow
def test_table_round_trip_full_grid(fork):
    check(gonio.measure(gonio.FULL))


def test_lookup_matches_nodes_and_midpoints():
    f = np.random.default_rng(1).random((19, 19, 37, 3)).astype(np.float32)
    np.testing.assert_array_equal(gonio.table_lookup(f, 30.0, 85.0, 180.0), f[6, 17, 36])
    np.testing.assert_array_equal(gonio.table_lookup(f, 90.0, 0.0, 200.0), f[18, 0, 32])  # phi 200 -> 160
    mid = gonio.table_lookup(f, 2.5, 0.0, 0.0)
    np.testing.assert_allclose(mid, 0.5 * (f[0, 0, 0] + f[1, 0, 0]), rtol=1e-6)
