"""harness.reports.regress: golden-image regression renders catch a changed scene, bless rewrites goldens.

The fast tests work on a copy of one committed scene (model_families: every brdf_model
family, 288x144, well under a second) in a temporary directory; the whole committed suite
(``make regress``) is the slow test at the end.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from harness.reports import regress
from harness.core.paths import REPO_ROOT

SCENE = "model_families"


def copy_scene(dst: Path, name: str = SCENE) -> Path:
    """scenes/regress/NAME.pov, its golden and tolerance, and a one-scene regress.toml in dst."""
    src = regress.SCENES_DIR
    manifest = tomllib.loads((src / "regress.toml").read_text())["scene"][name]
    (dst / "golden").mkdir(parents=True)
    shutil.copy(src / f"{name}.pov", dst)
    for ext in ("exr", "toml"):
        shutil.copy(src / "golden" / f"{name}.{ext}", dst / "golden")
    w, h = manifest["size"]
    (dst / "regress.toml").write_text(f'[scene.{name}]\nsize = [{w}, {h}]\ncovers = "copy for a test"\n')
    return dst / f"{name}.pov"


def summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())["scenes"][0]


@pytest.fixture
def scene_copy(tmp_path, fork):
    return copy_scene(tmp_path / "scenes")


def test_unchanged_copy_passes(scene_copy, tmp_path):
    out = tmp_path / "out"
    assert regress.main(["--scenes-dir", str(scene_copy.parent), "--out", str(out), "-q"]) == 0
    s = summary(out)
    assert s["ok"] and s["status"] == "pass"
    assert s["stats"]["half_ulps"] <= 0.5 and s["stats"]["rel_rmse"] < 4.9e-4  # half rounding only
    html = (out / "index.html").read_text()
    assert "1 of 1 pass" in html
    for img in ("golden.png", "new.png", "diff.png", "new.exr"):
        assert (out / SCENE / img).is_file(), img


def test_broken_scene_exits_nonzero(scene_copy, tmp_path):
    # A small change of one sphere's roughness (m 0.2 -> 0.22 of the microfacet ball).
    text = scene_copy.read_text()
    assert "m=0.2 f=dielectric" in text
    scene_copy.write_text(text.replace("m=0.2 f=dielectric", "m=0.22 f=dielectric"))
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "harness.reports.regress", "--scenes-dir", str(scene_copy.parent),
                           "--out", str(out), "-q"], cwd=REPO_ROOT, capture_output=True, text=True)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    s = summary(out)
    print(proc.stdout)
    assert not s["ok"] and s["status"] == "FAIL"
    assert s["stats"]["half_ulps"] > 1.0 and any(p.startswith("half_ulps") for p in s["problems"])
    assert "FAIL" in (out / "index.html").read_text()


def test_render_error_and_missing_golden_fail(scene_copy, tmp_path):
    d = scene_copy.parent
    scene_copy.write_text(scene_copy.read_text().replace('brdf_model { Spec[I] }', 'brdf_model { Spec[I] samples -1 }'))
    assert regress.main(["--scenes-dir", str(d), "--out", str(tmp_path / "o1"), "-q"]) == 1
    s = summary(tmp_path / "o1")
    assert s["status"] == "error" and "samples must be a whole number" in s["error"]
    shutil.copy(regress.SCENES_DIR / f"{SCENE}.pov", scene_copy)
    (d / "golden" / f"{SCENE}.exr").unlink()
    assert regress.main(["--scenes-dir", str(d), "--out", str(tmp_path / "o2"), "-q"]) == 1
    assert summary(tmp_path / "o2")["status"] == "no golden"


def test_bless_rewrites_golden_keeps_tolerance(scene_copy, tmp_path):
    d = scene_copy.parent
    tol_before = tomllib.loads((d / "golden" / f"{SCENE}.toml").read_text())["tolerance"]
    scene_copy.write_text(scene_copy.read_text().replace("rho=0.7,0.5,0.3", "rho=0.3,0.5,0.7"))
    assert regress.main(["--scenes-dir", str(d), "--out", str(tmp_path / "o1"), "-q", "--bless"]) == 0
    s = summary(tmp_path / "o1")
    assert s["status"] == "changed" and s["problems"][0].startswith("changed: rel_rmse")
    rec = tomllib.loads((d / "golden" / f"{SCENE}.toml").read_text())
    assert rec["tolerance"] == tol_before
    assert rec["golden"]["change"].startswith("changed") and rec["golden"]["size"] == [288, 144]
    assert regress.main(["--scenes-dir", str(d), "--out", str(tmp_path / "o2"), "-q"]) == 0
    # a scene without a tolerance file gets the default one, with its reason
    (d / "golden" / f"{SCENE}.toml").unlink()
    assert regress.main(["--scenes-dir", str(d), "--out", str(tmp_path / "o3"), "-q", "--bless"]) == 0
    rec = tomllib.loads((d / "golden" / f"{SCENE}.toml").read_text())
    assert rec["tolerance"]["reason"] == regress.DEFAULT_REASON and rec["golden"]["change"].startswith("unchanged")


def test_manifest_and_goldens_are_consistent():
    scenes = regress.load_scenes(regress.SCENES_DIR)
    assert len(scenes) >= 8
    total = 0
    for s in scenes:
        gexr, gtoml = regress.golden_paths(regress.SCENES_DIR, s.name)
        assert gexr.is_file() and gtoml.is_file(), s.name
        assert "reason" in tomllib.loads(gtoml.read_text())["tolerance"], s.name
        total += gexr.stat().st_size
    assert total < 2 * 1024 * 1024
    # every new keyword appears in some regression scene
    text = "\n".join(s.pov.read_text() for s in scenes)
    for kw in ("brdf_table", "brdf_model", "interpolate 0", "interpolate 1", "use_color", "scale <",
               "direction", "samples", "dipole {", "sigma_s_prime", "sigma_s <", "anisotropy", "sigma_a",
               "ior", "mm_per_unit", "sample_spacing", "error_bound", "single_scatter", "profile dipole"):
        assert kw in text, kw
    for family in ("lambert", "phong_pov", "blinn_pov", "phong_normalized", "microfacet", "ward",
                   "oren_nayar", "lafortune"):
        assert f'"{family} ' in text, family


@pytest.mark.slow
def test_committed_suite_passes(fork, tmp_path):
    assert regress.main(["--out", str(tmp_path / "out"), "-q"]) == 0
