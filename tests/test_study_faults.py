"""``make study`` under faults: killed (SIGKILL) and resumed, Ctrl-C and SIGTERM, a read-only or
full output folder, a Dask worker that dies.

The study here is tiny (2 materials x 2 shapes x 1 light at 48x40, no tables). The fork runs
behind a counting wrapper (:func:`counting_fork`): a shell script that logs each renderer it
starts (``start <job folder> <pid>``) and each one that exits 0 (``done <job folder>``), so a
test can count the renders run to completion, per cell. The study runs with ``TMPDIR`` set to a
folder of the test's own, so "nothing left in the temporary folder" is checked exactly.
"""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from harness.core import runner
from harness.core.paths import REPO_ROOT, Binary
from harness.reports import study

TINY = """
title = "tiny fault study"
size = [48, 40]
shapes = ["sphere", "torus"]
lights = ["key"]

[[material]]
name = "beckmann"
model = "microfacet d=beckmann m=0.3 f=dielectric eta=1.5 kd=0.3 rho_s=0.5"

[[material]]
name = "matte"
pov = "pigment { rgb <0.7, 0.5, 0.3> } finish { diffuse 0.8 }"
"""
CELLS = 4
#: The same with a soft light (576 shadow rays a pixel): about 1 s a render, long enough to
#: catch a renderer running and to see one that outlived the harness.
SOFT = TINY.replace('lights = ["key"]', 'lights = ["soft"]') + """
[light.soft]
pov = "light_source { <-4, 6, -5> rgb 1 area_light x * 2, z * 2, 24, 24 circular orient }"
"""


def _fork_path() -> Path:
    return Path(os.environ.get("POVRAY_BRDF") or REPO_ROOT / "build" / "bin" / "povray-brdf").resolve()


@pytest.fixture
def counting_fork(fork, tmp_path):
    """(wrapper path, log path): the fork behind a logging wrapper. The renderer is started
    with a parent-death signal (``setpriv --pdeathsig KILL``) so it dies with the wrapper as
    it dies with the harness."""
    if shutil.which("setpriv") is None:
        pytest.skip("setpriv (util-linux) is missing")
    log = tmp_path / "povray.log"
    wrapper = tmp_path / "povray-brdf-counting"
    # The renderer logs its own start once its parent-death signal is set and its parent is
    # still this script (else the script died in between and nobody would kill it: it exits).
    wrapper.write_text(f"""#!/bin/sh
setpriv --pdeathsig KILL -- sh -c '[ "$PPID" = "$0" ] || exit 111
echo "start $PWD $$ $0 $(date +%s.%N)" >> {log}
exec {fork.path.resolve()} "$@"' "$$" "$@" &
child=$!
wait $child
rc=$?
[ $rc -eq 0 ] && echo "done $PWD" >> {log}
exit $rc
""")
    wrapper.chmod(0o755)
    return wrapper, log


def _log(log: Path) -> list[list[str]]:
    return [ln.split() for ln in log.read_text().splitlines()] if log.is_file() else []


def _completions(log: Path) -> Counter:
    return Counter(Path(p[1]).name for p in _log(log) if p[0] == "done")


def _env(wrapper: Path, tmp: Path) -> dict[str, str]:
    tmp.mkdir(exist_ok=True)
    env = dict(os.environ, POVRAY_BRDF=str(wrapper), TMPDIR=str(tmp), PYTHONPATH=str(REPO_ROOT),
               MPLCONFIGDIR=str(tmp.parent / "mpl"))
    return env


def _cmd(study_file: Path, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "harness.reports.study", str(study_file), "--out", str(out), "-q", "--jobs", "2",
            *extra]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _renderers_alive(log: Path) -> list[int]:
    return [int(p[2]) for p in _log(log) if p[0] == "start" and _alive(int(p[2]))]


def _wait_for_a_new_renderer(log: Path, out: Path, stored: int) -> list[list[str]]:
    """Wait until ``stored`` renders are stored and a renderer started less than 0.3 s ago
    (a render lasts ~1 s) runs; the log lines of those."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if len(list((out / "renders").glob("*.npz"))) >= stored:
            fresh = [p for p in _log(log) if p[0] == "start" and time.time() - float(p[4]) < 0.3 and _alive(int(p[2]))]
            if fresh:
                return fresh
        time.sleep(0.003)
    raise AssertionError("no renderer started")


def _images(out: Path) -> dict[str, np.ndarray]:
    """The stored float image of every cell, by its key (summary.json's order)."""
    summary = json.loads((out / "summary.json").read_text())
    store = study.RenderStore(out / "renders")
    res = {c["key"]: store.load(c["key"]) for c in summary["cells"]}
    assert all(r is not None for r in res.values()), res
    return {k: r.image for k, r in res.items()}


def _leftovers(out: Path, tmp: Path) -> list[str]:
    left = [str(p) for p in tmp.iterdir()]
    left += [str(p) for p in out.rglob("*.tmp")] + [str(p) for p in (out / "renders").glob("*.job")]
    return left


@pytest.fixture
def tiny(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    return p


def _kill_and_resume(tiny: Path, wrapper: Path, log: Path, tmp_path: Path, moments: list[float]) -> dict:
    """An uninterrupted run, then a run killed (SIGKILL) at each moment in turn (seconds after its
    start; each next run resumes), then a last run to the end. Returns what was seen."""
    tmp = tmp_path / "tmp"
    env = _env(wrapper, tmp)
    ref_log = tmp_path / "ref.log"
    p = subprocess.run(_cmd(tiny, tmp_path / "ref"), env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    # the same again: every render kept, none run; its time is the least any run takes, so a
    # kill before it always lands in a run (starting, rendering or writing the pages)
    t0 = time.monotonic()
    p = subprocess.run(_cmd(tiny, tmp_path / "ref"), env=env, capture_output=True, text=True, timeout=300)
    ref_seconds = time.monotonic() - t0
    assert p.returncode == 0 and "4 kept from an earlier run" in p.stdout, p.stdout + p.stderr
    log.rename(ref_log)
    out = tmp_path / "out"
    seen = []
    for m in moments:
        while True:
            proc = subprocess.Popen(_cmd(tiny, out), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
            time.sleep(m * ref_seconds)
            if proc.poll() is None:
                break
            m /= 2  # a busy machine's times vary: this run ended before its kill; the kill comes earlier
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=60)
        time.sleep(0.1)  # the kernel delivers the renderers' parent-death signal
        seen.append({"at": m, "rc": proc.returncode, "kept": len(list((out / "renders").glob("*.npz")))
                     if (out / "renders").is_dir() else 0, "renderers_alive": _renderers_alive(log)})
    p = subprocess.run(_cmd(tiny, out), env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return {"ref_seconds": ref_seconds, "seen": seen, "ref": _images(tmp_path / "ref"), "out": _images(out),
            "completions": _completions(log), "ref_completions": _completions(ref_log), "stdout": p.stdout,
            "leftovers": _leftovers(out, tmp), "starts": sum(1 for x in _log(log) if x[0] == "start")}


def _check_resumed(r: dict) -> None:
    assert sum(r["ref_completions"].values()) == CELLS
    assert set(r["out"]) == set(r["ref"]) and len(r["out"]) == CELLS
    for k in r["ref"]:
        np.testing.assert_array_equal(r["out"][k], r["ref"][k])  # the same pixels, bit for bit
    # no render ran twice to completion (a render killed midway is not a completion)
    assert all(n == 1 for n in r["completions"].values()), r["completions"]
    assert sum(r["completions"].values()) <= CELLS
    assert r["leftovers"] == []
    assert all(s["renderers_alive"] == [] for s in r["seen"]), r["seen"]


def test_killed_once_resumes_without_redoing_a_render(counting_fork, tiny, tmp_path):
    """SIGKILL once, just after a renderer started (a render is stored already); then resume."""
    wrapper, log = counting_fork
    tiny.write_text(SOFT)
    tmp = tmp_path / "tmp"
    out = tmp_path / "out"
    proc = subprocess.Popen(_cmd(tiny, out), env=_env(wrapper, tmp), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    started = _wait_for_a_new_renderer(log, out, 1)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    time.sleep(0.1)
    kept = len(list((out / "renders").glob("*.npz")))
    assert 1 <= kept < CELLS
    assert _renderers_alive(log) == []  # the renderers died with the harness (a render lasts ~1 s)
    assert not {Path(p[1]).name for p in started} & set(_completions(log))
    assert not (out / "summary.json").exists()
    p = subprocess.run(_cmd(tiny, out), env=_env(wrapper, tmp), capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] and summary["failed"] == 0 and summary["renders_reused"] >= kept
    done = _completions(log)
    assert all(n == 1 for n in done.values()) and sum(done.values()) <= CELLS, done
    assert _leftovers(out, tmp) == []
    # the same pixels as the renders made straight through the runner
    st = study.load_study(tiny)
    fork = Binary(_fork_path(), "fork")
    direct = runner.render_many([study.scene_text(st, m, s, l) for m in st.materials for s in st.shapes
                                 for l in st.lights], binary=fork, width=48, height=40, float_exr=True,
                                progress=False, max_workers=2)
    got = _images(out)
    for c, d in zip(summary["cells"], direct):
        np.testing.assert_array_equal(got[c["key"]], d.image)


@pytest.mark.slow
def test_killed_at_ten_random_moments_resumes_to_the_same_images(counting_fork, tiny, tmp_path):
    """With renders of about a second, several kills land while renderers run; the others
    while the study starts or writes its pages."""
    wrapper, log = counting_fork
    tiny.write_text(SOFT)
    rng = random.Random(29)
    moments = [rng.uniform(0.05, 0.95) for _ in range(10)]  # fractions of the shortest run's time
    r = _kill_and_resume(tiny, wrapper, log, tmp_path, moments)
    print(f"run with every render kept {r['ref_seconds']:.2f} s; kills at {[round(x['at'], 2) for x in r['seen']]} of it; kept after each: "
          f"{[s['kept'] for s in r['seen']]}; renderers started {r['starts']}, run to completion "
          f"{sum(r['completions'].values())} of {CELLS}")
    assert all(s["rc"] == -signal.SIGKILL for s in r["seen"])
    _check_resumed(r)


# ---------------------------------------------------------------- Ctrl-C and SIGTERM

@pytest.mark.parametrize("sig, code, name", [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")])
def test_signal_stops_renderers_and_says_what_was_kept(counting_fork, tiny, tmp_path, sig, code, name):
    wrapper, log = counting_fork
    tiny.write_text(SOFT)
    tmp = tmp_path / "tmp"
    out = tmp_path / "out"
    proc = subprocess.Popen(_cmd(tiny, out), env=_env(wrapper, tmp), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    started = _wait_for_a_new_renderer(log, out, 0)
    running = _renderers_alive(log)
    assert running
    t0 = time.monotonic()
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    stop_seconds = time.monotonic() - t0
    print(f"{name}: stopped in {stop_seconds:.2f} s; {stderr.strip()}")
    # the renderer just started (it needs ~1 s) was killed, not waited for
    assert not {Path(p[1]).name for p in started} & set(_completions(log))
    assert proc.returncode == code, stderr
    assert "Traceback" not in stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    m = re.fullmatch(rf"study: interrupted \({name}\): (\d) of 4 renders done, kept in (\S+); run the same command "
                     r"again to render the rest", lines[0])
    assert m, lines[0]
    assert Path(m.group(2)) == out / "renders"
    assert int(m.group(1)) == len(list((out / "renders").glob("*.npz")))
    assert [p for p in running if _alive(p)] == []
    assert _renderers_alive(log) == []
    assert _leftovers(out, tmp) == []
    assert not (out / "summary.json").exists()


# ---------------------------------------------------------------- read-only and full output folders

def _mount_tmpfs(path: Path, options: str) -> None:
    path.mkdir(parents=True, exist_ok=True)
    p = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)], capture_output=True, text=True)
    if p.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({p.stderr.strip() or p.returncode}): needs root in a "
                    "container that permits mounts")


@pytest.fixture
def mounts():
    made: list[Path] = []
    yield made
    for m in made:
        subprocess.run(["umount", "-l", str(m)], capture_output=True)


def test_read_only_output_folder_is_refused_before_any_render(counting_fork, tiny, tmp_path, mounts, capsys,
                                                              monkeypatch):
    wrapper, log = counting_fork
    out = tmp_path / "ro"
    _mount_tmpfs(out, "size=1m,ro")
    mounts.append(out)
    monkeypatch.setenv("POVRAY_BRDF", str(wrapper))
    assert study.main([str(tiny), "--out", str(out / "study"), "-q"]) == 2
    err = capsys.readouterr().err
    assert f"the output folder {out / 'study'} is not writable (Read-only file system, errno 30)" in err, err
    assert "give another folder with --out" in err
    assert _log(log) == []  # not a single renderer started


@pytest.mark.parametrize("size_k", [64, 172, 180])
def test_full_disk_names_the_file_and_leaves_nothing_stale(counting_fork, tiny, tmp_path, mounts, capsys,
                                                           monkeypatch, size_k):
    """The whole study takes 179 KB. A 64 KiB output folder fills up while the renders are
    stored; 172 KiB at sheet.png, 180 KiB at summary.json (the last file written), when measured
    (which file depends on the order the renders end in). Before: an older finished run's
    summary, page and sheet, looking valid."""
    wrapper, log = counting_fork
    out = tmp_path / "full"
    _mount_tmpfs(out, f"size={size_k}k")
    mounts.append(out)
    for name in study.DERIVED:
        (out / name).write_text('{"complete": true}' if name.endswith("json") else "old")
    monkeypatch.setenv("POVRAY_BRDF", str(wrapper))
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    rc = study.main([str(tiny), "--out", str(out), "-q", "--jobs", "2"])
    err = capsys.readouterr().err
    print(f"{size_k} KiB: {err.strip()}")
    assert rc == 2
    m = re.search(r"study: cannot write (\S+): No space left on device \(errno 28\); the disk is full", err)
    assert m, err
    assert Path(m.group(1)).is_relative_to(out)
    for name in study.DERIVED:  # nothing from before or half-written stands for this run
        assert not (out / name).exists(), name
    assert list(out.rglob("*.tmp")) == [] and list(out.rglob(".*.tmp")) == []
    store = study.RenderStore(out / "renders")
    kept = sorted(p.stem for p in (out / "renders").glob("*.npz"))
    assert all(store.load(k) is not None for k in kept)  # every entry left is whole
    for job in (out / "renders").glob("*.job"):  # only a finished render the full disk could not store
        assert runner.result_from_job(job, Binary(wrapper, "fork"), 48, 40, True) is not None, job
    assert list((tmp_path / "tmp").iterdir()) == []
    assert f"{len(kept)} of 4 renders are done and kept in {out / 'renders'}: the next run renders only the rest" in err


# ---------------------------------------------------------------- Dask

def test_no_dask_worker_stops_with_the_renders_named(fork, tiny, tmp_path):
    distributed = pytest.importorskip("distributed")
    st = study.load_study(tiny)
    with distributed.LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                                  dashboard_address=":0") as cluster:
        t0 = time.monotonic()
        with pytest.raises(study.StudyError, match=r"no Dask worker at tcp://127\.0\.0\.1:\d+ for 2 s .*4 renders not "
                                                   r"done: beckmann \| sphere \| key, "):
            study.run(st, tmp_path / "out", scheduler=cluster.scheduler_address, progress=False, worker_wait=2.0)
        assert time.monotonic() - t0 < 30
    assert not (tmp_path / "out" / "summary.json").exists()


def _children(pid: int) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid and "povray-brdf" in stat.split("(", 1)[1]:
                out.append(int(d.name))
    return out


@pytest.mark.slow
def test_dask_worker_killed_mid_render_is_retried_and_leaves_no_renderer(counting_fork, tmp_path, monkeypatch):
    """Two worker processes; one is killed (SIGKILL) while its renderer runs. The render is
    done again on a worker, the study completes, the killed worker's renderer is gone."""
    distributed = pytest.importorskip("distributed")
    wrapper, log = counting_fork
    monkeypatch.setenv("POVRAY_BRDF", str(wrapper))  # the workers (started below) inherit it
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setenv("TMPDIR", str(tmp))
    p = tmp_path / "slow.toml"
    p.write_text(TINY.replace("size = [48, 40]", "size = [320, 240]").replace('lights = ["key"]', 'lights = ["area"]'))
    st = study.load_study(p)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, protocol="tcp://",
                                  host="127.0.0.1", dashboard_address=":0") as cluster, \
            distributed.Client(cluster.scheduler_address) as client:
        workers = client.run(os.getpid)
        box: dict = {}
        t0 = time.monotonic()
        th = threading.Thread(target=lambda: box.update(s=study.run(st, tmp_path / "out", progress=False,
                                                                    scheduler=cluster.scheduler_address)))
        th.start()
        victim, povray = None, []
        while not povray and time.monotonic() - t0 < 120:
            for w in workers.values():
                kids = _children(w)
                if kids:
                    victim, povray = w, kids
                    break
            time.sleep(0.02)
        assert povray, "no renderer seen under a worker"
        t_kill = time.monotonic() - t0
        os.kill(victim, signal.SIGKILL)
        time.sleep(0.5)
        povray += [int(x[2]) for x in _log(log) if x[0] == "start" and int(x[3]) in povray]  # the real renderer
        orphans = [k for k in povray if _alive(k)]
        th.join(300)
        wall = time.monotonic() - t0
    s = box["s"]
    starts = sum(1 for x in _log(log) if x[0] == "start")
    print(f"dask: worker {victim} killed at {t_kill:.1f} s with renderer(s) {povray}; study done in {wall:.1f} s; "
          f"failed {s['failed']}; renderers started {starts}, run to completion {sum(_completions(log).values())}; "
          f"renderers left {orphans}")
    assert orphans == []
    assert s["failed"] == 0 and s["renders"] == 4
    assert list(tmp.glob("povjob-*")) == []  # the killed worker's job folder was swept by the retry
    assert starts == 5 and sum(_completions(log).values()) == 4  # the killed worker's render, once more
    assert victim not in {c["worker_pid"] for c in s["cells"]}


# ---------------------------------------------------------------- what counts as done

def _result(image: np.ndarray) -> runner.RenderResult:
    return runner.RenderResult(image=image, exr_dtype=np.dtype(np.float32), trace_seconds=0.5, parse_seconds=0.1,
                               peak_memory_bytes=12345678, stats={"trace_time": 0.5}, warnings=[], command=["x"],
                               stderr="POV-Ray finished", wall_seconds=0.7, binary=Binary(Path("/bin/true"), "fork"),
                               pov_text="// scene")


def test_a_partial_or_foreign_kept_render_is_not_taken_as_done(tmp_path):
    store = study.RenderStore(tmp_path / "renders")
    img = np.random.default_rng(1).random((40, 48, 3), dtype=np.float32)
    store.save("k1", _result(img))
    back = store.load("k1")
    np.testing.assert_array_equal(back.image, img)
    assert back.trace_seconds == 0.5 and back.peak_memory_bytes == 12345678
    assert list(store.folder.iterdir()) == [store.entry("k1")]  # no temporary file left
    whole = store.entry("k1").read_bytes()
    for cut in (0, 100, len(whole) // 2, len(whole) - 1):  # a file cut short anywhere
        store.entry("k1").write_bytes(whole[:cut])
        assert store.load("k1") is None and not store.entry("k1").exists(), cut
    # another key's entry under this name (a copied folder) and flipped pixels
    store.save("k2", _result(img))
    store.entry("k2").rename(store.entry("k1"))
    assert store.load("k1") is None
    store.save("k3", _result(img))
    data = bytearray(store.entry("k3").read_bytes())
    i = data.index(img.tobytes()[:64])  # the pixels are stored uncompressed: flip a byte of one
    data[i + 8] ^= 0xFF
    store.entry("k3").write_bytes(bytes(data))
    assert store.load("k3") is None  # (the zip's CRC-32 catches this one first)
    # other pixels in a well-formed file under the right key: the sha256 of the pixels catches it
    store.save("k4", _result(img))
    with np.load(store.entry("k4")) as z:
        meta = np.array(z["meta"])
    with open(store.entry("k4"), "wb") as f:
        np.savez(f, image=img * 0.5, meta=meta)
    assert store.load("k4") is None


def test_a_job_folder_counts_only_with_its_whole_image_and_povs_last_line(tmp_path):
    from harness.core import exr

    job = tmp_path / "k.job"
    job.mkdir()
    img = np.full((40, 48, 3), 0.25, np.float32)
    exr.write_exr(job / runner.OUTPUT_NAME, img)
    (job / runner.SCENE_NAME).write_text("// scene")
    (job / runner.STDOUT_NAME).write_text("")
    (job / runner.STDERR_NAME).write_text("Trace Time: 0 hours 0 minutes 1 seconds (1.250 seconds)\nPOV-Ray finished\n")
    fork = Binary(Path("/bin/true"), "fork")
    r = runner.result_from_job(job, fork, 48, 40, True)
    assert r is not None and r.trace_seconds == 1.25 and r.peak_memory_bytes is None
    np.testing.assert_array_equal(r.image, img)
    (job / runner.STDERR_NAME).write_text("Trace Time: 0 hours 0 minutes 1 seconds (1.250 seconds)\n")  # killed before
    assert runner.result_from_job(job, fork, 48, 40, True) is None
    (job / runner.STDERR_NAME).write_text("POV-Ray finished\n")
    whole = (job / runner.OUTPUT_NAME).read_bytes()
    (job / runner.OUTPUT_NAME).write_bytes(whole[: len(whole) * 2 // 3])  # an image cut short
    assert runner.result_from_job(job, fork, 48, 40, True) is None
    (job / runner.OUTPUT_NAME).unlink()
    assert runner.result_from_job(job, fork, 48, 40, True) is None


def test_stale_job_folders_of_dead_processes_are_swept(tmp_path):
    dead = subprocess.run(["sh", "-c", "echo $$"], capture_output=True, text=True).stdout.strip()
    (tmp_path / f"povjob-{dead}-abc").mkdir()
    (tmp_path / f"povjob-{os.getpid()}-mine").mkdir()
    (tmp_path / "povjob-xyz").mkdir()  # an older name without a pid: not ours to judge
    (tmp_path / f".sheet.png.{dead}.a1b2c3.tmp").write_text("half")
    assert runner.sweep_stale_jobs(tmp_path) == 1
    from harness.core import files

    assert files.sweep_temps(tmp_path) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"povjob-{os.getpid()}-mine", "povjob-xyz"]


def test_the_key_changes_with_what_made_the_render(tmp_path):
    binary = tmp_path / "povray-brdf"
    binary.write_bytes(b"one")
    table = tmp_path / "t.brdf"
    table.write_bytes(b"table one")
    b = Binary(binary, "fork")
    opts = {"width": 48, "height": 40, "float_exr": True, "threads": 1, "files": {"t.brdf": str(table)}}
    k = study.render_key("scene", b, opts)
    assert study.render_key("scene", b, dict(opts, workdir="/x", tag="t")) == k  # where it runs: not part of it
    assert study.render_key("scene ", b, opts) != k
    assert study.render_key("scene", b, dict(opts, width=49)) != k
    assert study.render_key("scene", b, opts, [["lib/gold.brdf", 1, 2]]) != k
    table.write_bytes(b"table two")  # the staged table's contents, not its name
    assert study.render_key("scene", b, opts) != k
    table.write_bytes(b"table one")
    assert study.render_key("scene", b, opts) == k
    os.utime(binary, ns=(1, 1))  # a rebuilt binary (new mtime)
    assert study.render_key("scene", b, opts) != k
