"""sstool build says what it does in words a user can act on (issue 33): by default one line per
Monte Carlo run (run k/N, g, thickness, time); the fit diagnostics that meant nothing to a
user ("tail amplitude flux/fit worst 4708108650703185120329728.000") only with --verbose,
explained once."""

from __future__ import annotations

import re
import subprocess

from harness.core.paths import REPO_ROOT

SSTOOL = REPO_ROOT / "build" / "shading" / "sstool"
# A tiny grid: one g, two thicknesses (a slab file), one eta, few photons: about a second.
TINY = ["--g", "0", "--eta", "1.3", "--thickness", "1,4", "--photons", "3000", "--short-photons", "3000",
        "--albedos", "4", "--threads", "2"]


def build(tmp_path, *extra):
    p = subprocess.run([str(SSTOOL), "build", "-o", str(tmp_path / "t.ssp"), *TINY, *extra], capture_output=True,
                       text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return p.stderr.splitlines()


def test_build_prints_one_plain_line_per_run(tmp_path):
    lines = build(tmp_path)
    runs = [ln for ln in lines if ln.startswith("sstool build: run ")]
    assert len(runs) == 2, lines
    for k, (ln, d) in enumerate(zip(runs, ("1", "4")), 1):
        assert re.fullmatch(rf"sstool build: run {k}/2: g=0 d={d} \(1 etas\): [\d.]+ s, [\d.e+]+ flights, \d+ threads", ln), ln
    text = "\n".join(lines)
    for jargon in ("tail amplitude", "deconvolution", "flux mismatch", "angle fit"):
        assert jargon not in text, text
    assert re.fullmatch(r"sstool build: .*t\.ssp: \d+ bytes, \d+ records, [\d.]+ s", lines[-1]), lines[-1]


def test_verbose_explains_the_diagnostics_once(tmp_path):
    lines = build(tmp_path, "--verbose")
    text = "\n".join(lines)
    assert text.count("--verbose diagnostics") == 1
    assert "are noise" in text and "carry no light a render can" in text and "tests/test_ss_slabs.py" in text
    runs = [ln for ln in lines if ln.startswith("sstool build: run ")]
    assert len(runs) == 2 and all("tail amplitude flux/fit worst" in ln for ln in runs), runs


def test_quiet_prints_only_the_result(tmp_path):
    lines = build(tmp_path, "--quiet")
    assert len(lines) == 1 and lines[0].startswith("sstool build: "), lines
