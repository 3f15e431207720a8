"""Profile tables (``.ssp``) that cannot lie (issue 29).

``sstool build --if-stale`` (what ``make brdf-data`` runs) is the tables' cache: it keeps a file
only when it loads (magic, format version, the checksum of the whole file, every field) and was
built by this generator with the same settings. A tester changed byte 60 of a format-2 file (a
header field outside that format's payload checksum): it loaded and rendered 31-100 % off per
pixel. Here a small table is damaged in each class of byte position (magic, format version, a
header field such as byte 60, an axis, the payload, the checksum itself) and:

* the fork refuses it: a parse error at the finish's line naming the file and an offset, never
  an image;
* ``sstool build --if-stale`` rebuilds it with a warning naming the file, the rebuilt file is
  byte-identical to the undamaged one (the build is seeded and deterministic for any thread
  count), and a render with it equals the undamaged render exactly;
* a file built with other settings (a foreign cache) is rebuilt the same way.

The table: g 0, eta {1.3, 1.4}, 8 albedo nodes, a few thousand photons (about a second).
"""

from __future__ import annotations

import shutil
import struct
import subprocess

import numpy as np
import pytest

from harness.core import runner
from harness.core.paths import sstool

BUILD_ARGS = ["--g", "0", "--eta", "1.3,1.4", "--albedos", "8", "--photons", "3000", "--short-photons", "6000",
              "--seed", "1"]
NAME = "subsurface_profiles.ssp"

SCENE = """#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0, -4> look_at 0 }
light_source { <2, 5, -3> rgb 1 }
sphere { 0, 1 finish { ambient 0 dipole { sigma_s_prime 0.8 sigma_a 0.05 ior 1.3 mm_per_unit 1 thin_geometry off } } }
"""
LINE = 5


def build(path, *extra, threads=1):
    proc = subprocess.run([str(sstool()), "build", "--if-stale", "--quiet", "--threads", str(threads), "-o", str(path),
                           *BUILD_ARGS, *extra], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return "".join(line + "\n" for line in proc.stderr.splitlines() if "warning" in line)  # (not the size line)


def render(fork, table):
    return runner.render(SCENE, fork, width=24, height=24, float_exr=True, files={NAME: table})


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("ssp")
    path = d / "good.ssp"
    log = build(path)
    assert log == ""  # nothing was there: no warning
    return path


@pytest.fixture(scope="module")
def good_render(fork, good):
    img = render(fork, good).image
    assert np.isfinite(img).all() and img.max() > 0.01
    return img


def payload_offset(data: bytes) -> int:
    return struct.unpack_from("<I", data, 12)[0]


# byte position classes: (name, offset in the file, the offset the fork's message names)
CLASSES = [
    ("magic", lambda d: 0, "offset 0: expected the magic"),
    ("format version", lambda d: 8, "offset 8: expected format version 6"),
    ("payload offset field", lambda d: 12, "offset 24: expected the file's checksum"),
    ("generator version", lambda d: 32, "offset 24: expected the file's checksum"),
    ("byte 60 (radial nodes per decade)", lambda d: 60, "offset 24: expected the file's checksum"),
    ("photons", lambda d: 128, "offset 24: expected the file's checksum"),
    ("g axis", lambda d: 168 + 7, "offset 24: expected the file's checksum"),
    ("payload", lambda d: payload_offset(d) + 4 * 50 + 2, "offset 24: expected the file's checksum"),
    ("last byte", lambda d: len(d) - 1, "offset 24: expected the file's checksum"),
    ("checksum", lambda d: 27, "offset 24: expected the file's checksum"),
]
FAST = {"byte 60 (radial nodes per decade)"}


@pytest.mark.parametrize("what, where, message",
                         [pytest.param(*c, marks=() if c[0] in FAST else pytest.mark.slow, id=c[0]) for c in CLASSES])
def test_damaged_table_is_refused_then_rebuilt(fork, good, good_render, tmp_path, what, where, message):
    data = good.read_bytes()
    at = where(data)
    damaged = bytearray(data)
    damaged[at] ^= 0x01 if at != 8 else 0x02  # version 3 -> 1 (a flip of bit 0 gives 2)
    path = tmp_path / NAME
    path.write_bytes(bytes(damaged))

    # The fork never renders with it: a parse error naming the file and the offset.
    with pytest.raises(runner.RenderError) as ei:
        render(fork, path)
    e = ei.value
    print(f"{what} (byte {at}): {e.file} line {e.line}: {e.message}")
    assert (e.file, e.line) == ("scene.pov", LINE)
    assert f"dipole: {NAME}: {message}" in e.message, e.message

    # The cache builder rebuilds it, says so naming the file, and the result is the undamaged one.
    log = build(path)
    print(f"  sstool: {log.strip()}")
    assert log.startswith(f"sstool build: warning: {path}: {message.split(':')[0]}"), log
    assert log.rstrip().endswith("not used; rebuilding"), log
    assert path.read_bytes() == data
    again = render(fork, path).image
    np.testing.assert_array_equal(again, good_render)
    assert build(path) == ""  # now kept as it is


def test_foreign_table_is_rebuilt(fork, good, good_render, tmp_path):
    # Built with another seed (other settings), then asked for with seed 1: not used, rebuilt.
    path = tmp_path / NAME
    build(path, "--seed", "2")  # after BUILD_ARGS' --seed 1: the last one given wins
    foreign = path.read_bytes()
    assert foreign != good.read_bytes()
    log = build(path)
    print(log.strip())
    version = subprocess.run([str(sstool()), "version"], capture_output=True, text=True, check=True).stdout.strip()
    assert log.strip() == (f"sstool build: warning: {path} was built by generator {version} with other settings than asked "
                           "for: not used; rebuilding")
    assert path.read_bytes() == good.read_bytes()
    np.testing.assert_array_equal(render(fork, path).image, good_render)


def test_build_is_the_same_for_any_thread_count(good, tmp_path):
    path = tmp_path / "two-threads.ssp"
    build(path, threads=2)
    assert path.read_bytes() == good.read_bytes()


def test_build_leaves_no_temporary_file(good, tmp_path):
    shutil.copy(good, tmp_path / NAME)
    (tmp_path / NAME).write_bytes(b"PVSSPROF" + b"\0" * 200)  # damaged: rebuilt in place
    build(tmp_path / NAME)
    assert sorted(p.name for p in tmp_path.iterdir()) == [NAME]
    assert (tmp_path / NAME).read_bytes() == good.read_bytes()
