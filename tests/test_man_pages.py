"""The man pages (docs/man/*.1, installed by make install): valid roff without warnings, the
fork's version, and every brdftool command and option that `brdftool help` lists."""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from harness.core.paths import REPO_ROOT, brdftool

PAGES = {name: REPO_ROOT / "docs" / "man" / f"{name}.1" for name in ("povray-brdf", "brdftool", "sstool")}


def plain(page: str) -> str:
    """Roff source with its escapes for '-' undone, as a reader sees the words."""
    return page.replace("\\-", "-").replace("\\&", "")


@pytest.mark.parametrize("name", sorted(PAGES))
def test_page_renders_without_warnings(name):
    if not shutil.which("groff"):
        pytest.fail("groff is missing: `make deps` installs groff-base")
    p = subprocess.run(["groff", "-man", "-Tutf8", "-ww", "-z", str(PAGES[name])], capture_output=True, text=True)
    assert p.returncode == 0 and p.stderr == "", p.stderr
    version = (REPO_ROOT / "VERSION").read_text().strip()
    th = re.search(r'^\.TH (\S+) 1 "[0-9-]+" "povray-brdf ([^"]+)"', PAGES[name].read_text(), re.MULTILINE)
    assert th and th.group(1) == name.upper() and th.group(2) == version


def test_brdftool_page_has_every_command_and_option():
    page = plain(PAGES["brdftool"].read_text())
    usage = subprocess.run([str(brdftool()), "help"], capture_output=True, text=True).stdout
    commands = [ln.split()[0] for ln in usage.split("commands:\n", 1)[1].splitlines() if ln.strip()]
    assert len(commands) >= 10, usage
    for cmd in commands:
        assert re.search(rf"^\.SS {re.escape(cmd)} ", page, re.MULTILINE), f"no section for {cmd}"
        synopsis = subprocess.run([str(brdftool()), "help", cmd], capture_output=True, text=True).stdout.splitlines()[0]
        for opt in sorted(set(re.findall(r"--[a-z][a-z-]*", synopsis))):
            assert opt in page, f"brdftool {cmd} {opt} is not in docs/man/brdftool.1"
    for words in ("--version", "help", "at least once a second", "--quiet",
                  "trace time relative to stock POV-Ray's", "Reciprocity"):
        assert words in page, words


def test_povray_brdf_page_states_the_permissions():
    page = plain(PAGES["povray-brdf"].read_text())
    for words in ("FILES AND PERMISSIONS", "~/.povray/3.7/povray.conf", "read* = \"/srv/materials\"",
                  "%TMPDIR%", "%HOME%", "the folder of the scene being rendered", "+FE32", "brdf_table", "dipole"):
        assert words in page, words
