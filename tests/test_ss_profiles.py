"""Exact subsurface profiles (issue 15 part B) against independent references, fast and seeded.

References share no code with the library: Chandrasekhar's closed forms (two methods for H, in
numpy), the harness's own photon migration (:mod:`harness.reference.mc_subsurface`) and the
dipole's closed forms in numpy. The library is reached through ``sstool`` (its tables and its
Monte Carlo) and through renders of the fork. The full grid (alpha' x g x eta, every slab, more
views) is ``tests/test_ss_profiles_grid.py`` (slow) and ``python -m harness.reports.ss_profiles``.

Tolerances are stated in each test before its numbers; every Monte Carlo run is seeded.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from harness.core import runner
from harness.core import sstool as sst
from harness.core.paths import ss_profiles
from harness.reference import dipole_ref, mc_subsurface
from harness.reports import ss_profiles as sp


#: Named tolerances (docs/claims.md reads them). Monte Carlo ones hold together with "within 3
#: standard errors"; the measured values are the seeded runs of the fast suite.
#: The harness simulator's total vs Chandrasekhar (eta 1, isotropic), relative: measured 0.47 %.
MC_TOTAL_TOL = 0.01
#: ... its next-event radiance at mu 1 and 0.5, relative: measured 0.10 % at most.
MC_RADIANCE_TOL = 0.01
#: The exact profile's total vs the simulator, relative: measured 0.41 % at most.
EXACT_TOTAL_TOL = 0.02
#: ... its multiple-scattering Rd(r) in every resolved bin: measured 2.3 % at most.
EXACT_RD_TOL = 0.10
#: The exact profile's multiple-scattering radiance (total x exit factor, uniform light) below the
#: tables' first albedo node (alpha 0.095: Ketchup's green and blue, alpha' 0.067 and 0.02) vs
#: the simulator's, at mu 1 and 0.5, eta 1 and 1.3, relative: measured 0.55 % at most (the
#: reference's own error 0.1-0.3 %); +1.8 ... +6.7 % when the tables held node 0's v / alpha^2.
LOW_ALBEDO_TOL = 0.01
#: The dipole in its band (alpha' 0.99, eta 1): total within (measured 0.57 %) and Rd(r >= 4 mfp')
#: within (measured 21.5 %); out of it (alpha' 0.5, eta 1.5) at least this far off (measured 58 %).
DIPOLE_BAND_TOL = 0.02
DIPOLE_FAR_TOL = 0.25
DIPOLE_OUT_MIN = 0.30
#: A slab rendered at default settings vs Chandrasekhar's radiance (eta 1, isotropic; no noise
#: in the reference): measured 0.14 % at most. Was 2 %, which a 1 % error of the exact
#: profile's table read would pass (issue 19).
SLAB_CHANDRASEKHAR_TOL = 0.005
#: ... vs the simulator's radiance (g 0.5, eta 1.33; the reference's own error 0.34 %):
#: measured 0.14 %.
SLAB_MC_TOL = 0.02


@pytest.fixture(scope="module")
def tables():
    return ss_profiles()


# ---------------------------------------------------------------- the reference itself

def test_h_function_by_two_methods():
    # Explicit integral (Gauss-Legendre in theta) vs the fixed point of the integral equation:
    # 1e-7 (both converged far below).
    for w in (0.3, 0.9, 0.99):
        a = dipole_ref.chandrasekhar_h(np.array([0.1, 0.5, 1.0]), w)
        b = dipole_ref.chandrasekhar_h_iterated(np.array([0.1, 0.5, 1.0]), w)
        np.testing.assert_allclose(a, b, rtol=1e-7)


def test_simulator_matches_chandrasekhar_total_and_radiance():
    # eta = 1, isotropic, normal incidence: total 1 - H(1) sqrt(1 - w); single part w (1 - ln 2)/2;
    # next-event radiance pi L / E = w H(mu) H(1) / (4 (mu + 1)) at mu = 1 and 0.5. Stated: within
    # 3 standard errors and MC_TOTAL_TOL (total), MC_RADIANCE_TOL (radiance).
    for w in (0.5, 0.9):
        # 200 000 photons (about a second): standard errors 0.2-0.35 %, so that a 1 % error of
        # the simulator fails (issue 19; at 20 000 a +1.3 % albedo error passed).
        r = mc_subsurface.simulate(w, 1.0 - w, n_photons=200_000, seed=1,
                                   views=mc_subsurface.view_directions([1.0, 0.5]))
        exact = dipole_ref.plane_albedo_isotropic(w)
        print(f"w {w}: total {r.total:.5f} +- {r.total_err:.5f} vs {exact:.5f}")
        assert abs(r.total - exact) < 3 * r.total_err and abs(r.total / exact - 1) < MC_TOTAL_TOL
        single = w * (1 - math.log(2)) / 2
        assert abs(r.single - single) < 3 * r.single_err
        for i, mu in enumerate((1.0, 0.5)):
            got = r.radiance_single[i] + r.radiance_multiple[i]
            err = math.hypot(r.radiance_single_err[i], r.radiance_multiple_err[i])
            want = dipole_ref.plane_radiance_isotropic(w, mu)
            print(f"   radiance mu {mu}: {got:.5f} +- {err:.5f} vs {want:.5f}")
            assert abs(got - want) < 3 * err and abs(got / want - 1) < MC_RADIANCE_TOL
            assert abs(r.radiance_single[i] - w / (4 * (mu + 1))) < 3 * r.radiance_single_err[i]


def test_simulator_slab_without_absorption_conserves_energy():
    # Every photon leaves a non-absorbing slab: R + T = 1 (ballistic parts included), 0.5 %.
    r = mc_subsurface.simulate(1.0, 0.0, g=0.5, eta=1.33, thickness=1.0, n_photons=20000, seed=2)
    total = r.r_ballistic + r.total + r.t_ballistic + r.t_total
    print(f"R {r.total:.4f} T {r.t_total:.4f} ballistic {r.t_ballistic:.4f} sum {total:.5f}")
    assert abs(total - 1.0) < 0.005
    # unscattered transmission through 1 mfp at normal incidence: e^-1 (1 - F) (1 + F^2 e^-2 + ...)
    f = float(dipole_ref.fresnel_dielectric(1.0, 1 / 1.33))
    want = math.exp(-1) * (1 - f) / (1 - f * f * math.exp(-2))
    assert abs(r.t_ballistic - want) < 0.01


# ---------------------------------------------------------------- the exact profile vs the simulator

@pytest.mark.parametrize("g, eta, ap, photons", [(0.5, 1.33, 0.9, 100_000), (0.0, 1.5, 0.5, 300_000)])
def test_exact_profile_matches_the_simulator(tables, g, eta, ap, photons):
    # Total diffuse reflectance (tables' multiple scattering + exact single scattering) within 2 %;
    # multiple-scattering Rd(r) within 10 % in every bin of [0.1, 31.6] mfp' where the reference's
    # relative error is below 2.5 % (at least 4 such bins).
    row = sp.compare(sp.Case(g, eta, ap), tables=tables, photons=photons, seed=3)
    print(f"{row.case.label()}: total MC {row.mc_total:.4f} +- {row.mc_total_err:.4f}, exact {row.exact_total_err:+.4f}, "
          f"dipole {row.dipole_total_err:+.4f}; Rd(r) exact errors "
          + " ".join(f"{r:.2g}:{e:+.3f}" for r, e in zip(row.rd_radii, row.exact_rd_err)))
    assert abs(row.exact_total_err) < EXACT_TOTAL_TOL
    assert len(row.rd_radii) >= 4
    assert row.exact_rd_max < EXACT_RD_TOL


@pytest.mark.parametrize("eta", [1.0, 1.3])
def test_multiple_scattering_below_the_first_albedo_node(tables, eta):
    # Below the first albedo node the tables are continued linearly in u = -ln(1 - alpha)
    # (ss_profile.cpp, albedo_weights): multiple scattering is alpha^2 D2 (1 + alpha D3/D2 ...)
    # there. pi L / E of multiple scattering toward mu 1 and 0.5 within LOW_ALBEDO_TOL of the
    # simulator's next-event radiance (200 000 photons; they die within a few events).
    alphas, cos = (0.02, 0.067), (1.0, 0.5)
    rows = sst.eval_profile(tables, alphas, eta=eta, cos=cos)
    for ap, row in zip(alphas, rows):
        ref = mc_subsurface.simulate(ap, 1.0 - ap, eta=eta, n_photons=200_000, seed=11,
                                     views=mc_subsurface.view_directions(np.array(cos)))
        for k, mu in enumerate(cos):
            got = row["total"] * row["exit_factor"][k]
            want, err = ref.radiance_multiple[k], ref.radiance_multiple_err[k]
            print(f"alpha' {ap} eta {eta} mu {mu}: tables {got:.5g}, simulator {want:.5g} +- {err / want:.2%}")
            assert abs(got / want - 1) < LOW_ALBEDO_TOL


def test_dipole_holds_only_in_its_band(tables):
    # The dipole is a high-albedo, far-field approximation: at alpha' = 0.99 (eta 1) its total is
    # within 2 % of the simulator and its Rd(r) within 25 % from 4 mfp' on (at 2 mfp' it is ~30 %
    # high: shading/DIPOLE.md); at alpha' = 0.5, eta 1.5 its total is more than 30 % off while the
    # exact profile is within 2 %.
    hi = sp.compare(sp.Case(0.0, 1.0, 0.99), tables=tables, photons=30_000, seed=4)
    far = [e for r, e in zip(hi.rd_radii, hi.dipole_rd_err) if r >= 4 and e == e]
    print(f"alpha' 0.99: dipole total {hi.dipole_total_err:+.4f}, Rd(r >= 4) {far}")
    assert abs(hi.dipole_total_err) < DIPOLE_BAND_TOL
    assert far and max(abs(e) for e in far) < DIPOLE_FAR_TOL
    lo = sp.compare(sp.Case(0.0, 1.5, 0.5), tables=tables, photons=100_000, seed=5)
    print(f"alpha' 0.5, eta 1.5: dipole total {lo.dipole_total_err:+.4f}, exact {lo.exact_total_err:+.4f}")
    assert lo.dipole_total_err > DIPOLE_OUT_MIN
    assert abs(lo.exact_total_err) < EXACT_TOTAL_TOL


# ---------------------------------------------------------------- renders at default settings

@pytest.mark.parametrize("ap", [0.5, 0.9, 0.99])
def test_slab_renders_chandrasekhar_at_default_settings(ap):
    # eta = 1, isotropic, lit at normal incidence: the rendered pixel (pi L for irradiance 1) within
    # SLAB_CHANDRASEKHAR_TOL of w H(mu) H(1) / (4 (mu + 1)) at normal view and at 60 degrees.
    case = sp.Case(0.0, 1.0, ap)
    for mu in (1.0, 0.5):
        px = sp.render_slab(case, cos_view=mu)
        want = dipole_ref.plane_radiance_isotropic(ap, mu)
        print(f"alpha' {ap} view cos {mu}: {px:.5f} vs {want:.5f} ({px / want - 1:+.4f})")
        assert abs(px / want - 1) < SLAB_CHANDRASEKHAR_TOL


def test_slab_renders_the_simulator_at_default_settings():
    # g 0.5, eta 1.33, alpha' 0.9: the pixel within 2 % of the simulator's next-event radiance
    # (times the entering Fresnel factor) at normal view and at 60 degrees.
    row = sp.compare(sp.Case(0.5, 1.33, 0.9), tables=ss_profiles(), photons=60_000, seed=6)
    for i, mu in enumerate(sp.VIEWS):
        want, err = sp.expected_pixel(row, i)
        px = sp.render_slab(row.case, cos_view=mu)
        print(f"view cos {mu}: {px:.5f} vs {want:.5f} +- {err:.5f} ({px / want - 1:+.4f})")
        assert abs(px / want - 1) < SLAB_MC_TOL


def test_profile_dipole_counts_single_scattering_once():
    # `profile dipole`: Jensen's Rd stands for single and multiple scattering, so by default the
    # pixel is Ft(1)^2 Rd (no single-scattering BRDF); `single_scatter on` adds exactly the BRDF.
    case = sp.Case(0.0, 1.3, 0.9)
    dip = dipole_ref.Dipole(0.9, 0.1, 1.3)
    ft = 1 - float(dipole_ref.fresnel_dielectric(1.0, 1.3))
    px = sp.render_slab(case, extra="profile dipole")
    np.testing.assert_allclose(px, ft * ft * dip.rd_total(), rtol=2e-4)
    both = sp.render_slab(case, extra="profile dipole single_scatter on")
    n = np.array([0.0, 0.0, 1.0])
    single = math.pi * float(dipole_ref.single_scatter_brdf(n, n, 0.9, 0.0, 1.3))
    np.testing.assert_allclose(both - px, single, rtol=2e-4)
    # and the exact profile with single scattering off is its multiple part alone
    exact = sp.render_slab(case)
    multi = sp.render_slab(case, extra="single_scatter off")
    np.testing.assert_allclose(exact - multi, single, rtol=2e-4)


# ---------------------------------------------------------------- scene errors and warnings

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location <0, 0, -5> look_at 0 }}
light_source {{ <2, 5, -3> rgb 1 }}
sphere {{ 0, 1
  finish {{ dipole {{ {body} }} }} }}
"""


@pytest.mark.parametrize("body, message", [
    ('"Marble" profile foo', "dipole: profile must be exact or dipole"),
    ('"Marble" ior 2.5', "ior = 2.5 is outside the tables' range [1, "),
    ('"Marble" ior 2.5', "use `profile dipole` for this medium"),
])
def test_profile_errors_name_the_line(body, message):
    with pytest.raises(runner.RenderError) as e:
        runner.render(SCENE.format(body=body), "fork", width=8, height=8)
    assert message in str(e.value)
    assert e.value.line == 6


def test_g_beyond_the_tables_warns_and_renders():
    r = runner.render(SCENE.format(body="sigma_s 2 anisotropy 0.99 sigma_a 0.01 ior 1.33"), "fork", width=8, height=8,
                      float_exr=True)
    assert np.isfinite(r.image).all()
    notes = [w for w in r.warnings if "outside the exact profile's tables" in w]
    print(notes)
    assert len(notes) == 1 and "g = 0.99 (r, g, b) is outside the exact profile's tables [0, " in notes[0]
    ok = runner.render(SCENE.format(body="sigma_s 2 anisotropy 0.99 sigma_a 0.01 ior 2.5 profile dipole"), "fork",
                       width=8, height=8)
    assert not any("outside the exact profile" in w for w in ok.warnings)


# ---------------------------------------------------------------- slabs (library, phase-2 groundwork)

@pytest.fixture(scope="module")
def slab_tables(tmp_path_factory):
    path = tmp_path_factory.mktemp("slabs") / "slabs.ssp"
    log = sst.build(path, g=[0.0], eta=[1.33], thickness=[1.0, 4.0], photons=40000, short_photons=200000, threads=2)
    print(log)
    return path


@pytest.mark.parametrize("d", [1.0, 4.0])
def test_slab_totals_match_the_simulator(slab_tables, d):
    # Reflectance and transmittance of a slab d mfp thick (g 0, eta 1.33, normal incidence),
    # ballistic + single + multiple, from the library's slab tables: within 5 % of the harness's
    # simulator (where the quantity is above 1e-3; 100 000 reference photons: the unscattered
    # transmission through 4 mfp, e^-4, is then known to 1.5 %).
    for ap in (0.5, 0.9, 0.99):
        ref = mc_subsurface.simulate(ap, 1 - ap, g=0.0, eta=1.33, thickness=d, n_photons=100000, seed=7)
        r = sst.eval_profile(slab_tables, [ap], eta=1.33, thickness=d, face="r")[0]
        t = sst.eval_profile(slab_tables, [ap], eta=1.33, thickness=d, face="t")[0]
        lib_r = r["ballistic"] + r["single"] + r["total"]
        lib_t = t["ballistic"] + t["single"] + t["total"]
        mc_r = ref.r_ballistic + ref.total
        mc_t = ref.t_ballistic + ref.t_total
        print(f"d {d} alpha' {ap}: R {lib_r:.4f} vs {mc_r:.4f}, T {lib_t:.4f} vs {mc_t:.4f}")
        for lib, mc in ((lib_r, mc_r), (lib_t, mc_t)):
            if mc > 1e-3:
                assert abs(lib / mc - 1) < 0.05
