"""The half/difference table layout (layout 3, ``brdf_data/README.md``) rendered by the fork.

Narrow Beckmann lobes against the independent numpy model (:mod:`harness.reference.models`) on
the harness's sphere (lights at 0, 45 and 80 deg), with the 1 deg isotropic table beside them;
a synthetic MERL file converted without resampling; ``brdftool info/check/resample`` and the
numpy reader on a layout-3 file; the fork's lookup against the README's interpolation rule
written in numpy (:func:`harness.core.brdf_io.halfdiff_lookup`).

Tolerances, stated before measuring: the issue's goal, 0.3 % rel-RMSE at <= 18 MB per RGB table,
for every narrow lobe; float32 rounding (1e-6 relative) where a value is only carried through.
"""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from harness.core import brdf_io, runner, tables
from harness.core.compare import rel_rmse
from harness.core.paths import brdftool
from harness.core.scenes import DistantLight, FlatSampleScene, SphereScene
from harness.reference.expect import expected_image, measured_brdf, surface_samples
from harness.tools import merl_synth

LIGHTS = (DistantLight(0.0), DistantLight(45.0, 30.0), DistantLight(80.0, 200.0))
GOAL = 3e-3            # rel-RMSE against the model
#: The worst pixel's error relative to the image's peak (issue 19: a per-pixel bound beside the
#: image-wide one). Measured 8.3e-4 for m = 0.02 gold.
PIXEL_GOAL = 3e-3
MAX_BYTES = 18_000_000  # per RGB table
DIELECTRIC = "f=dielectric eta=1.5 kd=0.3 rho_s=0.7"
CONDUCTOR = "f=conductor n=0.143,0.374,1.442 k=3.983,2.385,1.603"  # gold


def spec(m: float, fresnel: str) -> str:
    return f"microfacet d=beckmann m={m} {fresnel}"


def sphere(finish, size):
    return SphereScene(lights=LIGHTS, finish=finish, width=size, height=size)


def table_error(fork, path, model_spec, size, worst=False):
    """rel-RMSE of the table's sphere against the numpy model's (and, with ``worst``, the worst
    pixel's error relative to the peak)."""
    want = expected_image(sphere({"brdf_model": {"spec": model_spec}}, size))
    img = runner.render(sphere({"brdf_table": {"file": "t.brdf"}}, size), fork, float_exr=True,
                        files={"t.brdf": path}).image
    mask = surface_samples(sphere({}, size)).mask
    err = rel_rmse(img, want, mask)
    return (err, float(np.abs(img - want)[mask].max() / want[mask].max())) if worst else err


def test_narrowest_lobe_meets_the_goal_where_the_1deg_table_does_not(fork):
    # Beckmann m = 0.02 gold, the hardest of the six, at the default nodes (256 x 128 x 32).
    s = spec(0.02, CONDUCTOR)
    hd = tables.tabulated_halfdiff(s)
    iso = tables.tabulated(s, step=1.0, fold=True)
    (e_hd, px_hd), e_iso = table_error(fork, hd, s, 96, worst=True), table_error(fork, iso, s, 96)
    print(f"m=0.02 gold: halfdiff {e_hd:.2e}, worst pixel {px_hd:.2e} of the peak ({hd.stat().st_size / 1e6:.1f} MB), "
          f"1 deg {e_iso:.2e} ({iso.stat().st_size / 1e6:.1f} MB)")
    assert hd.stat().st_size <= MAX_BYTES
    assert e_hd < GOAL
    assert px_hd < PIXEL_GOAL
    assert e_iso > 10 * GOAL  # the reason for the layout: 5 % at 1 deg


@pytest.mark.slow
@pytest.mark.parametrize("fresnel", [DIELECTRIC, CONDUCTOR], ids=["dielectric", "conductor"])
@pytest.mark.parametrize("m", [0.02, 0.05, 0.1])
def test_narrow_lobes_meet_the_goal(fork, m, fresnel):
    s = spec(m, fresnel)
    hd = tables.tabulated_halfdiff(s)
    iso = tables.tabulated(s, step=1.0, fold=True)
    e_hd, e_iso = table_error(fork, hd, s, 160), table_error(fork, iso, s, 160)
    print(f"m={m} {fresnel.split()[0]}: halfdiff {e_hd:.2e}, 1 deg {e_iso:.2e}")
    assert hd.stat().st_size <= MAX_BYTES
    assert e_hd < GOAL


@pytest.fixture(scope="module")
def synthetic_merl(tmp_path_factory):
    """merl_synth's file (standard 90 x 90 x 180, bin centres), its raw samples and its model."""
    d = tmp_path_factory.mktemp("merl")
    kd, rho_s, m, f0 = [0.25, 0.08, 0.05], 0.7, 0.2, 0.05
    f = merl_synth.synthetic_brdf(kd, rho_s, m, f0)
    binary = merl_synth.write_merl(d / "s.binary", f)
    out = d / "s.brdf"
    p = subprocess.run([str(brdftool()), "convert", str(binary), "--layout", "halfdiff", "-o", str(out)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    model = f"microfacet d=beckmann g=smith m={m} f=schlick f0={f0} kd={','.join(map(str, kd))} rho_s={rho_s}"
    return binary, out, model


def test_merl_bins_come_back_exactly(synthetic_merl):
    binary, out, _ = synthetic_merl
    raw = np.frombuffer(binary.read_bytes()[12:], dtype="<f8").reshape(3, 90, 90, 180)
    scaled = raw * merl_synth.SCALE[:, None, None, None]  # MERL's channel scales undone
    t = brdf_io.read_table(out)
    assert t.layout == brdf_io.HALFDIFF and t.f.shape == (90, 90, 180, 3)
    assert out.stat().st_size - 12 * 90 * 90 * 180 < 1024  # 17.5 MB of payload
    data = raw[0] >= 0
    for c in range(3):
        np.testing.assert_array_equal(t.f[..., c][data], scaled[c][data].astype(np.float32))
    # below-horizon bins (-1 in the file) were filled, finite and >= 0, and are not "no data"
    assert (~data).sum() > 0
    assert np.isfinite(t.f).all() and (t.f >= 0).all()
    assert t.nodata_filled == 0


def test_merl_renders_like_its_model(fork, synthetic_merl):
    _, out, model = synthetic_merl
    err = table_error(fork, out, model, 96)
    print(f"synthetic MERL as halfdiff: rel-RMSE {err:.2e} against {model}")
    assert err < GOAL


def test_fork_lookup_is_the_readme_interpolation(fork):
    # One direction pair per render (the virtual gonioreflectometer): the fork's value against
    # numpy's reading of the README, off the nodes, next to the theta_h pole and across the phi_d
    # wrap. A coarse table so that interpolation, not the lobe, decides the value.
    path = tables.tabulated_halfdiff(spec(0.3, CONDUCTOR), (12, 10, 8))
    f = brdf_io.read_table(path).f
    for ti, tr, phi in ((35.0, 52.0, 150.0), (40.0, 40.2, 179.7), (20.0, 61.0, 12.0)):
        sc = FlatSampleScene(theta_i_deg=ti, theta_r_deg=tr, phi_deg=phi, finish={"brdf_table": {"file": "t.brdf"}})
        got = measured_brdf(runner.render(sc, fork, float_exr=True, files={"t.brdf": path}).image, sc)
        want = brdf_io.halfdiff_lookup(f, sc.wi()[None], sc.wo()[None])[0]
        np.testing.assert_allclose(got, want, rtol=1e-5, err_msg=f"{ti} {tr} {phi}")


def run_tool(*args):
    return subprocess.run([str(brdftool()), *map(str, args)], capture_output=True, text=True)


def test_brdftool_reads_and_resamples_the_layout(tmp_path):
    hd = tables.tabulated_halfdiff("microfacet d=beckmann m=0.1 f=dielectric eta=1.5 kd=0.3 rho_s=0.7", (64, 32, 16))
    info = run_tool("info", hd)
    assert info.returncode == 0, info.stderr
    assert "half/difference 64x32x16" in info.stdout and "theta_i= 45.0" in info.stdout
    check = run_tool("check", hd)
    assert check.returncode == 0, check.stdout
    assert "reciprocity: exact (half/difference layout" in check.stdout
    # to the 1 deg layout and back to MERL's grid; a half/difference table is never folded
    iso, back = tmp_path / "iso.brdf", tmp_path / "back.brdf"
    assert run_tool("resample", hd, "-o", iso, "--layout", "iso", "--step", "1").returncode == 0
    assert brdf_io.read_table(iso).f.shape == (91, 91, 181, 3)
    p = run_tool("resample", iso, "-o", back, "--layout", "halfdiff", "--nodes", "90,90,180")
    assert p.returncode == 0, p.stderr
    assert brdf_io.read_table(back).f.shape == (90, 90, 180, 3)
    for bad in (["resample", hd, "-o", back, "--layout", "halfdiff", "--nodes", "64,32,16", "--fold"],
                ["tabulate", "lambert", "--layout", "halfdiff", "--step", "1", "-o", back],
                ["tabulate", "lambert", "--layout", "halfdiff", "--nodes", "1,4,4", "-o", back]):
        p = run_tool(*bad)
        assert p.returncode == 2 and "usage" in p.stderr, p.stderr
