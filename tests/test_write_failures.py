"""The renderer on a full disk (patch 0017): an error naming the file, no abort, nothing partial.

Upstream POV-Ray 3.7 (and Debian's stock binary) aborts with SIGABRT on a full disk: the
render state file (``FILE.pov-state``) throws from the message thread; and an image whose
write fails is left truncated in place. The fork writes the image to a temporary name, checks
every byte and the close, and renames it; the render state, when it cannot be written, is
reported once and removed. (An older image of the same name is removed when a render starts,
as upstream does, so a failed render never leaves a stale image that looks like its own.) The tests mount a small tmpfs as the output folder (root only;
skipped with the reason otherwise).
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from pathlib import Path

import pytest

from harness.core import exr

SCENE = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { orthographic location <0, 0, -3> direction z right x * 2 up y * 2 }
light_source { <-3, 4, -5> rgb 1 }
sphere { 0, 1 pigment { granite scale 0.05 } }
"""


@pytest.fixture()
def small_disk():
    """A 96 KiB tmpfs (mounted for this test, unmounted after it)."""
    if os.geteuid() != 0:
        pytest.skip("a full disk needs a tmpfs mount, and mounting needs root (run the tests as root)")
    d = Path(tempfile.mkdtemp(prefix="brdf-full-"))
    p = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=96k", "tmpfs", str(d)], capture_output=True, text=True)
    if p.returncode != 0:
        os.rmdir(d)
        pytest.skip(f"cannot mount a tmpfs here: {p.stderr.strip()}")
    try:
        yield d
    finally:
        subprocess.run(["umount", str(d)], check=False)
        os.rmdir(d)


def _render(fork, cwd: Path, out: Path, size: int, *extra: str) -> subprocess.CompletedProcess:
    (cwd / "s.pov").write_text(SCENE)
    env = {k: v for k, v in os.environ.items() if k not in ("POVINI", "POVINC")}
    return subprocess.run([str(fork.path), "+Is.pov", f"+O{out}", "-A", "-D", "-V", f"+W{size}", f"+H{size}",
                           "+WT1", *extra], cwd=cwd, env=env, capture_output=True, text=True, timeout=120)


def test_full_disk_is_an_error_naming_the_image_and_nothing_stale_or_partial_is_left(fork, small_disk, tmp_path):
    out = small_disk / "o.exr"
    out.write_bytes(b"the older image")  # removed when the render starts (upstream's rule: no stale image)
    p = _render(fork, tmp_path, out, 320, "+FE32")  # granite: ~300 KiB of float EXR > 96 KiB
    assert p.returncode not in (-6, 134), "aborted: " + p.stderr[-1500:]
    assert p.returncode != 0, p.stderr[-1500:]
    assert f"cannot write the image '{out}': No space left on device; nothing was written" in p.stderr, \
        p.stderr[-2000:]
    assert p.stderr.count("cannot write the image") == 1
    assert "terminate called" not in p.stderr
    assert sorted(f.name for f in small_disk.iterdir()) == []  # no image, no .part-*, no .pov-state


def test_a_render_state_that_does_not_fit_is_reported_once_and_removed(fork, small_disk, tmp_path):
    # ~1 KiB per pixel row in the state file; the image (PNG, compressed) is small enough to fit
    (small_disk / "fill").write_bytes(b"\0" * 60 * 1024)
    out = small_disk / "o.png"
    p = _render(fork, tmp_path, out, 96)
    assert p.returncode not in (-6, 134), "aborted: " + p.stderr[-1500:]
    state = small_disk / "o.pov-state"
    msgs = [ln for ln in p.stderr.splitlines() if "cannot write the render state" in ln]
    assert len(msgs) == 1 and f"'{state}': No space left on device" in msgs[0], p.stderr[-2000:]
    assert not state.exists()
    assert not any(f.name.startswith("o.png.part-") for f in small_disk.iterdir())


def test_the_image_is_written_to_a_temporary_name_and_renamed(fork, tmp_path):
    """strace shows where the image's bytes go: a temporary name beside it, then a rename."""
    out = tmp_path / "o.exr"
    log = tmp_path / "trace.txt"
    (tmp_path / "s.pov").write_text(SCENE)
    p = subprocess.run(["strace", "-f", "-qq", "-e", "trace=openat,rename,renameat,renameat2", "-o", str(log),
                        str(fork.path), "+Is.pov", f"+O{out}", "+FE32", "-A", "-D", "-V", "+W32", "+H32", "+WT1"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-1500:]
    trace = log.read_text()
    opened = [ln for ln in trace.splitlines() if "openat(" in ln and str(out) in ln and "O_WRONLY" in ln]
    assert opened and all(f"{out}.part-" in ln for ln in opened), opened   # never opened for writing in place
    assert any("rename" in ln and f"{out}.part-" in ln and f'"{out}"' in ln for ln in trace.splitlines()), trace[-2000:]
    assert exr.read_exr(out).shape[:2] == (32, 32)
    assert not any(".part-" in f.name for f in tmp_path.iterdir())
