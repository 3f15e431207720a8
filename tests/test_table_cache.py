"""The exact-profile tables through the cache a machine's clones share (mk/ss-tables.sh).

``make brdf-data`` builds its two ``.ssp`` files (minutes of Monte Carlo) through a cache keyed
by the sha256 of the sstool binary and of the build options. A fresh clone of the same tree
builds the same binary (path-independent objects) and so finds the file. What must hold:

* a cold build stores its file; another output path with the same options gets it from the
  cache, byte for byte, without a Monte Carlo run;
* a cached file is checked whole before use: a damaged entry (any byte) is refused by the
  loader, rebuilt, and the entry replaced by the good file;
* other options (here another seed) or another program are another key: no hit; the same
  program with other debug information (GCC records the tree's path there) is the same key;
* ``--threads`` is not part of the key (the build is the same for any thread count);
* an output already there and fresh is not copied over or stored again;
* a cache that cannot be written costs a warning, never the build.

Small tables (g 0, one eta, 4 albedo nodes): each build takes a fraction of a second.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from harness.core.paths import sstool

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "mk" / "ss-tables.sh"
ARGS = ["--g", "0", "--eta", "1.3", "--albedos", "4", "--photons", "2000", "--short-photons", "2000"]


def run(tool, cache, out, *args, threads=1):
    proc = subprocess.run(["bash", str(SCRIPT), str(tool), str(cache), str(out), "--threads", str(threads), *ARGS,
                           *args], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc.stderr


def built(log: str) -> bool:
    """sstool prints its size line only when it ran the Monte Carlo build."""
    return "records," in log


def entries(cache: Path):
    return sorted(cache.glob("*.ssp"))


def test_a_second_clone_gets_the_file_from_the_cache(tmp_path):
    cache = tmp_path / "cache"
    first = tmp_path / "a" / "subsurface_profiles.ssp"
    log = run(sstool(), cache, first)
    assert built(log), log
    (entry,) = entries(cache)
    assert entry.read_bytes() == first.read_bytes()

    second = tmp_path / "b" / "subsurface_profiles.ssp"
    log = run(sstool(), cache, second, threads=2)  # --threads is not in the key
    assert not built(log), log
    assert "from the cache" in log
    assert second.read_bytes() == first.read_bytes()
    assert entries(cache) == [entry]

    # Fresh and equal to the entry: neither copied over nor stored again.
    before = os.stat(second)
    log = run(sstool(), cache, second)
    after = os.stat(second)
    assert log == "" and (before.st_ino, before.st_mtime_ns) == (after.st_ino, after.st_mtime_ns)


@pytest.mark.parametrize("where", [0, 8, 40, -9, -1], ids=["magic", "format", "header", "payload", "last byte"])
def test_a_damaged_entry_is_refused_rebuilt_and_replaced(tmp_path, where):
    cache = tmp_path / "cache"
    good = tmp_path / "a" / "t.ssp"
    run(sstool(), cache, good)
    (entry,) = entries(cache)
    data = bytearray(entry.read_bytes())
    data[where] ^= 0x10
    entry.write_bytes(bytes(data))

    out = tmp_path / "b" / "t.ssp"
    log = run(sstool(), cache, out)
    assert "from the cache" in log and "warning" in log and "rebuilding" in log, log
    assert built(log)
    assert out.read_bytes() == good.read_bytes()
    assert entry.read_bytes() == good.read_bytes()


def test_other_options_or_another_binary_are_another_key(tmp_path):
    cache = tmp_path / "cache"
    run(sstool(), cache, tmp_path / "a" / "t.ssp")
    log = run(sstool(), cache, tmp_path / "b" / "t.ssp", "--seed", "2")
    assert built(log) and "from the cache" not in log, log
    assert len(entries(cache)) == 2

    # Another program: the same one with a byte of its .comment section (the compiler's name,
    # kept by the key's strip) changed: it still runs, and its code and data hash differently.
    other = tmp_path / "sstool-other"
    shutil.copy2(sstool(), other)
    data = bytearray(other.read_bytes())
    at = data.find(b"GCC: (")
    assert at > 0
    data[at] = ord("g")
    other.write_bytes(bytes(data))
    log = run(other, cache, tmp_path / "c" / "t.ssp")
    assert built(log) and "from the cache" not in log, log
    assert len(entries(cache)) == 3

    # Debug information alone (what GCC records of the tree's path) is not another key.
    plain = tmp_path / "sstool-plain"
    subprocess.run(["objcopy", "--strip-debug", str(sstool()), str(plain)], check=True)
    log = run(plain, cache, tmp_path / "d" / "t.ssp")
    assert not built(log) and "from the cache" in log, log


def test_no_cache_and_an_unwritable_cache_still_build(tmp_path):
    out = tmp_path / "a" / "t.ssp"
    log = run(sstool(), "", out)
    assert built(log) and out.stat().st_size > 0

    blocker = tmp_path / "file"  # a regular file where the cache folder should be
    blocker.write_text("x")
    out2 = tmp_path / "b" / "t.ssp"
    log = run(sstool(), blocker / "cache", out2)
    assert built(log), log
    assert "could not store" in log
    assert out2.read_bytes() == out.read_bytes()
