"""The shipped exact slab tables of thin geometry (issue 15; shading/DIPOLE.md 6a and 10) against
the harness's own photon migration (:mod:`harness.reference.mc_subsurface`: numpy, shares no code
with the library's transport Monte Carlo that filled the tables), and the renders that use them
(``profile exact`` on sheets thinner than the slab threshold).

The tables are reached through ``sstool eval`` (ln-d interpolation between their 31 thickness
nodes, as a render does); totals are per unit power entering, all scattering orders (the tables'
multiple-scattering face plus their single-scattering tally), without the unscattered beam. The
fast suite checks three corners of the grid (about 3 s); the whole grid d in {0.25, 1, 4, 16} mfp x
alpha' in {0.5, 0.9, 0.99} x eta in {1.0, 1.33, 1.5} is ``slow``. Every Monte Carlo run is seeded.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from harness.core import runner
from harness.core import sstool as sst
from harness.core.paths import ss_slabs
from harness.reference import dipole_ref, mc_subsurface, volume_ref


@pytest.fixture(scope="module")
def slabs():
    return ss_slabs()


def totals(path, ap, eta, d):
    """(R, T) of the tables: multiple + single scattering, per entering power."""
    r = sst.eval_profile(path, [ap], eta=eta, thickness=d, face="r")[0]
    t = sst.eval_profile(path, [ap], eta=eta, thickness=d, face="t")[0]
    return r["total"] + r["single"], t["total"] + t["single"]


def compare(path, ap, eta, d, photons):
    ref = mc_subsurface.simulate(ap, 1.0 - ap, 0.0, eta, n_photons=photons, seed=7, thickness=d)
    R, T = totals(path, ap, eta, d)
    eR, eT = R / ref.total - 1.0, T / ref.t_total - 1.0 if ref.t_total > 0 else 0.0
    print(f"alpha' {ap} eta {eta} d {d}: R {R:.4f} vs MC {ref.total:.4f} ({100 * eR:+.2f} %), "
          f"T {T:.4f} vs MC {ref.t_total:.4f} ({100 * eT:+.2f} %)")
    return ref, eR, eT


@pytest.mark.parametrize("ap, eta, d", [(0.5, 1.5, 4.0), (0.9, 1.33, 1.0), (0.99, 1.0, 0.25)])
def test_shipped_slab_totals_match_the_simulator(slabs, ap, eta, d):
    # Stated before measuring: within 1.5 % (the goal is 5 %; these corners measured
    # within 0.9 % with the shipped settings, the reference's standard error at 200 000 photons is
    # 0.2-0.6 %), so a 1 % error in the tables or their interpolation shows.
    ref, eR, eT = compare(slabs, ap, eta, d, 200_000)
    assert abs(eR) < 0.015
    assert ref.t_total > 1e-3 and abs(eT) < 0.015


@pytest.mark.slow
def test_shipped_slab_totals_full_grid(slabs):
    # The goal: R and T within 5 % of the simulator over the whole grid, where the
    # quantity is above 1e-3 (T through 16 mfp at alpha' 0.5 and 0.9 is 1e-5 .. 2e-4: noise).
    worst = [0.0, 0.0]
    for ap, eta, d in itertools.product((0.5, 0.9, 0.99), (1.0, 1.33, 1.5), (0.25, 1.0, 4.0, 16.0)):
        ref, eR, eT = compare(slabs, ap, eta, d, 200_000)
        assert abs(eR) < 0.05
        worst[0] = max(worst[0], abs(eR))
        if ref.t_total > 1e-3:
            assert abs(eT) < 0.05
            worst[1] = max(worst[1], abs(eT))
    print(f"worst |R| {100 * worst[0]:.2f} %, |T| {100 * worst[1]:.2f} %")


def test_shipped_slab_file_covers_the_presets(slabs):
    # g 0 (every Jensen preset) at every eta of the half-space file, 1/16 .. 64 mean free paths.
    for eta in (1.0, 1.3, 1.33, 1.5, 2.0):
        for d in (0.0625, 64.0):
            R, T = totals(slabs, 0.9, eta, d)
            assert 0 < R < 1 and 0 <= T < 1
    with pytest.raises(RuntimeError, match="outside the tables"):
        totals(slabs, 0.9, 1.33, 100.0)


# ---------------------------------------------------------------- renders with `profile exact`

SIGMA_S_PRIME, SIGMA_A, ETA = 1.0, 0.05, 1.3
MFP = 1.0 / (SIGMA_S_PRIME + SIGMA_A)
SHEET = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 0, 20> direction <0, 0, -1> right <4, 0, 0> up <0, 4, 0> }}
light_source {{ <0, 0, {light}> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-25, -25, {bottom}>, <25, 25, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ {dipole} }} }} }} }}
"""
EXACT = f"sigma_s_prime {SIGMA_S_PRIME} sigma_a {SIGMA_A} ior {ETA} mm_per_unit 1 profile exact"


def sheet(d, light_z, dipole=EXACT):
    return runner.render(SHEET.format(light=light_z, bottom=-d, dipole=dipole), "fork", width=16, height=16,
                         float_exr=True, threads=2)


def centre(r):
    img = r.image[..., :3].astype(np.float64)
    assert np.isfinite(img).all() and (img >= 0).all()
    return img[4:12, 4:12, 0].mean()


def test_exact_sheet_lit_from_behind_matches_the_simulator():
    # The transmitted radiance at normal view, pi L / E, against volume_ref.sheet (a numpy photon
    # tracer sharing no code with the library, next-event estimates toward the exact view).
    # Stated before measuring: within 5 % (the goal); narrowed to 2 % (a regression band).
    # Measured -1.0 / -0.6 / -1.2 % with the slab's own single scattering at each lookup
    # (2026-12-06). Until then the reference was the harness simulator's radiance within 18
    # degrees of the normal (extra["t_radiance_normal"]): a cone average, 1.1 % above the exact
    # normal at 0.25 mfp, where a thin slab's transmitted light leaves more obliquely.
    for t in (0.25, 1.0, 4.0):
        d = t * MFP
        r = sheet(d, -1000)
        ref = volume_ref.sheet([SIGMA_S_PRIME], [SIGMA_A], 0.0, ETA, d, [0, 0, -1], np.array([0.0, 0.0, 1.0]),
                               n_paths=200_000, seed=3)
        want, got = float(ref.radiance[0]), centre(r)
        print(f"exact sheet {t} mfp lit from behind: pixel {got:.5f}, volume_ref pi L {want:.5f} "
              f"+- {100 * float(ref.radiance_err[0]) / want:.2f} % ({100 * (got / want - 1):+.2f} %)")
        assert abs(got / want - 1) < 0.02
        assert "slab profiles" in r.stderr and "multipole" not in r.stderr


#: A sheet thicker than the slab threshold (the thickness from which its faces reflect as the
#: half-space's within 0.5 %: 14-18 mm here) but still passing light to its other face (T above
#: 1e-4 of R_inf up to 22-26 mm), lit from behind: the transmitted radiance against volume_ref,
#: beyond 4 of the reference's standard errors. Stated before measuring: the issue's 3 %.
#: Measured +3.98 % (+- 1.86) at 18 mm and +0.57 % (+- 3.40) at 22 mm; before 2026-12-06 (second
#: session) such a point was a half-space's: -87.5 % and -88.9 %.
TRANSMIT_BAND_TOL = 0.03


def test_exact_sheet_past_the_slab_threshold_passes_its_back_light():
    # ... with `directional on` (the default since 2026-12-07), whose lookups took the
    # half-space's there until then (a slab lookup does not shift; on a ball that cost the dark
    # side its shifted light): -88 % at 18 mm. A flat sheet now takes the slab's
    # (Subsurface::transmits); and with `directional off`.
    for d in (18.0, 22.0):
        ref = volume_ref.sheet([SIGMA_S_PRIME], [SIGMA_A], 0.0, ETA, d, [0, 0, -1], np.array([0.0, 0.0, 1.0]),
                               n_paths=200_000, seed=3)
        want, err = float(ref.radiance[0]), float(ref.radiance_err[0])
        for extra in ("", " directional off"):
            got = centre(sheet(d, -1000, EXACT + extra))
            print(f"exact sheet {d} mm lit from behind{extra}: pixel {got:.4e}, volume_ref pi L {want:.4e} "
                  f"+- {100 * err / want:.2f} % ({100 * (got / want - 1):+.2f} %)")
            assert abs(got / want - 1) - 4 * err / want < TRANSMIT_BAND_TOL, extra


def test_exact_thin_sheet_reflects_as_the_simulator_says():
    # Lit from the front, single scattering off (the finish's BRDF, not the slab): the pixel
    # against Ft(1) x the simulator's multiple-scattering radiance at normal view (next-event
    # estimator, 200 000 photons). Stated before measuring: within 5 %. Measured -0.97 / -0.27 /
    # -0.47 % (and a 30 mm half-space -0.47 %), narrowed to 2 % (a regression band); -1.73 /
    # -0.97 / -0.65 % on 2026-12-06, before and after that day's slab changes. Before the
    # estimator's two fixes (sigma_t in its attenuation, the far face's reflections of the view's
    # ray) it read -0.2 / -1.6 / -4.2 %, and -4.4 % for the half-space.
    ft1 = 1.0 - float(dipole_ref.fresnel_dielectric(1.0, ETA))
    plain = EXACT + " single_scatter off"
    view = mc_subsurface.view_directions([1.0])
    for t in (0.25, 1.0, 4.0):
        got = centre(sheet(t * MFP, 1000, plain))
        ref = mc_subsurface.simulate(SIGMA_S_PRIME, SIGMA_A, 0.0, ETA, n_photons=200_000, seed=5, thickness=t * MFP,
                                     views=view)
        want = ft1 * ref.radiance_multiple[0]
        print(f"exact sheet {t} mfp lit from the front: pixel {got:.5f}, Ft(1) pi L_MC {want:.5f} "
              f"({100 * (got / want - 1):+.2f} %)")
        assert abs(got / want - 1) < 0.02


def test_exact_thick_object_renders_as_before():
    # 30 mm = 31.5 mean free paths: above the slab threshold, no thickness ray, the image of
    # thin_geometry off bit for bit.
    on = sheet(30.0, 1000)
    off = sheet(30.0, 1000, EXACT + " thin_geometry off")
    assert np.array_equal(on.image, off.image)


def test_medium_outside_the_slab_tables_says_so_once():
    # g 0.5 at ior 1.8: the isotropic slab file holds g 0 only, the forward-scattering one iors
    # to 1.5; the thin sheet falls back to the scaled multipole and the statistics say why for
    # each file, once (two such objects).
    body = "sigma_s 2 anisotropy 0.5 sigma_a 0.05 ior 1.8 mm_per_unit 1 profile exact"
    scene = SHEET.format(light=-1000, bottom=-1.0, dipole=body) + \
        "box { <30, -25, -1>, <80, 25, 0> texture { pigment { rgb 1 } finish { ambient 0 dipole { " + body + " } } } }\n"
    r = runner.render(scene, "fork", width=16, height=16, float_exr=True, threads=2)
    assert np.isfinite(r.image).all() and centre(r) > 0
    lines = r.stderr.splitlines()
    at = [i for i, line in enumerate(lines) if "thin objects with profile exact use the multipole" in line]
    print("\n".join(lines[at[0]:at[0] + 3]) if at else r.stderr[-1500:])
    assert len(at) == 1 and "subsurface_slabs.ssp: g = 0.5 is outside the tables' range [0, 0]" in lines[at[0] + 2]
    assert "subsurface_slabs_forward.ssp: ior = 1.8 is outside the tables' range [1, 1.5]" in lines[at[0] + 3]
    # ... and, the medium scattering forward (g >= 0.5), what that costs and what gets it right
    advice = " ".join(line.strip() for line in lines[at[0] + 4:at[0] + 10])
    assert "forward-scattering" in advice and "`method random_walk`" in advice, advice
