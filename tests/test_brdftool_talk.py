"""brdftool talks: progress on long jobs, short answers that end with the finish line, its
version and help per command, units and words on the numbers it prints (issue 17)."""

from __future__ import annotations

import re
import subprocess
import threading
import time

import pytest

from harness.core import tables
from harness.core.paths import REPO_ROOT, brdftool

from tests.test_fitting import PLASTIC, tool  # one brdftool runner for the tool tests


def test_fit_prints_progress_at_least_every_two_seconds():
    """A Gaussian-lobe conductor fit on a 1 deg table (about 8 CPU-seconds on one thread; the
    real-arithmetic conductor Fresnel made the 2 deg TR fit of before too quick): stderr lines
    arrive at most 2 s apart, from the start to the exit, and say families done and time."""
    path = tables.measured_like(PLASTIC, step=1.0, seed=3)
    cmd = [str(brdftool()), "fit", str(path), "--model", "microfacet d=gaussian g=smith f=conductor", "--threads", "1"]
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stamps: list[tuple[float, str]] = []

    def read() -> None:
        for line in proc.stderr:
            stamps.append((time.monotonic(), line.rstrip("\n")))

    reader = threading.Thread(target=read)
    reader.start()
    out = proc.stdout.read()
    proc.wait(timeout=300)
    reader.join()
    t_end = time.monotonic()
    assert proc.returncode == 0, stamps
    times = [t0] + [t for t, _ in stamps] + [t_end]
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert t_end - t0 > 2.5, "the fit ran too briefly to show progress"
    assert max(gaps) <= 2.0, (gaps, stamps)
    lines = [ln for _, ln in stamps]
    assert re.fullmatch(r"brdftool fit: \d+ fit samples \(0 no-data nodes skipped\), 1 family on 1 thread\(s\)",
                        lines[0]), lines[0]
    progress = [ln for ln in lines[1:-1]]
    assert progress and all(re.fullmatch(r"brdftool fit: 0/1 families, \d+ s elapsed, time left: after the first "
                                         r"family", ln) for ln in progress), progress
    assert re.fullmatch(r"brdftool fit: 1/1 families in \d+\.\d s", lines[-1]), lines[-1]
    assert out.rstrip().splitlines()[-1].startswith("  pov:  finish { brdf_model {")
    quiet = tool("fit", path, "--model", "lambert", "--quiet")
    assert quiet.stderr == ""


def test_fit_of_several_families_is_short_and_ends_with_the_finish():
    path = tables.tabulated("microfacet d=tr m=0.2 kd=0.3 rho_s=0.5", step=10.0)
    p = tool("fit", path, "--model", "microfacet d=tr", "--quiet")  # 8 families, about 1 s
    lines = p.stdout.rstrip().splitlines()
    assert len(lines) < 25, p.stdout  # was one 11-line block per family
    assert lines[0] == f"table: {path} (isotropic 10x10x19 (theta 10 deg, phi 10 deg), 3 channels)"
    assert lines[1].startswith("families, best first (error: rel-RMSE of f, cos theta_i weighted; 0.02 = 2 %)")
    assert re.fullmatch(r"  microfacet d=tr g=smith f=none\s+0\.0000\d  \(0\.0 %\)", lines[2]), lines[2]
    assert len([ln for ln in lines if ln.startswith("  microfacet d=tr g=")]) == 8
    assert "best: microfacet d=tr g=smith f=none, error 0.0000" in p.stdout
    assert re.fullmatch(r"  m\s+0\.2\d*( \+- .*)?", lines[lines.index(next(ln for ln in lines if ln.startswith("best:"))) + 1])
    assert re.fullmatch(r'finish \{ brdf_model \{ "microfacet d=tr g=smith m=0\.2\d* f=none kd=0\.3\d* rho_s=0\.5\d*" \} \}',
                        lines[-1]), lines[-1]
    detailed = tool("fit", path, "--model", "microfacet d=tr", "--details", "--quiet").stdout
    assert detailed.count("family: ") == 8  # every family's block
    assert detailed.rstrip().splitlines()[-1] == lines[-1]


@pytest.mark.slow
def test_fit_of_every_family_lists_the_best_ten():
    path = tables.tabulated("ward rho_d=0.3 rho_s=0.2 alpha=0.1", step=15.0)
    out = tool("fit", path, "--quiet").stdout  # about 11 CPU-seconds
    more = re.search(r"\.\.\. (\d+) more \(--details lists every family", out)
    assert more and int(more.group(1)) > 20, out
    ranked = [ln for ln in out.splitlines() if re.match(r"  \S.*\s\d\.\d{5}  \(", ln)]
    assert len(ranked) == 10 and ranked[0].startswith("  ward ")


def test_recommend_states_its_cost_unit_and_ends_with_the_finish(tmp_path):
    path = tables.tabulated("lambert rho=0.4,0.5,0.6", step=10.0)
    p = tool("recommend", path, "--model", "lambert", "--quiet", "--costs", "/dev/null")
    assert "cost: trace time relative to stock POV-Ray's phong highlight on the same scene (1.00 = as fast)" in p.stdout
    assert "cost (x)" in p.stdout
    assert re.search(r"choice: lambert \(error 0\.0000\d = 0\.0 %, cost 1\.00 x stock phong; the table costs "
                     r"1\.25 x\)", p.stdout), p.stdout
    assert p.stdout.rstrip().splitlines()[-1].startswith('finish { brdf_model { "lambert rho=0.4')
    p = subprocess.run([str(brdftool()), "recommend", str(path), "--model", "lambert", "--quiet"], capture_output=True,
                       text=True, env={"BRDF_COSTS": str(tmp_path / "none.txt"), "PATH": "/usr/bin:/bin"})
    assert "from the built-in rough order (no measured costs: `brdf-cost` writes build/costs.txt)" in p.stdout


def test_version_and_help_per_command():
    v = tool("--version").stdout
    version = (REPO_ROOT / "VERSION").read_text().strip()
    assert v.splitlines()[0] == f"brdftool (povray-brdf) {version}"
    assert ".brdf format version 1" in v
    for cmd in ("fit", "recommend", "info", "tabulate"):
        assert tool("help", cmd).stdout == tool(cmd, "--help").stdout
        assert tool("help", cmd).stdout.startswith(f"usage: brdftool {cmd} ")
    bad = tool("help", "fitt", check=False)
    assert bad.returncode == 2 and "unknown command 'fitt'" in bad.stderr
    assert "brdftool help COMMAND" in tool("help").stdout


def test_info_explains_reciprocity_in_words(tmp_path):
    folded = REPO_ROOT / "build" / "brdf_data" / "red-plastic-measured.brdf"
    out = tool("info", folded).stdout
    m = re.search(r"by up to ([0-9.]+) 1/sr, ([0-9.]+) % of the table's largest value \(the description's\n"
                  r"\s+\"rel ([0-9.]+)\"\); the two were averaged", out)
    assert m, out
    assert abs(float(m.group(2)) - 100 * float(m.group(3))) < 0.01
    assert "Measured data is never exactly reciprocal" in out
    # an unfolded measurement: computed from the cells
    path = tables.measured_like("lambert rho=0.5", step=5.0, noise=0.02, seed=2)
    out = tool("info", path).stdout
    m = re.search(r"differ by up to ([0-9.e-]+) 1/sr,\n\s+([0-9.]+) % of the table's largest value \(rel ([0-9.]+)\); "
                  r"rms ([0-9.e-]+) 1/sr", out)
    assert m, out
    assert 0.02 < float(m.group(3)) < 0.3  # a few times the 2 % noise of one sample
    exact = tool("info", tables.tabulated("lambert rho=0.5", step=15.0)).stdout
    assert "differ by up to 0 1/sr" in exact


def test_a_missing_file_is_named_as_missing(tmp_path):
    # was "nosuch.brdf: offset 0: expected a readable file, found No such file or directory" (issue 33)
    for cmd in ("fit", "info", "check", "recommend"):
        p = subprocess.run([str(brdftool()), cmd, "nosuch.brdf"], capture_output=True, text=True, cwd=tmp_path)
        assert p.returncode == 1, (cmd, p.stderr)
        assert p.stderr == f"brdftool {cmd}: nosuch.brdf: no such file\n", p.stderr
    unreadable = tmp_path / "locked.brdf"
    unreadable.write_bytes(b"x")
    unreadable.chmod(0)  # root reads it anyway: run as nobody (setpriv, util-linux)
    p = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", str(brdftool()), "info",
                        str(unreadable)], capture_output=True, text=True)
    assert p.returncode == 1 and p.stderr == f"brdftool info: {unreadable}: not readable (permission denied)\n", p.stderr
