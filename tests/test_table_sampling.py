"""Glossy reflection of a table sampled from its own data (issue 16), rendered by the fork.

White furnace (:mod:`harness.reports.glossy_noise`): a sphere under a uniform sky of radiance 1,
Beckmann m = 0.3 + Smith, F = 1, as a 1 deg folded table and as the analytic model. The
table's expectation is its albedo integrated in numpy from the file
(:mod:`harness.reference.table_albedo`), independent of the C++ table and sampler.

Tolerances, stated before measuring: the table's per-pixel rms at 16 samples no worse than
1.2 x the model's (issue 16: "no worse than the analytic model's"; 20 % for the noise of a
48 x 48 image's rms itself); the mean over the sphere (64 samples) within 0.3 % of the numpy
integral.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from harness.core import runner
from harness.reports import glossy_noise


#: The table's glossy noise (per-pixel rms at 16 rays) relative to the analytic model's, and
#: the table's bias (mean relative error at 64 rays) against the numpy integral of its file.
NOISE_RATIO_TOL = 1.2
TABLE_BIAS_TOL = 3e-3
#: Mean relative error per band of cos(theta_o) (issue 32: 0.1 %).
BAND_BIAS_TOL = 1e-3
#: The table's glossy noise relative to the model's at narrow lobes (issue 32: at or below it).
NARROW_NOISE_RATIO = 1.0


def test_table_glossy_noise_is_no_worse_than_the_model(fork):
    model = glossy_noise.measure("model", 16, size=48)
    table = glossy_noise.measure("table", 16, size=48)
    print(f"16 samples: table rms {100 * table.rms:.2f} % (mean {100 * table.mean:+.3f} %), "
          f"model rms {100 * model.rms:.2f} % (mean {100 * model.mean:+.3f} %)")
    assert table.pixels > 1000
    assert table.rms <= NOISE_RATIO_TOL * model.rms
    assert table.rms < 0.05  # issue 16 measured 28.5 % with the generic sampler


@pytest.mark.parametrize("kind, m", [("table", 0.02), ("table", 0.1), ("halfdiff", 0.02), ("halfdiff", 0.1)])
def test_narrow_lobes_from_a_table_are_no_noisier_than_the_model(fork, kind, m):
    """Issue 32: at m = 0.1 the 1 deg table was 2.1 x the model's noise, the half/difference
    table 2.4 x; each layout's sampler must be at or below the model's (ratio <= 1 at 16 rays;
    measured at 48 x 48: 1 deg table 0.000 % at both (its sampler is the table itself), half/
    difference 0.060 % vs 0.175 % and 0.048 % vs 1.075 %)."""
    spec = glossy_noise.spec_for(m)
    model = glossy_noise.measure("model", 16, size=48, spec=spec)
    table = glossy_noise.measure(kind, 16, size=48, spec=spec)
    print(f"{kind} m={m}: rms {100 * table.rms:.3f} %, model {100 * model.rms:.3f} %")
    assert table.rms <= NARROW_NOISE_RATIO * model.rms


@pytest.mark.parametrize("kind", ["table", "halfdiff"])
def test_glossy_reflection_is_unbiased_in_every_band_of_viewing_angle(fork, kind):
    """Issue 32: the half/difference table was +0.18...+0.22 % at cos theta_o 0.15-0.3; every band
    of cos theta_o within 0.1 % of the numpy integral of the file, both layouts (measured within
    0.03 % at 128 x 128 and 256 rays; at 64 x 64 and 64 rays, 1 deg -0.014 %, half/difference
    +0.046 %, both in the grazing band)."""
    r = glossy_noise.measure(kind, 64, size=64, spec=glossy_noise.spec_for(0.1))
    print(kind, " ".join(f"{100 * b:+.3f}" for b in r.band_bias))
    assert all(np.isfinite(b) for b in r.band_bias)
    assert max(abs(b) for b in r.band_bias) < BAND_BIAS_TOL


def test_table_glossy_reflection_is_unbiased(fork):
    table = glossy_noise.measure("table", 64, size=48)
    print(f"64 samples: table rms {100 * table.rms:.2f} %, mean {100 * table.mean:+.3f} %")
    assert abs(table.mean) < TABLE_BIAS_TOL


def test_sampling_data_is_reported(fork):
    finish, files = glossy_noise.finish_text("table", 4, step=2.0)
    res = runner.render(glossy_noise.FURNACE.format(finish=finish), fork, width=16, height=16, files=files)
    m = re.search(r"BRDF sampling data:\s+(\d+) bytes", res.stderr)
    assert m, res.stderr[-1500:]
    # 2 deg table: 46 theta_o nodes x (45 x 90 cells + 45 rows) x 4 bytes (table_sampler.h)
    per_node = (45 * 90 + 45) * 4
    assert 46 * per_node < int(m[1]) < 46 * per_node + 50000
    plain = runner.render(glossy_noise.FURNACE.format(finish=finish.replace("samples 4", "")), fork,
                          width=16, height=16, files=files)
    assert "BRDF sampling data" not in plain.stderr  # built only for glossy rays


AREA_SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 1, -4> look_at 0 }}
light_source {{ <-3, 5, -4> rgb 1 {area} }}
plane {{ y, -1 pigment {{ rgb 0.5 }} }}
sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ brdf_model {{ "microfacet d=beckmann m=0.2" samples {samples} }} }} }}
"""


@pytest.mark.parametrize("area, samples, warned", [
    ("area_light x, z, 5, 4", 8, True),
    ("", 8, False),
    ("area_light x, z, 5, 4", 0, False),
])
def test_samples_with_area_lights_warn_about_the_cost(fork, area, samples, warned):
    res = runner.render(AREA_SCENE.format(area=area, samples=samples), fork, width=16, height=16)
    # said of the scene as a whole, with no line (tests/test_messages.py): on stderr, not in
    # the located warnings
    text = " ".join(res.stderr.split())
    assert ("Parse Warning: Glossy reflection:" in text) == warned, text
    if warned:
        assert "8 glossy rays" in text and "20 shadow rays" in text and "160" in text, text


#: A measured table's glossy noise against its channel floor (table_albedo.channel_floor: the
#: least spread rays shared by the channels can have where the channels' noise differs):
#: stated before measuring, at most 1.6 x the floor for 16 independent rays.
MERL_FLOOR_RATIO = 1.6
#: ... and at m = 0.02 that floor is at least the model's own noise (at least 1.0): why issue
#: 32's "at or below the model" cannot hold for a MERL table with 2 % noise per bin.
MERL_FLOOR_OVER_MODEL = 1.0


def test_a_noisy_merl_table_is_sampled_near_its_channel_floor(fork):
    """The MERL form of glossy_noise (Beckmann m = 0.02, 2 % noise per bin and channel, converted
    to a half/difference table on MERL's grid), 16 rays at 48 x 48. Measured: rms 0.30 %, floor
    0.22 % (ratio 1.37), model 0.175 % (floor / model 1.24)."""
    spec = glossy_noise.spec_for(0.02)
    merl = glossy_noise.measure("merl", 16, size=48, spec=spec)
    model = glossy_noise.measure("model", 16, size=48, spec=spec)
    floor = glossy_noise.floor("merl", 16, spec)
    print(f"merl rms {100 * merl.rms:.3f} %, floor {100 * floor:.3f} %, model {100 * model.rms:.3f} %")
    assert merl.pixels > 1000
    assert merl.rms <= MERL_FLOOR_RATIO * floor
    assert floor >= MERL_FLOOR_OVER_MODEL * model.rms


def _cells_variance(h: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Each channel's relative variance of f / pdf when cell k is drawn with probability p[k]
    and channel c's integrand has mass h[k, c] (summing to 1): sum h^2 / p - 1, written out."""
    return np.array([sum(h[k, c] ** 2 / p[k] for k in range(len(p)) if p[k] > 0) - 1.0 for c in range(h.shape[1])])


def test_channel_floor_is_the_least_spread_of_any_shared_density():
    """table_albedo.shared_floor against the variance written out: two cells, channel masses
    (1, 1) and (1, 3) give P = (sqrt(5/16), sqrt(13/16)) normalised and spreads 0.2412, 0.2732
    (by hand); no other density has a smaller sum of variances (2000 random ones); channels of
    one shape give 0."""
    from harness.reference.table_albedo import shared_floor

    g = np.array([[1.0, 1.0], [1.0, 3.0]])
    spread, p = shared_floor(g)
    want_p = np.array([np.sqrt(5 / 16), np.sqrt(13 / 16)])
    want_p /= want_p.sum()
    assert np.allclose(p, want_p, rtol=1e-12)
    assert np.allclose(spread, [0.2412, 0.2732], atol=1e-4)
    h = g / g.sum(axis=0)
    assert np.allclose(spread ** 2, _cells_variance(h, want_p), rtol=1e-12)
    rng = np.random.default_rng(7)
    g = rng.uniform(0.1, 1.0, (12, 3))
    h = g / g.sum(axis=0)
    best = (shared_floor(g)[0] ** 2).sum()
    for _ in range(2000):
        q = rng.dirichlet(np.ones(12))
        assert _cells_variance(h, q).sum() >= best - 1e-12
    assert np.all(shared_floor(np.outer(rng.uniform(0.1, 1.0, 12), [1.0, 2.0, 5.0]))[0] < 1e-7)
