"""The light's edges in a subsurface object's samples, as rendered (issue 31).

A half-space of Jensen's marble (blue channel as a grey medium: sigma_s' 3.0, sigma_a 0.0071
/mm, ior 1.3, `mm_per_unit` its transport mean free path, so the scene is in mfp') under a
black plate, lit straight down through a round hole of radius 0.5, `sample_spacing 0.1` (the
walk_bench rd scene).

* The plate ends exactly where the block does. The sample lines' grid used to start at the
  block's bounding box, so with the spacing coarsened out of view (0.8: 112.5 spacings across)
  a row of lines ran down the block's very edge, where the shadow rays graze the plate's edge:
  113 samples of 0.64 square mfp' each were lit, and a view of one quadrant about the hole
  rendered its far pixels up to 2.2x too bright (+39 % averaged at 26-30 mfp'). With a plate
  that overhangs the block the same view is exactly as bright as the centred one.
* The hole holds ~79 sample cells. A cell at its rim was lit or not by its centre alone, so
  the hole's flux (and every pixel around it) moved by several per cent as the grid fell
  (-4.5 % or +1.9 %); the rim's samples now take their cells' mean irradiance.
* A hole smaller than the sample spacing can lie wholly between the samples: the cloud sees no
  light, and nothing glows around the hole (here, 48^2, the mean from 1 to 10 mfp': -100 % at
  a spacing of 2; at 1, the hole's own diameter, +0.04 % against the spacing 0.1). The
  statistics say so.

Tolerances fixed before measuring.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from harness.core import runner

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <{cx}, {cy}, 80> direction <0, 0, -1> right <{w}, 0, 0> up <0, {w}, 0> }}
light_source {{ <0, 0, 1000> rgb 1 parallel point_at <0, 0, 0> }}
difference {{
  box {{ <-{plate}, -{plate}, 0.002>, <{plate}, {plate}, 0.003> }}
  cylinder {{ <{hx}, {hy}, 0>, <{hx}, {hy}, 1>, 0.5 }}
  pigment {{ rgb 0 }} finish {{ ambient 0 diffuse 0 }} no_image
}}
box {{ <-45, -45, -45>, <45, 45, 0> texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{
  sigma_s <3, 3, 3> sigma_a <0.0071, 0.0071, 0.0071> ior 1.3 mm_per_unit 0.3325463071 sample_spacing {spacing} }} }} }} }}
"""

#: The corner view against the same view of a plate that overhangs the block: worst relative
#: difference of a pixel from 10 to 30 mfp' from the hole (before the fix: 1.18, at 26 mfp').
FLUSH_PLATE = 0.01
#: The annulus 2-10 mfp' about the hole, the hole moved by a fraction of the spacing: relative
#: difference of its mean (before the edge means: several per cent).
GRID_OFFSET = 0.005


def _render(n: int, **kw) -> np.ndarray:
    args = dict(cx=0, cy=0, w=20, plate=45, hx=0, hy=0, spacing=0.1)
    args.update(kw)
    r = runner.render(SCENE.format(**args), "fork", width=n, height=n, float_exr=True, threads=2)
    img = r.image[..., 0].astype(np.float64)
    assert np.isfinite(img).all()
    return img


def _radius(n: int, w: float, cx: float, cy: float, hx: float = 0, hy: float = 0) -> np.ndarray:
    """Distance of each pixel's centre from the hole (row 0 at the top, as POV writes it)."""
    px = w / n
    x = cx - w / 2 + (np.arange(n) + 0.5) * px
    y = cy + w / 2 - (np.arange(n) + 0.5) * px
    return np.hypot(x[None, :] - hx, y[:, None] - hy)


def test_a_plate_flush_with_the_blocks_edge_lights_nothing_along_it():
    n = 96
    corner = dict(cx=15, cy=15, w=30)
    flush = _render(n, **corner)
    overhang = _render(n, plate=60, **corner)
    far = (_radius(n, 30, 15, 15) > 10) & (_radius(n, 30, 15, 15) < 30)
    worst = float(np.abs(flush[far] / overhang[far] - 1).max())
    print(f"flush plate against an overhanging one, 10-30 mfp': worst pixel {worst:.2e}")
    assert worst <= FLUSH_PLATE


@pytest.mark.parametrize("offset", [(0.05, 0.0), (0.031, 0.067)])
def test_a_lit_spot_renders_the_same_wherever_the_sample_grid_falls(offset):
    n = 128
    hx, hy = offset
    base = _render(n)
    moved = _render(n, cx=hx, cy=hy, hx=hx, hy=hy)
    ring = lambda img, cx, cy: img[(_radius(n, 20, cx, cy, cx, cy) > 2) & (_radius(n, 20, cx, cy, cx, cy) < 10)].mean()
    rel = float(ring(moved, hx, hy) / ring(base, 0, 0) - 1)
    print(f"hole moved by {offset}: annulus 2-10 mfp' {100 * rel:+.3f} %")
    assert abs(rel) <= GRID_OFFSET


UNRESOLVED = "lit points with no lit sample within 8 spacings"


def test_a_lit_spot_between_the_samples_is_reported():
    # The hole (radius 0.5) sampled every 2 mfp': no sample is lit, the lit pixels are counted
    # and the statistics say what to do; sampled every 1 it is resolved, and nothing is said.
    n = 48
    out = {}
    for spacing in (2, 1):
        r = runner.render(SCENE.format(cx=0, cy=0, w=20, plate=45, hx=0, hy=0, spacing=spacing), "fork", width=n,
                          height=n, float_exr=True, threads=2)
        ring = (_radius(n, 20, 0, 0) > 2) & (_radius(n, 20, 0, 0) < 10)
        out[spacing] = (float(r.image[..., 0][ring].mean()), r.stderr)
        print(f"sample_spacing {spacing}: annulus 2-10 mfp' {out[spacing][0]:.3g}, warned: {UNRESOLVED in r.stderr}")
    glow, log = out[2]
    assert glow == 0 and UNRESOLVED in log and "Give sample_spacing a quarter of the lit" in log
    assert re.search(r"one at <[-0-9.e]+, [-0-9.e]+, [-0-9.e]+>", log)  # a lit point inside the hole
    glow, log = out[1]
    assert glow > 0 and UNRESOLVED not in log
