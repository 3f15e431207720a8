"""Render cost of each model family: trace-time ratio against stock POV-Ray's ``phong``.

``brdftool recommend`` weighs a fit's error against what the model costs to render. The cost
of a family is measured here once and cached in ``build/costs.txt`` (the file brdftool reads
by default), as the median over ``repeat`` (5) alternating pairs of

    trace time (fork, sphere with ``brdf_model { "SPEC" }``)
    / trace time (stock, same sphere with ``finish { diffuse 0.6 phong 0.5 phong_size 40 }``)

on a shading-bound scene: a sphere filling a 640x640 frame under four distant lights (one
thread, no anti-aliasing; POV's own trace CPU seconds, start-up and parsing excluded). ``table`` is
a 1 degree ``brdf_table`` of the same material.

    python -m harness.tools.cost            # measure if build/costs.txt is missing, print it
    python -m harness.tools.cost --force    # measure again

File format (``brdftool recommend --costs``): ``FAMILY RATIO`` per line, ``#`` comments;
FAMILY is a prefix of brdftool's family names (the longest matching prefix applies).
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
import time
from pathlib import Path
from typing import Callable, Mapping, Optional, Sequence

from harness.core import runner, tables
from harness.core.files import write_whole
from harness.core.paths import cache_dir
from harness.core.scenes import DistantLight, SphereScene

#: Where the measured table is cached: build/costs.txt in a checkout (brdftool's default:
#: costs.txt beside build/shading/); outside one, the cache folder (pass it to
#: `brdftool recommend --costs` or set BRDF_COSTS).
COSTS_PATH = cache_dir("costs.txt")

#: One representative spec per family key (a glossy red plastic where the family allows).
FAMILY_SPECS: Mapping[str, str] = {
    "lambert": "lambert rho=0.5,0.06,0.04",
    "oren_nayar": "oren_nayar rho=0.5,0.06,0.04 sigma=0.3",
    "ward": "ward rho_d=0.5,0.06,0.04 rho_s=0.3 alpha=0.15",
    "lafortune k=1": "lafortune kd=0.5,0.06,0.04 lobe=-1.1,-1.1,1.1,20,0.4",
    "lafortune k=2": "lafortune kd=0.5,0.06,0.04 lobe=-1.1,-1.1,1.1,20,0.3 lobe=-1,-1,0.9,200,0.1",
    "microfacet d=blinn": "microfacet d=blinn g=smith m=0.15 f=dielectric eta=1.5 kd=0.5,0.06,0.04 rho_s=0.5",
    "microfacet d=gaussian": "microfacet d=gaussian g=smith m=0.15 f=dielectric eta=1.5 kd=0.5,0.06,0.04 rho_s=0.5",
    "microfacet d=tr": "microfacet d=tr g=smith m=0.15 f=dielectric eta=1.5 kd=0.5,0.06,0.04 rho_s=0.5",
    "microfacet d=beckmann": "microfacet d=beckmann g=smith m=0.15 f=dielectric eta=1.5 kd=0.5,0.06,0.04 rho_s=0.5",
    "microfacet d=tr g=smith f=conductor":
        "microfacet d=tr g=smith m=0.15 f=conductor n=0.238,1.007,1.240 k=3.626,2.582,2.393",
}
#: The table row: a 1 degree table of this spec.
TABLE_SPEC = FAMILY_SPECS["microfacet d=tr"]

LIGHTS = (DistantLight(0.0), DistantLight(40.0, 30.0), DistantLight(60.0, 160.0), DistantLight(75.0, 260.0))
SIZE = 640
STOCK_FINISH = {"diffuse": 0.6, "phong": 0.5, "phong_size": 40.0}


def _scene(finish: dict) -> SphereScene:
    return SphereScene(lights=LIGHTS, finish=finish, width=SIZE, height=SIZE, pigment=(0.8, 0.1, 0.08))


def _trace(scene: SphereScene, binary: str, files: Optional[dict] = None) -> float:
    res = runner.render(scene, binary, files=files or {}, threads=1)
    # CPU seconds of the trace (POV's "using 1 thread(s) with X CPU-seconds total"): less
    # sensitive than wall time to other work on a shared machine.
    t = res.stats.get("trace_cpu_time", res.trace_seconds)
    if t is None:
        raise RuntimeError("POV printed no trace time")
    return t


def measure(repeat: int = 5, log: Optional[Callable[[str], None]] = None,
            families: Optional[Sequence[str]] = None) -> dict[str, float]:
    """Median trace-time ratio per family key (and ``table``), alternating with stock phong."""
    stock = _scene(STOCK_FINISH)
    cands: dict[str, tuple[SphereScene, dict]] = {
        k: (_scene({"brdf_model": {"spec": v}}), {}) for k, v in FAMILY_SPECS.items()
        if families is None or k in families}
    if families is None or "table" in families:
        path = tables.tabulated(TABLE_SPEC, step=1.0, fold=True)
        cands["table"] = (_scene({"brdf_table": {"file": "t.brdf"}}), {"t.brdf": path})
    _trace(stock, "stock")  # warm caches
    out = {}
    for key, (scene, files) in cands.items():
        _trace(scene, "fork", files)
        ratios = []
        for _ in range(max(1, repeat)):
            b = _trace(stock, "stock")
            c = _trace(scene, "fork", files)
            if b > 0:
                ratios.append(c / b)
        out[key] = statistics.median(ratios)
        if log:
            log(f"  {key:<40} {out[key]:.3f}  ({', '.join(f'{r:.3f}' for r in ratios)})")
    return out


def format_costs(costs: Mapping[str, float], note: str = "") -> str:
    lines = ["# trace-time ratio vs stock POV phong (harness/tools/cost.py): sphere "
             f"{SIZE}x{SIZE}, {len(LIGHTS)} distant lights, 1 thread, median of alternating pairs"]
    if note:
        lines.append(f"# {note}")
    for k, v in costs.items():
        # what read_costs and brdftool read back: 5 significant digits ("1.0200", "1.0000e-06";
        # a fixed 4 decimals wrote a ratio below 5e-5 as "0.0000", which both refuse)
        if not MIN_RATIO <= v <= MAX_RATIO or not k or k != " ".join(k.split()) \
                or "#" in k or not all(0x21 <= ord(c) <= 0x7E for c in k.replace(" ", "")):
            raise ValueError(f"cost {k!r} {v!r}: expected a family name in printable ASCII and a ratio in "
                             f"[{MIN_RATIO:g}, {MAX_RATIO:g}]")
        lines.append(f"{k} {v:#.5g}")
    return "\n".join(lines) + "\n"


#: RATIO's range and form, as brdftool's parser (shading/src/fit/fit.cpp, parse_costs) has them.
MIN_RATIO, MAX_RATIO = 1e-6, 1e6
_DECIMAL = re.compile(rb"\+?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_SPACE = b" \t\r\v\f"


class CostFileError(ValueError):
    """A cost file brdftool would refuse: ``PATH: line L, offset B: expected X, found Y. ...``
    (B: the byte offset in the file), the message brdftool gives for the same file."""

    def __init__(self, path: Path, line: int, offset: int, expected: str, found: str):
        self.path, self.line, self.offset = str(path), line, offset
        super().__init__(f"{path}: line {line}, offset {offset}: expected {expected}, found {found}. Each line is "
                         "'FAMILY RATIO' (e.g. 'microfacet d=tr 1.15'), '#' starts a comment; "
                         "`brdf-cost --force` writes the file again")


def _shown(w: bytes) -> str:
    s = "".join(chr(c) if 0x20 <= c < 0x7F and c not in (0x27, 0x5C) else f"\\x{c:02x}" for c in w[:40])
    return f"'{s}...'" if len(w) > 40 else f"'{s}'"


def parse_costs(data: bytes, path: Path) -> dict[str, float]:
    """The bytes of a cost file as a dict, by brdftool's grammar (``parse_costs`` in
    shading/src/fit/fit.cpp): lines end at '\\n', '#' starts a comment, words are separated by ASCII
    spaces; the last word is RATIO (a decimal number in [MIN_RATIO, MAX_RATIO]), the others,
    printable ASCII joined by one space, FAMILY. A later line for the same FAMILY wins."""
    out: dict[str, float] = {}
    start = 0
    for lineno, raw in enumerate(data.split(b"\n"), 1):
        line = raw.split(b"#", 1)[0]
        words, k = [], 0
        while k < len(line):
            if line[k] in _SPACE:
                k += 1
                continue
            b = k
            while k < len(line) and line[k] not in _SPACE:
                k += 1
            words.append((start + b, line[b:k]))
        start += len(raw) + 1
        if not words:
            continue
        if len(words) < 2:
            raise CostFileError(path, lineno, words[0][0], "'FAMILY RATIO' (two or more words)",
                                _shown(words[0][1]) + " alone")
        for at, w in words[:-1]:
            for c, ch in enumerate(w):
                if not 0x21 <= ch <= 0x7E:
                    raise CostFileError(path, lineno, at + c, "a family name in printable ASCII", _shown(bytes([ch])))
        at, word = words[-1]
        if not _DECIMAL.fullmatch(word):
            raise CostFileError(path, lineno, at, "RATIO, a decimal number", _shown(word))
        v = float(word)
        if not MIN_RATIO <= v <= MAX_RATIO:
            raise CostFileError(path, lineno, at, "RATIO in [1e-06, 1e+06]", _shown(word))
        out[" ".join(w.decode("ascii") for _, w in words[:-1])] = v
    return out


def read_costs(path: Path = COSTS_PATH) -> dict[str, float]:
    """The cost file as a dict (:func:`parse_costs`; :class:`CostFileError` on a line brdftool refuses)."""
    return parse_costs(Path(path).read_bytes(), Path(path))


def ensure_costs(path: Path = COSTS_PATH, force: bool = False, repeat: int = 5,
                 log: Optional[Callable[[str], None]] = None) -> Path:
    """Measure and write the cost table unless it is already there (``force`` re-measures)."""
    path = Path(path)
    if path.is_file() and not force:
        return path
    t0 = time.perf_counter()
    costs = measure(repeat, log)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_whole(path, format_costs(costs, f"measured {time.strftime('%Y-%m-%d')} in {time.perf_counter() - t0:.0f} s"))
    return path


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="brdf-cost", description=__doc__.split("\n\n")[0])
    ap.add_argument("--force", action="store_true", help="measure again even if the file exists")
    ap.add_argument("--repeat", type=int, default=5, help="alternating pairs per family (default 5)")
    ap.add_argument("-o", "--output", type=Path, default=COSTS_PATH, help=f"cost file (default {COSTS_PATH})")
    args = ap.parse_args(argv)
    path = ensure_costs(args.output, args.force, args.repeat, log=lambda s: print(s, file=sys.stderr, flush=True))
    print(path.read_text(), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
