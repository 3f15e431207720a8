"""Thin geometry of the dipole finish (issue 15): light through sheets thinner than the
distance light diffuses, rendered by the fork and compared with the diffusion theory of a slab
computed independently in the harness (:func:`harness.reference.dipole_ref.slab_totals`, a
linear solve of the 1-D diffusion equation, not the library's image sums or closed form).

A wide sheet of thickness d (a box), parallel light at normal incidence, orthographic camera
looking straight at it, default sampling. POV's pixel is pi L = Ft(cos_o) M, and M = E_t x total
for a wide sheet: E_t = Ft(1) (light colour 1 at normal incidence), so the centre pixel is
Ft(1)^2 T(d) lit from behind and Ft(1)^2 R(d) lit from the front (plus single scattering, off
here where it would light the front face).
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.core import runner
from harness.reference import dipole_ref

#: sigma_s' = 1/mm, sigma_a = 0.05/mm, eta 1.3 (harness.reports.dipole_bench's medium): transport
#: mean free path 1/1.05 mm, diffusion length 2.5 mm.
SIGMA_S_PRIME, SIGMA_A, ETA = 1.0, 0.05, 1.3
MFP = 1.0 / (SIGMA_S_PRIME + SIGMA_A)

SHEET = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ orthographic location <0, 0, 20> direction <0, 0, -1> right <4, 0, 0> up <0, 4, 0> }}
light_source {{ <0, 0, {light}> rgb 1 parallel point_at <0, 0, 0> }}
box {{ <-25, -25, {bottom}>, <25, 25, 0>
  texture {{ pigment {{ rgb 1 }} finish {{ ambient 0 dipole {{ {dipole} }} }} }} }}
"""
DIPOLE = f"sigma_s_prime {SIGMA_S_PRIME} sigma_a {SIGMA_A} ior {ETA} mm_per_unit 1 profile dipole"


def sheet(fork, d, light_z, dipole=DIPOLE):
    return runner.render(SHEET.format(light=light_z, bottom=-d, dipole=dipole), fork, width=16, height=16,
                         float_exr=True, threads=2)


def centre(r):
    img = r.image[..., :3].astype(np.float64)
    assert np.isfinite(img).all() and (img >= 0).all()
    return img[4:12, 4:12, 0].mean()


def ft2():
    return (1.0 - float(dipole_ref.fresnel_dielectric(1.0, ETA))) ** 2


def test_sheet_lit_from_behind_transmits_the_slab_total(fork):
    ch = dipole_ref.Dipole(SIGMA_S_PRIME, SIGMA_A, ETA)
    for t in (0.25, 1.0, 4.0):
        d = t * MFP
        r = sheet(fork, d, -1000)
        want = ft2() * dipole_ref.slab_totals(ch, d)[1]
        got = centre(r)
        print(f"sheet {t} mfp lit from behind: pixel {got:.5f}, diffusion {want:.5f} ({100 * (got / want - 1):+.2f} %)")
        # tolerance stated before measuring: 3 % (the thickness is rounded to a node 2.2 % apart,
        # which moves T by < 1 %; sample quadrature < 0.5 % in the library test)
        assert abs(got / want - 1) < 0.03
        assert "slab profiles" in r.stderr and "Dipole thin geometry: 1 object" in r.stderr


def test_thin_sheet_reflects_less_than_a_thick_one(fork):
    ch = dipole_ref.Dipole(SIGMA_S_PRIME, SIGMA_A, ETA)
    plain = DIPOLE + " single_scatter off"
    thick = centre(sheet(fork, 30.0, 1000, plain))
    assert abs(thick / (ft2() * ch.rd_total()) - 1) < 0.01
    for t in (0.25, 1.0, 4.0):
        thin = centre(sheet(fork, t * MFP, 1000, plain))
        want = dipole_ref.slab_totals(ch, t * MFP)[0] / ch.rd_total()
        print(f"sheet {t} mfp lit from the front: thin / thick {thin / thick:.4f}, diffusion {want:.4f}")
        assert abs((thin / thick) / want - 1) < 0.03
    # without thin geometry (the half-space everywhere) a 1 mfp sheet reflects like a thick one
    off = centre(sheet(fork, MFP, 1000, plain + " thin_geometry off"))
    print(f"sheet 1 mfp lit from the front, thin_geometry off: off / thick {off / thick:.4f}")
    assert off / thick > 0.97


def test_thick_object_renders_as_before(fork):
    # 30 mm = 31.5 mean free paths: above the slab threshold, so not a single thickness ray is
    # shot at a shading point and the image is the one without thin geometry, bit for bit.
    on = sheet(fork, 30.0, 1000)
    off = sheet(fork, 30.0, 1000, DIPOLE + " thin_geometry off")
    assert np.array_equal(on.image, off.image)
    assert "thin geometry" not in on.stderr


@pytest.mark.slow
def test_multipole_totals_against_monte_carlo_at_high_albedo():
    # The diffusion theory the finish uses for slabs against the harness Monte Carlo (isotropic,
    # all scattering orders, per entering power), where diffusion holds: alpha' = 0.99. Measured
    # first (shading/DIPOLE.md 6a table, 20000 photons): worst |R| 3.7 %, |T| 3.0 % for
    # d <= 4 mfp, T -6.3 % at 16 mfp (T ~ 0.035 there). Bounds: 5 %, and 8 % for T at 16 mfp.
    # At low albedo the multipole is 10-140 % off (the table): no bound is claimed there.
    from harness.reference import mc_subsurface
    for eta in (1.0, 1.33, 1.5):
        for t in (0.25, 1.0, 4.0, 16.0):
            r = mc_subsurface.simulate(0.99, 0.01, 0.0, eta, n_photons=20000, seed=7, thickness=t)
            R, T = dipole_ref.slab_totals(dipole_ref.Dipole(0.99, 0.01, eta), t)
            print(f"eta {eta} d {t}: R {R:.4f} vs MC {r.total:.4f}, T {T:.4f} vs MC {r.t_total:.4f}")
            assert abs(R / r.total - 1) < 0.05
            assert abs(T / r.t_total - 1) < (0.08 if t > 8 else 0.05)
