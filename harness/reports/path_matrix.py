"""Attack POV-Ray's I/O restrictions: every way a scene or its options open a file, against
every path form a hostile scene could write (``python -m harness.reports.path_matrix``).

Each case renders a tiny scene from a folder three levels below a user's project, with the
shipped configuration (the fork's ``povray.conf``; Debian's ``/etc/povray/3.7/povray.conf``
for the stock binary): the current folder (the scene's folder) is read+write, ``HOME`` is
readable, ``secret/`` beside the project is permitted by nothing. A case is one **entry
point** (``#include``, ``#fopen`` read/write/append, ``#read``, ``image_map``,
``height_field``, a ``ttf`` font, ``brdf_table``, ``+O``, ``+GF``, ``+HI``, ``+L``) with one
**path form** that the kernel resolves either into ``secret/`` (or one folder above the
project: must be refused) or into the current folder (must be permitted)::

    consecutive ..            ../../../../secret/FILE
    consecutive .. below /tmp ../../../../../var/tmp/.../secret/FILE   (scene in /tmp/X/a/b/c)
    .. after an absolute permitted prefix   /tmp/X/a/b/c/../../../../../<secret>/FILE
    symlink out               link_out/FILE          (link_out -> secret)
    .. after a symlink        up/../FILE             (up -> secret/sub: the kernel lands in secret)
    a name beginning with ..  ..dots/FILE            (a folder named "..dots": permitted)
    ...

A read **escapes** when the render succeeds (the file was read: every scene uses what it
reads); a write escapes when the file appears in the refused folder. A permitted case
**works** when the render succeeds and the write lands where the kernel puts it. The
fork must refuse every escape form and permit every permitted one; the stock binary's
column is printed beside it (Debian's 3.7.0.10 enforces no restriction at all, and its
path canonicalisation is the one patch 0015 replaces).

``--binary fork`` (default both), ``--jobs N``; exits 1 if the fork lets one escape or
refuses a permitted case.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional, Sequence

import numpy as np

from harness.core import exr
from harness.core.paths import Binary, fork_binary, stock_binary

#: A render that takes longer than this hangs (a symlink loop in upstream's canonicaliser).
TIMEOUT_S = 20.0

FONT = Path("/usr/share/povray-3.7/include/timrom.ttf")


@dataclass(frozen=True)
class Form:
    """A path form: ``prefix(site)`` is what the scene writes before the file name;
    ``lands(site)`` the folder the kernel resolves it to (None: nowhere, a symlink loop)."""
    name: str
    refused: bool
    prefix: Callable[["Site"], str]
    lands: Callable[["Site"], Optional[Path]]
    cwd: Optional[Callable[["Site"], Path]] = None   # where the scene is rendered (default site.cwd)


@dataclass(frozen=True)
class Entry:
    """An entry point: how the scene (or the command line) opens FILE at ``path``."""
    name: str
    write: bool
    file: str
    scene: Callable[[str], str]                      # the scene's text for that path
    options: Callable[[str], Sequence[str]] = lambda p: ()
    fork_only: bool = False


class Site:
    """A user's world in a fresh folder outside the temporary folder (which the confs permit):
    ``home/`` (HOME), ``proj/a/b/c/`` (the current folder and the scene's), ``secret/``
    (permitted by nothing), and a folder under the temporary folder for the absolute forms."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.home = root / "home"
        self.cwd = root / "proj" / "a" / "b" / "c"
        self.above = root / "proj" / "a" / "b"
        self.secret = root / "secret"
        self.tmp = Path(tempfile.mkdtemp(prefix="brdf-matrix-", dir="/tmp"))
        for d in (self.home, self.cwd / "sub", self.cwd / "..dots", self.cwd / "d" / "e",
                  self.secret / "sub", self.tmp / "a" / "b" / "c"):
            d.mkdir(parents=True, exist_ok=True)
        os.symlink(self.secret, self.cwd / "link_out")
        os.symlink(self.secret / "sub", self.cwd / "up")
        os.symlink("d/e", self.cwd / "link_in")
        os.symlink("loop", self.cwd / "loop")

    def close(self) -> None:
        shutil.rmtree(self.root, ignore_errors=True)
        shutil.rmtree(self.tmp, ignore_errors=True)


def _up_to_root(p: Path) -> str:
    return "../" * len(p.parts[1:])


FORMS: list[Form] = [
    # refused: the kernel lands outside every permitted folder
    Form("one ..", True, lambda s: "../", lambda s: s.above),
    Form("consecutive ..", True, lambda s: "../../../../secret/", lambda s: s.secret),
    Form("abs. permitted prefix + ..", True,
         lambda s: f"{s.tmp}/a/b/c/{_up_to_root(s.tmp / 'a' / 'b' / 'c')}{str(s.secret).lstrip('/')}/",
         lambda s: s.secret),
    # the scene three folders below the temporary folder (read+write): upstream's one-pass
    # removal kept a ".." and the string still began with the temporary folder
    Form("consecutive .. below /tmp", True,
         lambda s: f"{_up_to_root(s.tmp / 'a' / 'b' / 'c')}{str(s.secret).lstrip('/')}/",
         lambda s: s.secret, cwd=lambda s: s.tmp / "a" / "b" / "c"),
    Form("abs. current folder + ..", True, lambda s: f"{s.cwd}/../../../../secret/", lambda s: s.secret),
    Form("./ then ..", True, lambda s: "./../../../../secret/", lambda s: s.secret),
    Form("// and ..", True, lambda s: ".//..//..//../..//secret//", lambda s: s.secret),
    Form("sub/.. then ..", True, lambda s: "sub/../../../../../secret/", lambda s: s.secret),
    Form("symlink out", True, lambda s: "link_out/", lambda s: s.secret),
    Form(".. after a symlink", True, lambda s: "up/../", lambda s: s.secret),
    Form("symlink loop", True, lambda s: "loop/", lambda s: None),
    # permitted: the kernel lands in the current folder (read+write) or the temporary folder
    Form("plain", False, lambda s: "", lambda s: s.cwd),
    Form("./", False, lambda s: "./", lambda s: s.cwd),
    Form("// inside", False, lambda s: ".//sub//", lambda s: s.cwd / "sub"),
    Form("sub/..", False, lambda s: "sub/../", lambda s: s.cwd),
    Form("name beginning with ..", False, lambda s: "..dots/", lambda s: s.cwd / "..dots"),
    Form("symlink inside + ..", False, lambda s: "link_in/../../", lambda s: s.cwd),
    Form("abs. temporary folder + ..", False, lambda s: f"{s.tmp}/a/b/c/../", lambda s: s.tmp / "a" / "b"),
]

_HEAD = ("#version 3.7;\nglobal_settings { assumed_gamma 1.0 }\n"
         "camera { orthographic location <0, 0, -3> direction z right x * 2 up y * 2 }\n"
         "light_source { <-3, 4, -5> rgb 1 }\n")


def _scene(body: str) -> str:
    return _HEAD + body + "\n"


def _uses(value: str) -> str:
    """A sphere whose colour needs ``value``: an undeclared identifier is a parse error."""
    return f"sphere {{ 0, 1 pigment {{ rgb {value} }} }}"


ENTRIES: list[Entry] = [
    Entry("#include", False, "y.inc", lambda p: _scene(f'#include "{p}"\n' + _uses("Got"))),
    Entry("#fopen read + #read", False, "r.txt",
          lambda p: _scene(f'#fopen F "{p}" read\n#read (F, Got)\n#fclose F\n' + _uses("Got"))),
    Entry("#fopen write", True, "w.txt",
          lambda p: _scene(f'#fopen F "{p}" write\n#write (F, "x\\n")\n#fclose F\n' + _uses("1"))),
    Entry("#fopen append", True, "w.txt",
          lambda p: _scene(f'#fopen F "{p}" append\n#write (F, "x\\n")\n#fclose F\n' + _uses("1"))),
    Entry("image_map", False, "i.png",
          lambda p: _scene(f'plane {{ z, 1 pigment {{ image_map {{ png "{p}" }} }} }}')),
    Entry("height_field", False, "i.png",
          lambda p: _scene(f'height_field {{ png "{p}" pigment {{ rgb 1 }} rotate -x * 90 }}')),
    Entry("ttf font", False, "f.ttf",
          lambda p: _scene(f'text {{ ttf "{p}" "A" 0.1, 0 pigment {{ rgb 1 }} }}')),
    Entry("brdf_table", False, "t.brdf",
          lambda p: _scene(f'sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ brdf_table {{ "{p}" }} }} }}'),
          fork_only=True),
    Entry("+O output", True, "o.png", lambda p: _scene(_uses("1")), lambda p: (f"+O{p}",)),
    # POV 3.7 takes a stream file's bare name and puts it in the image's folder (+O)
    Entry("+GF log file", True, "log.txt", lambda p: _scene(_uses("1")),
          lambda p: ("+GFlog.txt", f"+O{p[:-len('log.txt')]}gf.png")),
    Entry("+HI header", False, "y.inc", lambda p: _scene(_uses("Got")), lambda p: (f"+HI{p}",)),
    Entry("+L library path", False, "lib.inc",
          lambda p: _scene('#include "lib.inc"\n' + _uses("Got")), lambda p: (f"+L{p or '.'}",)),
]


def _stage_readable(folder: Path, name: str, table: Optional[Path]) -> None:
    path = folder / name
    if name.endswith(".inc"):
        path.write_text("#declare Got = 1;\n")
    elif name.endswith(".txt"):
        path.write_text("1,\n")
    elif name.endswith(".png"):
        exr.write_png_preview(path, np.full((2, 2, 3), 0.5, dtype=np.float32))  # a grey 2x2 image
    elif name.endswith(".ttf") and FONT.is_file():
        shutil.copyfile(FONT, path)
    elif name.endswith(".brdf") and table is not None:
        shutil.copyfile(table, path)


@dataclass(frozen=True)
class Outcome:
    entry: str
    form: str
    binary: str
    expect_refused: bool
    escaped: bool        # refused forms: the file was read, or written where it must not be
    worked: bool         # permitted forms: the render ran and the write landed
    returncode: Optional[int]
    seconds: float
    detail: str          # the refusal line, or why it counts as it does

    @property
    def ok(self) -> bool:
        return (not self.escaped) if self.expect_refused else self.worked


def _run_case(binary: Binary, entry: Entry, form: Form, root: Path, table: Optional[Path]) -> Outcome:
    site = Site(root)
    try:
        prefix = form.prefix(site)
        path = prefix + entry.file if entry.name != "+L library path" else prefix.rstrip("/")
        lands = form.lands(site)
        if lands is not None and not entry.write:
            _stage_readable(lands, entry.file, table)  # only there: a read that succeeds got there
        cwd = form.cwd(site) if form.cwd is not None else site.cwd
        (cwd / "scene.pov").write_text(entry.scene(path))
        env = {k: v for k, v in os.environ.items() if k not in ("POVINI", "POVINC")}
        env["HOME"] = str(site.home)
        cmd = [str(binary.path), "+Iscene.pov", "-D", "-V", "-UA", "-A", "+W4", "+H4", "+WT1", *entry.options(path)]
        if not any(o.startswith("+O") for o in entry.options(path)):
            cmd.append("+Oout.png")
        t0 = time.perf_counter()
        try:
            p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT_S,
                               start_new_session=True)
            rc, err = p.returncode, p.stderr
        except subprocess.TimeoutExpired as e:
            rc, err = None, f"hung: no answer in {TIMEOUT_S:.0f} s"
        seconds = time.perf_counter() - t0
        refusal = next((ln.strip() for ln in err.splitlines()
                        if "not permitted" in ln or "IO Restrictions prohibit" in ln), "")
        if entry.write:
            landed = lands is not None and (lands / entry.file).exists()
            escaped = form.refused and (landed or (lands is None and rc == 0))
            worked = rc == 0 and landed
        else:
            escaped = form.refused and rc == 0
            worked = rc == 0
        if rc is None:
            detail = err
        elif refusal:
            detail = refusal
        elif rc != 0:
            detail = next((ln.strip() for ln in reversed(err.splitlines()) if "rror" in ln), f"exit {rc}")
        else:
            detail = "read" if not entry.write else ("written" if (lands and (lands / entry.file).exists()) else "ran")
        return Outcome(entry.name, form.name, binary.flavour, form.refused, escaped, worked, rc, seconds, detail[:200])
    finally:
        site.close()


def run_matrix(binaries: Sequence[Binary], *, table: Optional[Path] = None, jobs: int = 4,
               entries: Sequence[Entry] = tuple(ENTRIES), forms: Sequence[Form] = tuple(FORMS)) -> list[Outcome]:
    """Every entry point x path form for each binary, ``jobs`` renders at a time. ``table``: a
    valid ``.brdf`` for the ``brdf_table`` entry (skipped without one and for stock)."""
    cases = [(b, e, f) for b in binaries for e in entries for f in forms
             if not (e.fork_only and (b.flavour != "fork" or table is None))]
    base = Path(tempfile.mkdtemp(prefix="brdf-matrix-", dir="/var/tmp"))
    try:
        with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
            futures = [pool.submit(_run_case, b, e, f, base / f"case{i}", table) for i, (b, e, f) in enumerate(cases)]
            return [fu.result() for fu in futures]
    finally:
        shutil.rmtree(base, ignore_errors=True)


def format_matrix(outcomes: Sequence[Outcome]) -> str:
    """One row per entry point x form; a column per binary: ``refused``, ``ESCAPED``,
    ``permitted``, ``REFUSED`` (a permitted case that failed)."""
    labels = sorted({o.binary for o in outcomes}, key=lambda b: (b != "fork", b))
    by = {(o.entry, o.form, o.binary): o for o in outcomes}
    rows = sorted({(o.entry, o.form, o.expect_refused) for o in outcomes},
                  key=lambda r: ([e.name for e in ENTRIES].index(r[0]) if r[0] in [e.name for e in ENTRIES] else 99,
                                 [f.name for f in FORMS].index(r[1]) if r[1] in [f.name for f in FORMS] else 99))

    def cell(o: Optional[Outcome]) -> str:
        if o is None:
            return "n/a"
        if o.expect_refused:
            return "ESCAPED" if o.escaped else ("hung" if o.returncode is None else "refused")
        return "permitted" if o.worked else "REFUSED"

    w0 = max(len(r[0]) for r in rows) if rows else 8
    w1 = max(len(r[1]) for r in rows) if rows else 8
    lines = [f"{'entry point':<{w0}}  {'path form':<{w1}}  {'expect':<9}  " + "  ".join(f"{b:<9}" for b in labels)]
    for e, f, refused in rows:
        lines.append(f"{e:<{w0}}  {f:<{w1}}  {'refused' if refused else 'permitted':<9}  "
                     + "  ".join(f"{cell(by.get((e, f, b))):<9}" for b in labels))
    for b in labels:
        mine = [o for o in outcomes if o.binary == b]
        esc = sum(o.escaped for o in mine)
        tried = sum(o.expect_refused for o in mine)
        bad = sum((not o.expect_refused) and not o.worked for o in mine)
        lines.append(f"{b}: {len(mine)} cases, {esc} of {tried} escape attempts got through, "
                     f"{bad} of {len(mine) - tried} permitted cases refused")
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m harness.reports.path_matrix", description=__doc__.split("\n\n")[0])
    ap.add_argument("--binary", choices=["fork", "stock", "both"], default="both")
    ap.add_argument("--jobs", type=int, default=4)
    args = ap.parse_args(argv)
    from harness.core import tables
    binaries = []
    if args.binary in ("fork", "both"):
        binaries.append(fork_binary())
    if args.binary in ("stock", "both"):
        binaries.append(stock_binary())
    table = tables.tabulated("lambert rho=0.5", step=15.0) if any(b.flavour == "fork" for b in binaries) else None
    outcomes = run_matrix(binaries, table=table, jobs=args.jobs)
    print(format_matrix(outcomes))
    fork = [o for o in outcomes if o.binary == "fork"]
    return 1 if any(not o.ok for o in fork) else 0


if __name__ == "__main__":
    sys.exit(main())
