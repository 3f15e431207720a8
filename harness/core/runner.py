"""Run POV-Ray on a scene and bring back a float image and POV's own statistics.

Each render runs in a fresh temporary directory used as the working directory, with relative
file names (``scene.pov`` → ``out.exr``): stock POV's ``/etc/povray/3.7/povray.conf`` permits
writes to ``.`` and ``/tmp``. ``HOME`` points to an empty directory inside the job so no user
``~/.povray/3.7/povray.{conf,ini}`` interferes, and ``POVINI``/``POVINC`` are removed from the
environment. The fork brings its own conf, compiled in.

Options always passed:

* ``-A``  no anti-aliasing: exactly one ray through each pixel centre (what :mod:`harness.reference.expect`
  models);
* ``-D``  no display; ``-V`` not verbose (drops the per-line progress, keeps the statistics,
  which go to the statistics stream: never pass ``-GA``); ``-UA`` no alpha channel;
* ``+FE32`` (fork, ``float_exr=True``) or ``+FE`` (stock: half float only; stock *accepts*
  ``+FE32`` and still writes half, so the runner does not pretend);
* ``+WT<threads>`` (default 1: timings per thread, and the machines are small);
* ``+L<dir>`` for each :func:`harness.core.paths.include_dirs` entry.
"""

from __future__ import annotations

import ctypes
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from concurrent.futures import FIRST_EXCEPTION, ThreadPoolExecutor
from concurrent.futures import wait as wait_futures
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from harness.core import exr
from harness.core.files import WRITE_ERRNOS, WriteError, orphaned_entries
from harness.core.paths import Binary, include_dirs, resolve_binary
from harness.core.progress import bar as progress_bar
from harness.core.povwriter import scene_to_pov

SCENE_NAME = "scene.pov"
OUTPUT_NAME = "out.exr"
#: POV's standard output and error, written by POV itself into the job folder (so a finished
#: render's statistics outlive the harness: :func:`result_from_job`).
STDOUT_NAME = "pov.stdout"
STDERR_NAME = "pov.stderr"
#: Temporary job folders are ``povjob-<harness pid>-<random>`` in the temp folder.
JOB_PREFIX = "povjob-"


class RenderError(RuntimeError):
    """POV-Ray failed. ``message`` is POV's own error text; ``file``/``line`` where it points."""

    def __init__(self, message: str, *, file: Optional[str] = None, line: Optional[int] = None,
                 returncode: Optional[int] = None, command: Sequence[str] = (), stderr: str = "",
                 pov_text: str = "") -> None:
        where = f"{file} line {line}: " if file is not None and line is not None else ""
        super().__init__(f"POV-Ray failed (exit {returncode}): {where}{message}")
        self.message = message
        self.file = file
        self.line = line
        self.returncode = returncode
        self.command = list(command)
        self.stderr = stderr
        self.pov_text = pov_text


@dataclass
class RenderResult:
    """One finished render.

    ``image`` is float32 (H, W, 3), linear, row 0 at the top; ``exr_dtype`` says how the file
    stored it (``float16`` for stock). Times are POV's own, in seconds (None if not printed);
    ``wall_seconds`` includes start-up (~0.6 s). ``peak_memory_bytes`` is POV's "Peak memory
    used" where it prints one, else the renderer's own peak resident set size
    (``stats["max_rss_bytes"]``: its ``VmHWM``, see :func:`_run_measured`; within 1 % of GNU
    ``time -v``'s maximum resident size for the same render).
    """

    image: np.ndarray
    exr_dtype: np.dtype
    trace_seconds: Optional[float]
    parse_seconds: Optional[float]
    peak_memory_bytes: Optional[int]
    stats: dict[str, float]
    warnings: list[str]
    command: list[str]
    stderr: str
    wall_seconds: float
    binary: Binary
    pov_text: str


# ---------------------------------------------------------------- parsing POV's output

_TIME_RE = re.compile(
    r"^\s*(?P<what>Parse|Bounding|Photon|Radiosity|Trace) Time:\s*"
    r"(?P<h>\d+)\s+hours?\s+(?P<m>\d+)\s+minutes?\s+(?P<s>\d+)\s+seconds?"
    r"(?:\s*\((?P<secs>\d+(?:\.\d+)?)\s+seconds?\))?"
    r"(?:[ \t]*\r?\n\s*using\s+(?P<threads>\d+)\s+thread\(s\)\s+with\s+"
    r"(?P<cpu>\d+(?:\.\d+)?)\s+CPU-seconds\s+total)?",
    re.MULTILINE)
_COUNT_RES = {
    "pixels": re.compile(r"^Pixels:\s+(\d+)", re.MULTILINE),
    "samples": re.compile(r"^Pixels:.*?Samples:\s+(\d+)", re.MULTILINE),
    "rays": re.compile(r"^Rays:\s+(\d+)", re.MULTILINE),
    "shadow_ray_tests": re.compile(r"^Shadow Ray Tests:\s+(\d+)", re.MULTILINE),
    "shadow_rays_succeeded": re.compile(r"^Shadow Ray Tests:.*?Succeeded:\s+(\d+)", re.MULTILINE),
    "peak_memory_bytes": re.compile(r"^\s*Peak memory used:\s+(\d+)\s+bytes", re.MULTILINE),
    "reflected_rays": re.compile(r"^Reflected Rays:\s+(\d+)", re.MULTILINE),
}
_MSG_RE = re.compile(r"^File '(?P<file>[^']*)' line (?P<line>\d+):\s*(?P<msg>.*)$", re.MULTILINE)
_END_MARKERS = ("Fatal error", "Render failed", "----", "====")


def parse_stats(stderr: str) -> dict[str, float]:
    """POV's statistics as numbers.

    Keys (present when printed): ``<what>_time`` in seconds for parse, bounding, photon,
    radiosity, trace (the ``(12.345 seconds)`` figure, else h/m/s); ``<what>_cpu_time`` and
    ``<what>_threads`` from the ``using N thread(s) with X CPU-seconds total`` line; ``pixels``,
    ``samples``, ``rays``, ``shadow_ray_tests``, ``shadow_rays_succeeded``,
    ``peak_memory_bytes``, ``reflected_rays``. "No photons"/"No trace" lines give no key.
    """
    out: dict[str, float] = {}
    for m in _TIME_RE.finditer(stderr):
        key = m["what"].lower()
        if m["secs"] is not None:
            secs = float(m["secs"])
        else:
            secs = 3600.0 * int(m["h"]) + 60.0 * int(m["m"]) + int(m["s"])
        out[f"{key}_time"] = secs
        if m["threads"] is not None:
            out[f"{key}_threads"] = float(m["threads"])
            out[f"{key}_cpu_time"] = float(m["cpu"])
    for key, rx in _COUNT_RES.items():
        c = rx.search(stderr)
        if c:
            out[key] = float(c.group(1))
    return out


def _message_at(stderr: str, m: re.Match) -> str:
    """The message starting at match ``m``, with POV's 80-column continuation lines joined.

    POV indents a continuation line by one space where it broke at a space; where a word
    reached the 80th column it breaks inside the text, and the next line starts without a
    space (e.g. ``,`` after a long path): such a line follows a full one (79+ characters).
    """
    text = m["msg"].strip()
    prev = stderr[m.start():m.end()]
    for ln in stderr[m.end():].splitlines()[1:]:
        if not ln.strip() or ln.strip().startswith(_END_MARKERS) or _MSG_RE.match(ln):
            break
        if ln.startswith(" "):
            text += " " + ln.strip()
        elif len(prev) >= 79:
            text += ln.rstrip()
        else:
            break
        prev = ln
    return text


def parse_messages(stderr: str) -> list[tuple[str, int, str]]:
    """Every ``File 'f' line N: …`` message POV printed, as ``(file, line, text)``."""
    return [(m["file"], int(m["line"]), _message_at(stderr, m)) for m in _MSG_RE.finditer(stderr)]


def parse_error(stderr: str) -> tuple[str, Optional[str], Optional[int]]:
    """POV's error as ``(message, file, line)``; file/line are None when POV gave none.

    Takes the last located message that is an error (not a warning); failing that, the
    lines that end the output (e.g. ``Parse Error: Cannot open input file.``).
    """
    located = [msg for msg in parse_messages(stderr) if "Error" in msg[2] or "error" in msg[2]]
    if located:
        f, n, text = located[-1]
        return text, f, n
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    lines = [ln for ln in lines if ln != "Render failed"]
    errs = [ln for ln in lines if "rror" in ln or "annot" in ln or "ailed" in ln]
    return (" ".join(errs[-3:]) if errs else " ".join(lines[-5:])), None, None


# ---------------------------------------------------------------- running

def clean_env(home: Path) -> dict[str, str]:
    """The environment a render runs in: this one with ``HOME`` = ``home`` (no user conf or
    INI) and without ``POVINI``/``POVINC``."""
    env = dict(os.environ)
    env["HOME"] = str(home)
    for k in ("POVINI", "POVINC"):
        env.pop(k, None)
    return env


def _stage(src: Path, dst: Path) -> None:
    """Put ``src`` into the job directory as ``dst``: a hard link, or a copy across file systems
    (a directory is copied).

    Not a symlink: with I/O restrictions on, POV-Ray resolves symlinks before checking a path,
    so a symlink in the job directory to a file outside the permitted paths is refused.
    """
    if src.is_dir():
        shutil.copytree(src, dst)
        return
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)


def _vm_hwm(pid: Union[int, str]) -> Optional[int]:
    """``VmHWM`` (peak resident set size) of a process in bytes, from ``/proc/PID/status``;
    None once its memory is gone (it exited) or where there is no /proc."""
    try:
        with open(f"/proc/{pid}/status", "rb") as f:
            for line in f:
                if line.startswith(b"VmHWM:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


#: How often :func:`_run_measured` reads the renderer's VmHWM (seconds).
RSS_POLL_SECONDS = 0.01
#: How far the child's ``ru_maxrss`` must exceed this process's own peak to be taken as the
#: renderer's (the counters behind both are approximate by up to a few MB under load).
INHERITED_MARGIN_BYTES = 64 * 2**20


# ---------------------------------------------------------------- the renderer processes

_PR_SET_PDEATHSIG = 1
try:
    _prctl = ctypes.CDLL(None, use_errno=True).prctl
except (OSError, AttributeError):  # not Linux: no parent-death signal, the process group remains
    _prctl = None

_LIVE_LOCK = threading.Lock()
_LIVE: dict[subprocess.Popen, str] = {}   # running renderer -> its tag
_STOPPING: set[str] = set()                # tags being stopped: no new renderer starts for them


class Stopped(RuntimeError):
    """The render was stopped by :func:`stop_renders` (Ctrl-C, SIGTERM, a failed study)."""


def _child_setup(parent: int) -> None:
    """Run in the renderer's process before ``exec``: it dies (SIGKILL) with the harness thread
    that started it, even when the harness itself is killed with SIGKILL (Linux
    ``PR_SET_PDEATHSIG``). Only async-signal-safe work here: the harness has threads."""
    if _prctl is not None:
        _prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    if os.getppid() != parent:  # the harness died before the call above: nobody would kill us
        os._exit(137)


def _start(cmd: Sequence[str], cwd: Path, env: Mapping[str, str], out: Any, err: Any, tag: str) -> subprocess.Popen:
    """Start a renderer in its own process group, registered under ``tag`` so that
    :func:`stop_renders` can end it (and whatever it started: the whole group)."""
    with _LIVE_LOCK:
        if tag in _STOPPING or "" in _STOPPING:
            raise Stopped("stopped before the renderer started")
        parent = os.getpid()
        proc = subprocess.Popen(cmd, cwd=cwd, env=dict(env), stdin=subprocess.DEVNULL, stdout=out, stderr=err,
                                process_group=0, preexec_fn=lambda: _child_setup(parent))
        _LIVE[proc] = tag
    return proc


def _kill_group(proc: subprocess.Popen, sig: int = signal.SIGKILL) -> None:
    try:
        os.killpg(proc.pid, sig)  # the group the renderer leads (a wrapper's children too)
    except OSError:
        try:
            proc.send_signal(sig)
        except OSError:
            pass


def stop_renders(tag: str = "") -> int:
    """Kill (SIGKILL, the whole process group) every renderer this process runs under ``tag``
    (``""``: all of them), and refuse new ones for ``tag`` until :func:`allow_renders`. Their
    :func:`render` calls raise :class:`Stopped` and remove their temporary folders. Returns how
    many were running."""
    with _LIVE_LOCK:
        _STOPPING.add(tag)
        live = [p for p, t in _LIVE.items() if not tag or t == tag]
    for p in live:
        _kill_group(p)
    return len(live)


def allow_renders(tag: str = "") -> None:
    """Undo :func:`stop_renders` for ``tag``."""
    with _LIVE_LOCK:
        _STOPPING.discard(tag)


def running_renders(tag: str = "") -> list[int]:
    """Process ids of the renderers running under ``tag`` (``""``: all)."""
    with _LIVE_LOCK:
        return [p.pid for p, t in _LIVE.items() if not tag or t == tag]


def sweep_stale_jobs(folder: Optional[Union[str, os.PathLike]] = None, prefix: str = JOB_PREFIX) -> int:
    """Remove temporary job folders (``povjob-<pid>-*``; another ``prefix``: ``<prefix><pid>-*``)
    left in the temp folder by harness processes that were killed (their pid is gone) and
    owned by this user. Returns how many."""
    n = 0
    for ent in orphaned_entries(folder or tempfile.gettempdir(), re.compile(re.escape(prefix) + r"(\d+)-.+")):
        if ent.is_dir(follow_symlinks=False):
            shutil.rmtree(ent.path, ignore_errors=True)
            n += 1
    return n


def _run_measured(cmd: Sequence[str], cwd: Path, env: Mapping[str, str],
                  timeout: Optional[float], tag: str = "") -> tuple[Optional[int], str, str, Optional[int]]:
    """Run ``cmd``; return ``(exit status or None on timeout, stdout, stderr, peak RSS bytes)``.

    The renderer writes its standard output and error to :data:`STDOUT_NAME` and
    :data:`STDERR_NAME` in ``cwd`` itself (read back after it exits), runs in its own process
    group and dies with the harness (:func:`_child_setup`); :func:`stop_renders` kills it.

    The peak RSS is the renderer's own. ``ru_maxrss`` of a child started from Python is
    not: Linux keeps, across ``exec``, the high-water mark of the memory the child had before
    it (Python's, copied or shared at fork), so a 16 MB render of a 60 MB harness reads 60 MB.
    ``VmHWM`` in ``/proc/PID/status`` starts afresh at ``exec``; a thread reads it every
    :data:`RSS_POLL_SECONDS` while the child runs (it is a high-water mark, so only growth in
    the last interval before exit can be missed). Where the child's ``ru_maxrss`` (from
    ``os.wait4``) exceeds this process's own peak after the start, it is the renderer's exact
    peak and is used instead (when it exceeds it by more than :data:`INHERITED_MARGIN_BYTES`).
    A timer kills the child at ``timeout``.
    """
    with open(cwd / STDOUT_NAME, "wb") as fout, open(cwd / STDERR_NAME, "wb") as ferr:
        proc = _start(cmd, cwd, env, fout, ferr, tag)
    try:
        own_peak = _vm_hwm("self")  # after exec: at least what the child inherited
        exited = threading.Event()
        polled = [0]

        def poll() -> None:
            while not exited.is_set():
                v = _vm_hwm(proc.pid)
                if v is not None and v > polled[0]:
                    polled[0] = v
                exited.wait(RSS_POLL_SECONDS)

        poller = threading.Thread(target=poll, daemon=True)
        poller.start()
        timed_out = threading.Event()

        def kill() -> None:
            timed_out.set()
            _kill_group(proc)

        timer = threading.Timer(timeout, kill) if timeout is not None else None
        if timer is not None:
            timer.start()
        try:
            _, status, usage = os.wait4(proc.pid, 0)
        finally:
            exited.set()
            if timer is not None:
                timer.cancel()
        poller.join()
        proc.returncode = os.waitstatus_to_exitcode(status)  # Popen must not wait for it again
    except BaseException:
        _kill_group(proc)  # this thread was interrupted: the renderer must not outlive it
        raise
    finally:
        with _LIVE_LOCK:
            stopped = _LIVE.pop(proc, None) is not None and (tag in _STOPPING or "" in _STOPPING)
        if proc.returncode is None:
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass
    out = (cwd / STDOUT_NAME).read_bytes().decode(errors="replace")
    err = (cwd / STDERR_NAME).read_bytes().decode(errors="replace")
    if stopped and proc.returncode != 0:
        raise Stopped(f"renderer stopped (exit {proc.returncode})")
    maxrss = int(usage.ru_maxrss) * 1024 if usage.ru_maxrss > 0 else None
    # The kernel's resident counters are kept per thread and synchronised lazily, so the
    # inherited part of ru_maxrss can read slightly above the VmHWM this process saw of itself
    # (CI once took a 481 MB harness for a 34 MB render). Only a clear excess is the renderer's.
    if maxrss is not None and own_peak is not None and maxrss > own_peak + INHERITED_MARGIN_BYTES:
        rss: Optional[int] = maxrss       # above anything inherited: the renderer's own peak
    elif polled[0] > 0:
        rss = polled[0]
    else:
        rss = maxrss if own_peak is None else None  # no /proc: the old measure
    return (None if timed_out.is_set() else proc.returncode), out, err, rss


def build_command(binary: Binary, width: int, height: int, float_exr: bool = False,
                  threads: int = 1, extra_args: Sequence[str] = ()) -> list[str]:
    """The command line the runner uses (relative names: run it in the job directory)."""
    fmt = "+FE32" if (float_exr and binary.flavour == "fork") else "+FE"
    cmd = [str(binary.path), f"+I{SCENE_NAME}", f"+O{OUTPUT_NAME}", fmt,
           "-A", "-D", "-V", "-UA", f"+W{int(width)}", f"+H{int(height)}", f"+WT{int(threads)}"]
    cmd += [f"+L{d}" for d in include_dirs()]
    cmd += list(extra_args)
    return cmd


def render(scene: Any, binary: Union[str, os.PathLike, Binary] = "stock", *,
           width: Optional[int] = None, height: Optional[int] = None, float_exr: bool = False,
           extra_args: Sequence[str] = (), threads: int = 1,
           files: Optional[Mapping[str, Union[str, os.PathLike]]] = None,
           workdir: Optional[Union[str, os.PathLike]] = None,
           timeout: Optional[float] = 600.0, wrapper: Sequence[str] = (), tag: str = "") -> RenderResult:
    """Render ``scene`` (a :mod:`harness.core.scenes` dataclass, or ``.pov`` text) with ``binary``.

    ``width``/``height`` default to the scene's (required for text). ``files`` maps names in
    the job directory to files staged there (hard links or copies: tables, include files).
    ``workdir`` renders in that directory and keeps it; otherwise a temporary one is removed
    afterwards. ``wrapper`` runs POV under another program (e.g. valgrind: its report is in
    the result's ``stderr``). ``tag`` names the render for :func:`stop_renders`.
    Raises :class:`RenderError` (with POV's message, file and line) when POV fails or writes
    no image, :class:`Stopped` when :func:`stop_renders` ended it, and
    :class:`harness.core.paths.BinaryNotFound` when the binary is missing. The temporary
    folder (``povjob-<pid>-*``) is removed however the call ends; one left by a killed harness
    is removed by :func:`sweep_stale_jobs`.
    """
    b = resolve_binary(binary)
    if isinstance(scene, str):
        text = scene
        if width is None or height is None:
            raise ValueError("width and height are required when rendering scene text")
    else:
        text = scene_to_pov(scene)
        width = scene.width if width is None else width
        height = scene.height if height is None else height
    cmd = list(wrapper) + build_command(b, width, height, float_exr, threads, extra_args)

    tmp = None
    if workdir is None:
        tmp = tempfile.mkdtemp(prefix=f"{JOB_PREFIX}{os.getpid()}-")
        job = Path(tmp)
    else:
        job = Path(workdir)
        job.mkdir(parents=True, exist_ok=True)
    try:
        home = job / "home"
        try:
            home.mkdir(exist_ok=True)
            (job / SCENE_NAME).write_text(text)
            for name, src in (files or {}).items():
                dst = job / name
                dst.parent.mkdir(parents=True, exist_ok=True)
                if dst.is_dir() and not dst.is_symlink():
                    shutil.rmtree(dst)
                elif dst.is_symlink() or dst.exists():
                    dst.unlink()
                _stage(Path(src).resolve(), dst)
            out = job / OUTPUT_NAME
            if out.exists():
                out.unlink()
            t0 = time.perf_counter()
            returncode, stdout, stderr, max_rss = _run_measured(cmd, job, clean_env(home), timeout, tag)
        except OSError as e:
            if isinstance(e, WriteError) or e.errno not in WRITE_ERRNOS or str(e.filename) == cmd[0]:
                raise
            raise WriteError(e.filename or job, e) from e  # Errno 28 alone names no file
        wall = time.perf_counter() - t0
        stderr = stderr + stdout
        if returncode is None:
            raise RenderError(f"timed out after {timeout} s", command=cmd, stderr=stderr, pov_text=text)
        if returncode != 0 or not out.is_file():
            msg, f, n = parse_error(stderr)
            if returncode == 0:
                msg = f"no output image written. {msg}"
            raise RenderError(msg, file=f, line=n, returncode=returncode, command=cmd,
                              stderr=stderr, pov_text=text)
        return _result(job, b, cmd, text, stderr, wall, max_rss)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _result(job: Path, b: Binary, cmd: list[str], text: str, stderr: str, wall: float,
            max_rss: Optional[int]) -> RenderResult:
    img = exr.read_exr_full(job / OUTPUT_NAME)
    stats = parse_stats(stderr)
    if max_rss is not None:
        stats["max_rss_bytes"] = float(max_rss)
    # POV 3.7's unix build prints no "Peak memory used" (a memory-debug build does): then
    # the process's peak resident set size stands in for it.
    mem = stats.get("peak_memory_bytes", stats.get("max_rss_bytes"))
    warnings = [f"{f} line {n}: {t}" for f, n, t in parse_messages(stderr) if "Warning" in t]
    return RenderResult(image=img.pixels, exr_dtype=img.stored_dtype,
                        trace_seconds=stats.get("trace_time"), parse_seconds=stats.get("parse_time"),
                        peak_memory_bytes=int(mem) if mem is not None else None, stats=stats,
                        warnings=warnings, command=cmd, stderr=stderr, wall_seconds=wall,
                        binary=b, pov_text=text)


#: The last line POV-Ray prints after a render that succeeded.
FINISHED_LINE = "POV-Ray finished"


def result_from_job(job: Union[str, os.PathLike], binary: Union[str, os.PathLike, Binary], width: int, height: int,
                    float_exr: bool = False, threads: int = 1, extra_args: Sequence[str] = ()) -> Optional[RenderResult]:
    """The result of a render that finished in the kept folder ``job`` (``render(workdir=job)``)
    even if the harness that started it was killed before reading it: its scene, its image
    (read whole) and POV's own output ending with :data:`FINISHED_LINE`. None when the render
    did not finish there (no image, a truncated one, no final line). The renderer's peak
    memory is not known then (``peak_memory_bytes`` is POV's or None); ``wall_seconds`` is NaN."""
    job = Path(job)
    try:
        err = (job / STDERR_NAME).read_bytes().decode(errors="replace")
        out = (job / STDOUT_NAME).read_bytes().decode(errors="replace")
        text = (job / SCENE_NAME).read_text()
        if not (err.rstrip().endswith(FINISHED_LINE) or out.rstrip().endswith(FINISHED_LINE)):
            return None
        b = resolve_binary(binary)
        cmd = build_command(b, width, height, float_exr, threads, extra_args)
        return _result(job, b, cmd, text, err + out, float("nan"), None)
    except Exception:  # noqa: BLE001 - missing, truncated or unreadable (OpenEXR's own errors): not finished
        return None


@dataclass
class RenderJob:
    """One job for :func:`render_many`: a scene (or text) and keyword arguments for :func:`render`."""

    scene: Any
    options: dict[str, Any] = field(default_factory=dict)


def render_many(jobs: Iterable[Union[RenderJob, Any]], *, max_workers: Optional[int] = None,
                progress: bool = True, return_exceptions: bool = False, progress_label: str = "render",
                on_done: Optional[Callable[[int, Union[RenderResult, Exception]], None]] = None,
                **common: Any) -> list[Union[RenderResult, Exception]]:
    """Render several jobs concurrently (threads: each job is a POV process); results in order.

    ``jobs`` are :class:`RenderJob` or bare scenes; ``common`` keyword arguments apply to all
    (a job's own options win). ``max_workers`` defaults to the CPU count. With
    ``return_exceptions`` a failed job's exception takes its place; otherwise the first
    failure (in job order) is raised after all jobs finish. ``progress``: a bar with the
    renders done, failed, elapsed and left on stderr (:mod:`harness.core.progress`), labelled
    ``progress_label``. ``on_done(index, result or exception)`` runs in the job's thread as
    each job ends (e.g. to store the result at once); an exception it raises stops the batch.

    Stopping: when this call is interrupted (Ctrl-C's ``KeyboardInterrupt``, any exception
    raised in the calling thread, an ``on_done`` error) the jobs not started are dropped, the
    running renderers are killed (:func:`stop_renders` for this call's tag), their temporary
    folders removed, and the exception is raised once every thread has ended.
    """
    jl = [j if isinstance(j, RenderJob) else RenderJob(j) for j in jobs]
    failed = 0
    lock = threading.Lock()
    tag = f"render_many-{os.getpid()}-{id(jl)}-{time.monotonic_ns()}"

    with progress_bar(len(jl), progress_label, unit="render", enabled=progress) as prog:
        def run(i: int, job: RenderJob) -> Union[RenderResult, Exception]:
            nonlocal failed
            try:
                r: Union[RenderResult, Exception] = render(job.scene, **{"tag": tag, **common, **job.options})
            except Stopped:
                raise
            except Exception as e:  # noqa: BLE001 - handed back or re-raised below
                r = e
            if on_done is not None:
                on_done(i, r)
            with lock:
                if isinstance(r, Exception):
                    failed += 1
                    prog.set_postfix_str(f"{failed} failed", refresh=False)
                prog.update(1)
            return r

        pool = ThreadPoolExecutor(max_workers=max_workers or os.cpu_count() or 1)
        futures = []
        try:
            futures = [pool.submit(run, i, j) for i, j in enumerate(jl)]
            while True:
                # Short waits: a signal the kernel hands to another thread (one waiting for its
                # renderer) runs its Python handler (Ctrl-C's KeyboardInterrupt) only when this
                # thread runs Python code again, not while it blocks in one long wait.
                done, pending = wait_futures(futures, timeout=0.05, return_when=FIRST_EXCEPTION)
                for f in done:
                    if f.exception() is not None:
                        raise f.exception()  # type: ignore[misc]
                if not pending:
                    break
            results = [f.result() for f in futures]
        except BaseException:
            for f in futures:
                f.cancel()
            stop_renders(tag)
            pool.shutdown(wait=True, cancel_futures=True)  # each thread removes its job folder
            allow_renders(tag)
            raise
        pool.shutdown(wait=True)
    if not return_exceptions:
        for r in results:
            if isinstance(r, Exception):
                raise r
    return results
