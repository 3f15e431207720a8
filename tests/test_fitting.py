"""From measurement to material: brdftool fit/recommend/fill, the cost table, sphere sampling
and scattering estimation (docs/fitting.md)."""

from __future__ import annotations

import math
import re
import subprocess

import numpy as np
import pytest

from harness.tools import cost, recommend, scatter_fit, sphere_sampling
from harness.core import tables
from harness.core.brdf_io import read_brdf, write_brdf
from harness.core.paths import brdftool

PLASTIC = "microfacet d=tr m=0.15 f=dielectric eta=1.5 kd=0.5,0.06,0.04 rho_s=0.5"


def tool(*args, check=True):
    p = subprocess.run([str(brdftool()), *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError(f"brdftool {' '.join(map(str, args))}: {p.stderr}")
    return p


def spec_value(spec: str, key: str) -> list[float]:
    m = re.search(rf"\b{key}=([0-9.e,+-]+)", spec)
    assert m, (key, spec)
    return [float(x) for x in m.group(1).split(",")]


# ---------------------------------------------------------------- brdftool fit / recommend

#: brdftool fit on a simulated measurement (5 deg, 2 % noise, 1 % cells missing) of GGX m 0.15
#: on eta 1.5: the recovered roughness (absolute) and index (absolute).
FIT_M_TOL = 0.003
FIT_ETA_TOL = 0.01  # measured 1.6e-3 (m: 7.1e-4)
#: The scattering fit on noisy (3 %) dipole profiles: sigma_a and sigma_s' relative.
SCATTER_FIT_TOL = 0.005  # measured 1.1e-3 at most (seeded noise)
#: The scattering fit's 95 % interval on a Monte Carlo profile: at most this wide (relative
#: half-width; measured 0.21 for sigma_a, 0.19 for sigma_s').
SCATTER_INTERVAL_MAX = 0.3


def test_fit_recovers_a_measured_like_table():
    path = tables.measured_like(PLASTIC, step=5.0, noise=0.02, missing=0.01, seed=4)
    out = tool("fit", path, "--model", "microfacet d=tr g=smith f=dielectric").stdout
    spec = re.search(r"spec: (.*)", out).group(1)
    print(f"fitted: {spec}")
    assert abs(spec_value(spec, "m")[0] - 0.15) < FIT_M_TOL
    assert abs(spec_value(spec, "eta")[0] - 1.5) < FIT_ETA_TOL
    assert np.allclose(spec_value(spec, "kd"), [0.5, 0.06, 0.04], atol=0.01)
    err = float(re.search(r"error: ([0-9.]+)", out).group(1))
    assert err < 0.03  # the 2 % noise itself
    assert f'pov:  finish {{ brdf_model {{ "{spec}" }} }}' in out


def test_fit_tsv_ranks_the_true_family_first():
    path = tables.tabulated("ward rho_d=0.3 rho_s=0.2 alpha=0.1", step=10.0)
    out = tool("fit", path, "--model", "ward", "--tsv", "--quiet").stdout.splitlines()
    assert out[0].split("\t")[:2] == ["family", "error"]
    fam, err, *_ = out[1].split("\t")
    assert fam == "ward" and float(err) < 1e-4
    assert tool("fit", path, "--model", "phong", check=False).returncode == 2


def test_recommend_picks_the_cheapest_within_tolerance(tmp_path):
    path = tables.tabulated("lambert rho=0.4,0.5,0.6", step=10.0)
    costs = tmp_path / "costs.txt"
    costs.write_text("lambert 1.5\noren_nayar 1.01\nward 1.2\ntable 1.3\n")
    out = tool("recommend", path, "--model", "lambert", "--costs", costs, "--tsv").stdout
    assert out.splitlines()[-1].split("\t")[1] == "lambert"
    # Oren-Nayar (sigma = 0 is Lambert) fits too and is cheaper by this file.
    both = subprocess.run([str(brdftool()), "recommend", str(path), "--costs", str(costs)] + ["--model", "oren_nayar"],
                          capture_output=True, text=True).stdout
    assert "choice: oren_nayar" in both
    # Nothing within a tolerance below what a Lambert fits to a glossy table: keep the table.
    glossy = tables.tabulated(PLASTIC, step=10.0)
    out = tool("recommend", glossy, "--model", "lambert", "--tol", "0.01", "--costs", costs).stdout
    assert "choice: keep the table" in out
    assert tool("recommend", glossy, "--costs", tmp_path / "missing.txt", check=False).returncode == 1


def test_recommend_wrapper_renders_image_error():
    path = tables.tabulated("microfacet d=beckmann m=0.3 kd=0.4 rho_s=0.5", step=5.0)
    rows, table_cost, choice = recommend.run_recommend(path, 0.05, None, model="microfacet d=beckmann g=smith")
    assert choice.startswith("microfacet d=beckmann g=smith")
    best = rows[0]
    recommend.image_errors(path, [best], size=48)
    assert best.image_error is not None and best.image_error < 0.01


def test_cost_file_round_trip(tmp_path):
    p = tmp_path / "c.txt"
    p.write_text(cost.format_costs({"lambert": 1.02, "microfacet d=tr": 1.3}, "test"))
    assert cost.read_costs(p) == {"lambert": 1.02, "microfacet d=tr": 1.3}
    assert cost.ensure_costs(p) == p  # present: not measured again


@pytest.mark.slow
def test_cost_measurement_runs():
    c = cost.measure(repeat=1, families=["lambert", "table"])
    assert set(c) == {"lambert", "table"} and all(0.2 < v < 10 for v in c.values())


# ---------------------------------------------------------------- table I/O and fill

def test_write_brdf_with_nodata_then_fill(tmp_path):
    f = np.full((10, 10, 19, 3), 0.5 / math.pi)
    f[3, 4, 5] = np.nan
    f[6, 6, 0:4] = np.nan
    sparse = write_brdf(tmp_path / "s.brdf", f, "test sparse")
    back, desc = read_brdf(sparse, nodata="keep")
    assert desc == "test sparse" and np.isnan(back[3, 4, 5]).all()
    assert "5 no-data cells filled" in tool("fill", sparse, "-o", tmp_path / "f.brdf").stdout
    filled, _ = read_brdf(tmp_path / "f.brdf")
    assert np.allclose(filled, 0.5 / math.pi, rtol=1e-6)
    # fit skips the no-data cells of the sparse table
    out = tool("fit", sparse, "--model", "lambert").stdout
    assert "(5 no-data excluded)" in out and "lambert rho=0.5" in out


# ---------------------------------------------------------------- sphere sampling

def test_extract_samples_inverts_pov_units():
    # A Lambert sphere rendered analytically: pixel = rho cos_i E  ->  f = rho / pi.
    from harness.reference.expect import expected_image, surface_samples
    from harness.core.scenes import DistantLight, SphereScene
    sc = SphereScene(lights=(DistantLight(40.0, 10.0, (2.0, 2.0, 2.0)),), finish={"diffuse": 0.6}, width=32, height=32)
    img = expected_image(sc)
    ss = surface_samples(sc)
    lt = sc.world_lights()[0]
    s = sphere_sampling.extract_samples(img, ss.normal, ss.mask, lt.direction, -sc.camera().ray_direction(), lt.colour)
    assert np.allclose(s.f, 0.6 / math.pi, rtol=1e-9)
    # theta_i, theta_r and phi obey the spherical law of cosines for the fixed 40 deg angle.
    t_i, t_r, ph = (np.radians(a) for a in (s.theta_i, s.theta_r, s.phi))
    cg = np.cos(t_i) * np.cos(t_r) + np.sin(t_i) * np.sin(t_r) * np.cos(ph)
    assert np.allclose(cg, math.cos(math.radians(40.0)), atol=1e-9)


def test_bin_samples_linear_removes_off_centre_bias():
    rng = np.random.default_rng(1)
    ti, tr, ph = rng.uniform(0, 89, 20000), rng.uniform(0, 89, 20000), rng.uniform(0, 180, 20000)
    f = np.stack([0.1 + 0.01 * ti + 0.002 * ph] * 3, axis=1)  # linear in the angles
    t, cov = sphere_sampling.bin_samples(sphere_sampling.Samples(ti, tr, ph, f), step=10.0, reciprocal=False)
    ang_i = np.arange(10)[:, None, None] * 10.0
    ang_p = np.arange(19)[None, None, :] * 10.0
    want = 0.1 + 0.01 * ang_i + 0.002 * ang_p
    ok = cov >= 8
    mean, _ = sphere_sampling.bin_samples(sphere_sampling.Samples(ti, tr, ph, f), step=10.0, reciprocal=False,
                                          linear=False)
    w = np.broadcast_to(want, cov.shape)[ok]
    lin_rms = np.sqrt(np.mean((t[..., 0][ok] - w) ** 2))
    mean_rms = np.sqrt(np.mean((mean[..., 0][ok] - w) ** 2))
    assert lin_rms < 0.3 * mean_rms and lin_rms < 3e-3


def test_sphere_round_trip_small(fork):
    known = tables.tabulated("microfacet d=beckmann m=0.4 kd=0.4 rho_s=0.5", step=1.0)
    rt = sphere_sampling.round_trip(known, [float(t) for t in range(0, 171, 10)], step=10.0, size=48)
    assert rt.coverage > 0.8
    assert rt.covered_error_80 < 0.03
    assert rt.filled_error_80 < 0.05


@pytest.mark.slow
def test_sphere_round_trip_5deg(fork):
    known = tables.tabulated("microfacet d=beckmann m=0.35 f=dielectric eta=1.5 kd=0.4 rho_s=0.6", step=1.0)
    rt = sphere_sampling.round_trip(known, sphere_sampling.DEFAULT_THETAS, step=5.0, size=128)
    assert rt.coverage > 0.95
    assert rt.covered_error_80 < 0.005
    assert rt.covered_error < 0.03


# ---------------------------------------------------------------- scattering estimation

@pytest.mark.parametrize("sa,ss", [(0.02, 1.0), (0.1, 2.0)])
def test_scatter_fit_recovers_dipole_profiles(sa, ss):
    fit, _ = scatter_fit.demo_dipole(sa, ss, eta=1.3, noise=0.03, seed=2, bootstrap=20)
    print(f"sigma_a {fit.sigma_a / sa - 1:+.2e}, sigma_s' {fit.sigma_s_prime / ss - 1:+.2e}")
    assert abs(fit.sigma_a - sa) < 4 * fit.sigma_a_err and abs(fit.sigma_a / sa - 1) < SCATTER_FIT_TOL
    assert abs(fit.sigma_s_prime - ss) < 4 * fit.sigma_s_prime_err and abs(fit.sigma_s_prime / ss - 1) < SCATTER_FIT_TOL
    sd = fit.bootstrap.std(axis=0, ddof=1)  # the bootstrap agrees with the covariance
    assert 0.5 < sd[0] / fit.sigma_a_err < 2 and 0.5 < sd[1] / fit.sigma_s_prime_err < 2
    assert 0.5 < fit.chi2 / fit.dof < 1.5


def test_scatter_fit_free_amplitude_uses_the_shape():
    r = np.geomspace(0.1, 30, 40)
    data = 7.0 * scatter_fit.dipole_profile(0.03, 1.2, 1.4, r)
    fit = scatter_fit.fit_profile(r, data, 1.4, free_amplitude=True)
    assert abs(fit.sigma_a / 0.03 - 1) < 1e-4 and abs(fit.sigma_s_prime / 1.2 - 1) < 1e-4
    assert abs(fit.amplitude / 7.0 - 1) < 1e-4


def test_scatter_fit_monte_carlo_profile():
    # Small and seeded; the dipole itself is ~5 % off the transport solution in the window.
    fit, t = scatter_fit.demo_mc(0.02, 1.0, eta=1.3, n_photons=20000, seed=1)
    assert abs(fit.sigma_a / 0.02 - 1) < 0.25
    assert abs(fit.sigma_s_prime / 1.0 - 1) < 0.25


def test_scatter_fit_interval_covers_the_transport_truth():
    # The documented claim (docs/fitting.md): the 95 % interval (statistics plus the dipole's
    # calibrated model error) of a fit to a Monte Carlo transport profile covers the true
    # coefficients. Measured (seeded): the truth at 0.75 of the half-width for both, which is
    # 21 % of sigma_a and 19 % of sigma_s'. The point estimates alone are 15 % off: the dipole's
    # own error, which is why the interval and not the estimate carries the claim.
    from harness.reference.mc_subsurface import simulate
    sa, ss, eta = 0.02, 1.0, 1.3
    edges = np.concatenate([[0.0], np.geomspace(0.05, 40.0, 41)]) / (sa + ss)
    mc = simulate(ss, sa, g=0.0, eta=eta, n_photons=20000, seed=1, r_edges=edges)
    prof = scatter_fit.Profile("mc", 0.5 * (edges[:-1] + edges[1:]), mc.rd_r, mc.rd_r_err, edges, True, "mm")
    est = scatter_fit.estimate(prof, eta)
    assert est.calibrated
    for which, truth in (("sigma_a", sa), ("sigma_s_prime", ss)):
        v, half, _, _ = est.interval(which)
        print(f"{which}: {v:.4g} +- {half:.3g} (truth {truth}: {abs(v - truth) / half:.2f} half-widths)")
        assert abs(v - truth) < half
        assert half < SCATTER_INTERVAL_MAX * truth
