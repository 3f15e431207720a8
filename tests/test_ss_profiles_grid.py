"""The full accuracy grid of the exact subsurface profile (slow; the fast subset is
tests/test_ss_profiles.py, the report ``python -m harness.reports.ss_profiles``).

Stated before measuring, for alpha' in {0.3, 0.5, 0.7, 0.9, 0.99, 0.999} x g in {0, 0.5, 0.9} x
eta in {1, 1.33, 1.5} against the harness's own Monte Carlo (sharing no code with the library):

* total diffuse reflectance (tables' multiple scattering + exact single scattering) within 2 %;
* multiple-scattering Rd(r) within 10 % in every bin of [0.1, 31.6] mfp' where the reference's
  relative error is below 2.5 %;
* the rendered slab at default settings within 2 % of the reference's radiance at normal view
  and at 60 degrees, for alpha' in {0.5, 0.9, 0.99}, g in {0.5, 0.9}, where the reference's own
  error is below 0.6 %;
* slab totals (library tables) within 5 % at d in {0.25, 1, 4, 16} mfp, g in {0, 0.5}.
"""

from __future__ import annotations

import math

import pytest

from harness.core import sstool as sst
from harness.core.paths import ss_profiles
from harness.reference import mc_subsurface
from harness.reports import ss_profiles as sp

pytestmark = pytest.mark.slow

CASES = [(g, eta, ap) for g in sp.GS for eta in sp.ETAS for ap in sp.ALPHAS]


@pytest.mark.parametrize("g, eta, ap", CASES)
def test_exact_profile_grid(g, eta, ap):
    case = sp.Case(g, eta, ap)
    row = sp.compare(case, tables=ss_profiles(), photons=sp.photons_for(case, seconds=15.0), seed=21)
    print(f"{case.label()}: total {row.exact_total_err:+.4f} (MC se {row.mc_total_err / row.mc_total:.4f}); Rd(r) "
          + " ".join(f"{r:.2g}:{e:+.3f}" for r, e in zip(row.rd_radii, row.exact_rd_err)))
    assert abs(row.exact_total_err) < 0.02
    assert row.rd_radii, "no reliable reference bin"
    assert row.exact_rd_max < 0.10


@pytest.mark.parametrize("g, eta, ap", [(g, eta, ap) for g in (0.5, 0.9) for eta in sp.ETAS for ap in (0.5, 0.9, 0.99)])
def test_rendered_slab_grid(g, eta, ap):
    case = sp.Case(g, eta, ap)
    row = sp.compare(case, tables=ss_profiles(), photons=sp.photons_for(case, seconds=20.0), seed=22)
    for i, mu in enumerate(sp.VIEWS):
        want, err = sp.expected_pixel(row, i)
        px = sp.render_slab(case, cos_view=mu)
        print(f"{case.label()} view cos {mu}: {px:.5f} vs {want:.5f} +- {err:.5f} ({px / want - 1:+.4f})")
        if err < 0.006 * want:
            assert abs(px / want - 1) < 0.02


@pytest.fixture(scope="module")
def slab_tables(tmp_path_factory):
    path = tmp_path_factory.mktemp("slabs") / "slabs.ssp"
    sst.build(path, g=[0.0, 0.5], eta=[1.33], thickness=[0.25, 0.5, 1, 2, 4, 8, 16, 32, 64], photons=40000,
              short_photons=200000, threads=2)
    return path


@pytest.mark.parametrize("g", [0.0, 0.5])
@pytest.mark.parametrize("d", [0.25, 1.0, 4.0, 16.0])
def test_slab_totals_grid(slab_tables, g, d):
    # d in mean free paths 1/sigma_t for the simulator; the tables take transport mfp: d (1 - alpha g)
    for ap in (0.5, 0.9, 0.99):
        a = ap / (1 - g + ap * g)
        ref = mc_subsurface.simulate(a, 1 - a, g=g, eta=1.33, thickness=d, n_photons=100000, seed=23)
        d_tr = d * (1 - a * g)
        r = sst.eval_profile(slab_tables, [ap], g=g, eta=1.33, thickness=d_tr, face="r")[0]
        t = sst.eval_profile(slab_tables, [ap], g=g, eta=1.33, thickness=d_tr, face="t")[0]
        lib_r, lib_t = r["ballistic"] + r["single"] + r["total"], t["ballistic"] + t["single"] + t["total"]
        mc_r, mc_t = ref.r_ballistic + ref.total, ref.t_ballistic + ref.t_total
        print(f"g {g} d {d} alpha' {ap}: R {lib_r:.4f} vs {mc_r:.4f}, T {lib_t:.5f} vs {mc_t:.5f}")
        for lib, mc in ((lib_r, mc_r), (lib_t, mc_t)):
            if mc > 1e-3:
                assert abs(lib / mc - 1) < 0.05
