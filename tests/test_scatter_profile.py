"""sigma_a and sigma_s' from a measured profile file (brdf-scatter-fit PROFILE --eta ETA): a Monte
Carlo profile written by the harness's simulator is recovered within the interval the tool
states; units are converted; an EXR line works; bad files get clear errors."""

from __future__ import annotations

import math
import re
import subprocess
import sys

import numpy as np
import pytest

from harness.core import exr
from harness.core.paths import REPO_ROOT
from harness.tools import scatter_fit

FIT = [str(REPO_ROOT / ".venv" / "bin" / "brdf-scatter-fit")]


def fit_cli(*args, cwd=None):
    return subprocess.run([*FIT, *map(str, args)], capture_output=True, text=True, cwd=cwd, timeout=300)


def intervals(out: str) -> dict[str, tuple[float, float, float]]:
    got = {}
    for key, label in (("sigma_a", r"sigma_a "), ("sigma_s_prime", r"sigma_s'")):
        m = re.search(rf"^{label} = ([0-9.e+-]+) 1/mm   95 % interval ([0-9.e+-]+) \.\. ([0-9.e+-]+) 1/mm", out,
                      re.MULTILINE)
        assert m, out
        got[key] = tuple(float(x) for x in m.groups())
    return got


@pytest.fixture(scope="module")
def mc_profile(tmp_path_factory):
    """sigma_s' = 1/mm, sigma_a = 0.03/mm (alpha' = 0.971, between the calibration's nodes),
    eta 1.3, 40000 photons, a seed the calibration did not use (about 3 s)."""
    d = tmp_path_factory.mktemp("profile")
    p = subprocess.run([sys.executable, "-m", "harness.reference.mc_subsurface", "--profile", "1.0", "0.03", "--eta",
                        "1.3", "--photons", "40000", "--seed", "5", "-o", d / "mc.csv", "-q"], capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return d / "mc.csv"


def test_monte_carlo_profile_is_recovered_within_the_stated_interval(mc_profile):
    p = fit_cli(mc_profile, "--eta", "1.3")
    assert p.returncode == 0, p.stderr
    iv = intervals(p.stdout)
    for key, truth in (("sigma_a", 0.03), ("sigma_s_prime", 1.0)):
        v, lo, hi = iv[key]
        assert lo <= truth <= hi, (key, truth, iv[key], p.stdout)
        assert (hi - lo) / 2 < 0.3 * v, (key, iv[key])  # an interval that says something
    assert "dipole model +-" in p.stdout and "Rd in 1/mm^2 (absolute), with standard errors" in p.stdout
    assert re.search(r"^finish \{ dipole \{ sigma_s_prime [0-9.]+ sigma_a [0-9.]+ ior 1\.3 profile dipole \} \}", p.stdout, re.MULTILINE)


def test_units_are_converted(mc_profile, tmp_path):
    """The same profile in cm (and Rd per cm^2) gives the same coefficients in 1/mm."""
    lines = mc_profile.read_text().splitlines()
    out = [ln for ln in lines if ln.startswith("#")]
    out.append("r_inner [cm], r_outer [cm], Rd [1/cm^2], Rd_err [1/cm^2]")
    for ln in lines:
        if ln[:1].isdigit():
            a, b, v, e = (float(x) for x in ln.split(","))
            out.append(f"{a / 10!r}, {b / 10!r}, {v * 100!r}, {e * 100!r}")
    (tmp_path / "cm.csv").write_text("\n".join(out) + "\n")
    mm, cm = fit_cli(mc_profile, "--eta", "1.3"), fit_cli(tmp_path / "cm.csv", "--eta", "1.3")
    assert mm.returncode == 0 and cm.returncode == 0, cm.stderr
    a, b = intervals(mm.stdout), intervals(cm.stdout)
    for key in a:
        assert a[key] == pytest.approx(b[key], rel=1e-6), (a, b)


def test_a_line_of_an_image_in_arbitrary_units(tmp_path):
    """A glow image whose row through the entry point is the dipole's profile (the dipole's own
    coefficients: no model error) times 37 in camera units, with 2 % noise."""
    sa, ssp, eta, px = 0.02, 1.0, 1.3, 0.1
    x = np.arange(401) + 0.5
    r = np.abs(x - 200.5) * px
    rd = scatter_fit.dipole_profile(sa, ssp, eta, np.maximum(r, px / 2))
    rng = np.random.default_rng(3)
    img = np.zeros((21, 401, 3))
    img[10] = (37.0 * rd * (1 + 0.02 * rng.standard_normal(r.size)))[:, None]
    exr.write_exr(tmp_path / "glow.exr", img)
    p = fit_cli(tmp_path / "glow.exr", "--eta", "1.3", "--pixel-size", px, "--units", "mm")
    assert p.returncode == 0, p.stderr
    assert "row 10, centre x = 200.5 px" in p.stdout and "arbitrary units (the amplitude is fitted" in p.stdout
    iv = intervals(p.stdout)
    assert iv["sigma_a"][1] <= sa <= iv["sigma_a"][2] and iv["sigma_s_prime"][1] <= ssp <= iv["sigma_s_prime"][2], iv
    assert abs(iv["sigma_a"][0] / sa - 1) < 0.1 and abs(iv["sigma_s_prime"][0] / ssp - 1) < 0.1, iv


GOOD = "radius [mm], Rd [1/mm^2]\n" + "".join(f"{r:g}, {math.exp(-r)}\n" for r in (0.5, 1, 2, 3, 4, 5, 6))


@pytest.mark.parametrize("text, extra, message", [
    (GOOD.replace(" [mm]", ""), (), "line 1: the radius column 'radius' names no unit: write 'radius [mm]'"),
    (GOOD.replace("3, ", "x3, "), (), "line 5, column 1 (radius): 'x3' is not a number"),
    (GOOD.replace("4, ", "4, 1, "), (), "line 6: expected 2 values, found 3"),
    (GOOD.replace("6, ", "0.7, "), (), "the radii must increase"),
    ("radius [mm], Rd [1/mm^2]\n1, 2\n2, 1\n", (), "2 data lines; a fit of two coefficients needs at least 5"),
    (GOOD.replace("[mm]", "[furlong]"), (), "unknown length unit [furlong]"),
    (GOOD, ("--units", "cm"), "the header gives the radius in [mm], --units says cm"),
    (GOOD, ("--row", "3"), "--row applies to an image (.exr) profile only"),
])
def test_bad_profile_files_say_where_and_what(tmp_path, text, extra, message):
    (tmp_path / "p.csv").write_text(text)
    p = fit_cli(tmp_path / "p.csv", "--eta", "1.3", *extra)
    assert p.returncode == 2 and message in p.stderr, p.stderr
    assert "Traceback" not in p.stderr


def test_missing_eta_file_and_image_options(tmp_path):
    (tmp_path / "p.csv").write_text(GOOD)
    p = fit_cli(tmp_path / "p.csv")
    assert p.returncode == 2 and "--eta is required" in p.stderr
    p = fit_cli(tmp_path / "nope.csv", "--eta", "1.3")
    assert p.returncode == 2 and "nope.csv: no such profile file" in p.stderr
    exr.write_exr(tmp_path / "g.exr", np.ones((4, 8, 3)))
    p = fit_cli(tmp_path / "g.exr", "--eta", "1.3")
    assert p.returncode == 2 and "needs --pixel-size" in p.stderr
    p = fit_cli(tmp_path / "g.exr", "--eta", "1.3", "--pixel-size", "0.1", "--units", "mm", "--row", "9")
    assert p.returncode == 2 and "--row 9: the image has rows 0 .. 3" in p.stderr
    (tmp_path / "bad.exr").write_text("no image")
    p = fit_cli(tmp_path / "bad.exr", "--eta", "1.3", "--pixel-size", "0.1", "--units", "mm")
    assert p.returncode == 2 and "bad.exr: not a readable OpenEXR image" in p.stderr
