"""make install: the installed fork finds its include files and tables through its installed conf.

Installs into a temporary PREFIX with mk/install.sh (what ``make install`` runs after ``all``
and ``brdf-data``; about 10 s: one file recompiled, the fork relinked), then renders with the
installed binary in an empty directory with an empty HOME and no ``+L``: everything the scene
names must come from PREFIX/etc/povray-brdf/povray.ini.
"""

from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from harness.core import exr
from harness.core.paths import REPO_ROOT

READY = REPO_ROOT / "build" / "brdf_data"

SCENE = """#version 3.7;
#include "colors.inc"
#include "brdf_metals.inc"
#include "dipole_media.inc"
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -7> look_at 0 }
light_source { <-3, 4, -5> color White }
sphere { <-2.2, 0, 0>, 1 finish { brdf_table { "gold.brdf" } } }
sphere { <0, 0, 0>, 1 finish { F_BRDF_Copper_Satin } }
sphere { <2.2, 0, 0>, 1 finish { brdf_table { "only-installed.brdf" } } }
"""


@pytest.fixture(scope="module")
def prefix(tmp_path_factory, fork):
    if not (READY / "gold.brdf").is_file():
        pytest.skip("run make brdf-data first")
    root = tmp_path_factory.mktemp("install")
    pfx = root / "pfx"
    p = subprocess.run(["bash", str(REPO_ROOT / "mk" / "install.sh"), str(REPO_ROOT), str(pfx)],
                       capture_output=True, text=True)
    if p.returncode != 0 and "the fork's build is out of date" in p.stderr:
        pytest.skip(p.stderr.strip())  # sources edited since the last `make`: nothing to install yet
    assert p.returncode == 0, p.stdout + p.stderr
    return pfx


def render(binary, workdir):
    """Render SCENE with ``binary`` in ``workdir`` (empty HOME, no +L); the image and the log."""
    workdir.mkdir(exist_ok=True)
    (workdir / "home").mkdir()
    (workdir / "s.pov").write_text(SCENE)
    env = {"HOME": str(workdir / "home"), "PATH": "/usr/bin:/bin"}
    p = subprocess.run([str(binary), "+Is.pov", "+Os.exr", "+FE32", "-A", "-D", "-V", "-UA", "+W96", "+H32", "+WT1"],
                       cwd=workdir, env=env, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    return exr.read_exr(workdir / "s.exr"), p.stderr


def test_layout(prefix):
    share, etc = prefix / "share" / "povray-brdf", prefix / "etc" / "povray-brdf"
    for f in ("bin/povray-brdf", "bin/brdftool", "etc/povray-brdf/povray.conf", "etc/povray-brdf/povray.ini",
              "share/povray-brdf/include/brdf_metals.inc", "share/povray-brdf/include/colors.inc",
              "share/povray-brdf/brdf_data/gold.brdf", "share/povray-brdf/doc/README.md",
              "share/povray-brdf/doc/shading/MODELS.md", "share/povray-brdf/doc/docs/fitting.md",
              "share/man/man1/povray-brdf.1.gz", "share/man/man1/brdftool.1.gz", "share/man/man1/sstool.1.gz",
              "bin/sstool", "share/povray-brdf/brdf_data/subsurface_profiles.ssp",
              "share/povray-brdf/brdf_data/subsurface_slabs.ssp",
              "share/povray-brdf/brdf_data/subsurface_slabs_forward.ssp"):
        assert (prefix / f).is_file(), f
    for page in ("povray-brdf", "brdftool", "sstool"):  # `man` finds them under PREFIX/share/man
        shown = subprocess.run(["man", "-M", str(prefix / "share" / "man"), page], capture_output=True, text=True,
                               env={"MANWIDTH": "80", "PATH": "/usr/bin:/bin", "MAN_DISABLE_SECCOMP": "1"})
        assert shown.returncode == 0 and shown.stdout.startswith(page.upper()), shown.stderr
    assert not (prefix / "bin" / "povray").exists()  # stock's name stays stock's
    assert f"Library_Path={share}/include" in (etc / "povray.ini").read_text()
    # the fork's tables: searched after the user's folders (patch 0018)
    conf = (etc / "povray.conf").read_text()
    assert f"[Library Paths]\nLibrary_Path={share}/brdf_data" in conf
    assert f"read* = {share}/include" in (etc / "povray.conf").read_text()
    strings = subprocess.run(["strings", str(prefix / "bin" / "povray-brdf")], capture_output=True, text=True).stdout
    assert f"{etc}/povray.conf" in strings.splitlines()
    assert "build/conf" not in strings  # the build tree's conf is not compiled in any more
    out = subprocess.run([str(prefix / "bin" / "brdftool"), "info", str(share / "brdf_data" / "gold.brdf")],
                         capture_output=True, text=True)
    assert out.returncode == 0 and "isotropic" in out.stdout
    out = subprocess.run([str(prefix / "bin" / "sstool"), "info", str(share / "brdf_data" / "subsurface_profiles.ssp")],
                         capture_output=True, text=True)
    assert out.returncode == 0 and "exact subsurface profiles" in out.stdout


def test_installed_binary_renders_with_installed_conf(prefix, fork, tmp_path):
    share = prefix / "share" / "povray-brdf"
    # a table that exists only in the installed tree: found only through the installed povray.conf
    shutil.copy(READY / "lambert-white.brdf", share / "brdf_data" / "only-installed.brdf")
    img, log = render(prefix / "bin" / "povray-brdf", tmp_path / "installed")
    assert "BRDF tables:" in log
    assert np.isfinite(img).all()
    for third in (img[:, :32], img[:, 32:64], img[:, 64:]):  # gold table, copper satin, the extra table
        assert third.max() > 0.05
    # the same pixels as the fork of the build tree, which finds the same files through its
    # build/conf (the extra table sits in its working directory)
    tree = tmp_path / "tree"
    tree.mkdir()
    shutil.copy(READY / "lambert-white.brdf", tree / "only-installed.brdf")
    ref, _ = render(fork.path, tree)
    np.testing.assert_array_equal(img, ref)


def test_uninstall_removes_everything(prefix, tmp_path):
    # uninstall through DESTDIR: the manifest names PREFIX paths, staged under DESTDIR
    dest = tmp_path / "dest"
    (dest / prefix.relative_to("/")).parent.mkdir(parents=True)
    shutil.copytree(prefix, dest / prefix.relative_to("/"), symlinks=True)
    p = subprocess.run(["bash", str(REPO_ROOT / "mk" / "uninstall.sh"), str(prefix), str(dest)],
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    left = sorted(f.name for f in (dest / prefix.relative_to("/")).rglob("*") if f.is_file())
    assert left in ([], ["only-installed.brdf"])  # a file it did not install stays
