"""Thin sheets of forward-scattering media at default settings (issue 31): the slab tables of
``subsurface_slabs_forward.ssp`` (g 0 to 0.95, ``make brdf-data``) against
``harness.reference.volume_ref.sheet`` (numpy transport that shares no code with the library).

Before these tables a g 0.9 sheet fell back to the multipole: Skin1 0.25 mfp' thick, seen
through, rendered 1 % of the light (-99 %), its lit side 2.6x too bright at ior 1. The bound,
stated before measuring, is the issue's: 3 % of the reference, plus 4 of its standard errors.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from harness.core import runner
from harness.reference import volume_ref
from harness.reports import walk_bench as wb


BOUND = 0.03
PATHS = 100_000


def views():
    """(side, angle, direction toward the eye): the lit side and seen through, at 0 and 45 degrees."""
    out = []
    for side in ("reflected", "transmitted"):
        for angle in (0, 45):
            t = math.radians(angle)
            out.append((side, angle, np.array([math.sin(t), 0.0, math.cos(t) * (1 if side == "reflected" else -1)])))
    return out


def render_sheet(fork, name: str, eta: float, g: float, d: float, view: np.ndarray, extra: str = ""):
    scene = wb.SHEET.format(bottom=-d, dipole=wb.medium_text(name, g, eta) + extra, **wb.sheet_camera(view, d))
    r = runner.render(scene, fork, width=8, height=8, float_exr=True, threads=2)
    img = r.image[..., :3].astype(np.float64).reshape(-1, 3)
    assert np.isfinite(img).all() and (img >= 0).all(), "NaN or negative pixels"
    return img.mean(0), r.stderr or ""


@pytest.mark.parametrize("name,eta,mfps", [("Skin1", 1.3, 0.25), ("Skin1", 1.0, 1.0), ("Marble", 1.0, 4.0)])
def test_forward_scattering_sheet_matches_exact_transport(fork, name, eta, mfps):
    """Light straight down on the sheet; the pixel from either face at 0 and 45 degrees.
    Marble at 4 mfp' is 40-55 mean free paths at g 0.9, near the tables' last node (64): g 0.9
    arrives from POV as the float 0.899999976, which must read as the node (as the 4-node
    stencil its g 0.95 neighbour's slabs ended at 3.2 mfp' and the render read -12 to -18 %)."""
    g = 0.9
    ss, sa = wb.coefficients(name, g)
    d = mfps * wb.longest_mfp(name)
    vs = views()
    ref = volume_ref.sheet(ss, sa, g, eta, d, [0, 0, 1], np.array([v for _, _, v in vs]), n_paths=PATHS, seed=13)
    worst = excess = 0.0
    for k, (side, angle, view) in enumerate(vs):
        got, stderr = render_sheet(fork, name, eta, g, d, view)
        assert "use the multipole" not in stderr, stderr[-800:]
        want, err = ref.radiance[:, k], ref.radiance_err[:, k]
        for c in range(3):
            if not (err[c] < 0.05 * want[c]):
                continue  # the reference does not resolve it (Skin1's blue seen through)
            rel = got[c] / want[c] - 1
            worst = max(worst, abs(rel))
            excess = max(excess, (abs(got[c] - want[c]) - 4 * err[c]) / want[c])
            print(f"{name} ior {eta} {mfps} mfp' {side:11s} {angle:2d} deg ch {c}: {got[c]:.5f} vs {want[c]:.5f} "
                  f"+- {err[c]:.5f} ({100 * rel:+.2f} %)")
            assert abs(got[c] - want[c]) < BOUND * want[c] + 4 * err[c], (side, angle, c)
    print(f"worst {100 * worst:.2f} %, beyond 4 standard errors {100 * max(excess, 0.0):.2f} %")


def check_seen_through(fork, name: str, eta: float, mfps: float, noise: float) -> None:
    """A g 0.9 sheet `mfps` of its longest channel's transport mean free paths thick, lit
    straight down, seen through at 0 and 45 degrees against 1.5 million reference paths, every
    channel resolved to `noise`; the bound the issue's: 3 % plus 4 standard errors."""
    g = 0.9
    ss, sa = wb.coefficients(name, g)
    d = mfps * wb.longest_mfp(name)
    vs = [v for v in views() if v[0] == "transmitted"]
    ref = volume_ref.sheet(ss, sa, g, eta, d, [0, 0, 1], np.array([v for _, _, v in vs]), n_paths=1_500_000, seed=13)
    for k, (side, angle, view) in enumerate(vs):
        got, _ = render_sheet(fork, name, eta, g, d, view)
        want, err = ref.radiance[:, k], ref.radiance_err[:, k]
        for c in range(3):
            rel = got[c] / want[c] - 1
            print(f"{side} {angle:2d} deg ch {c}: {got[c]:.6f} vs {want[c]:.6f} +- {err[c]:.6f} ({100 * rel:+.2f} %)")
            assert err[c] < noise * want[c], "the reference must resolve every channel"
            assert abs(got[c] - want[c]) < BOUND * want[c] + 4 * err[c], (angle, c)


@pytest.mark.slow
def test_light_through_a_thick_forward_sheet_falls_as_transport_does(fork):
    """Skin1 at g 0.9, ior 1.3, a sheet 4 of red's transport mean free paths thick (green 5.4,
    blue 7.7): light through a slab a few diffusion lengths thick falls as e^(-kappa d), and the
    tables' thickness nodes, sqrt(2) apart, were read linearly in ln d, which put the transmitted
    light low by about 1.5 % x kappa d (blue -10.2 %, green -4.7 % seen straight through, against
    4 million reference paths). Seen through at 0 and 45 degrees, against 1.5 million paths
    (noise 0.3-1.4 %)."""
    check_seen_through(fork, "Skin1", eta=1.3, mfps=4.0, noise=0.02)


@pytest.mark.slow
def test_a_thick_forward_sheet_seen_through_at_a_slant_leaves_as_transport_does(fork):
    """Marble at g 0.9, ior 1.3, a sheet 8 of red's transport mean free paths thick, seen
    through at 0 and 45 degrees: its light leaves with the exit distribution of g 0.9's
    thickest slab (6.4 mfp'), whose transmitted light has scattered hundreds of times. At
    20 000 paths per node that distribution was photon noise (its 45-degree value 3.5 % from
    seed to seed), and the shipped table's read 10 % high: against these 1.5 million
    reference paths (noise 0.4-0.5 %) the render was +7.3 to +8.6 % at 45 degrees and within
    2.8 % straight on. A thick slab's normal-incidence run now takes up to 8 times the paths
    (ProfileBuildSettings::normal_photons): worst +1.9 %."""
    check_seen_through(fork, "Marble", eta=1.3, mfps=8.0, noise=0.01)
