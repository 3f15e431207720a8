"""Property-based fuzzing (Hypothesis) of the harness's readers: ``.brdf`` tables
(:func:`harness.core.brdf_io.read_table`), cost files (:func:`harness.tools.cost.read_costs`)
and measured profiles (:func:`harness.tools.scatter_fit.read_profile_csv`).

Each reader gets valid files (the harness's own writers, and the seeds of the C++ fuzzers in
``shading/fuzz/corpus``), mutated: truncated, bytes overwritten, header fields set to edge
values, payload values set to NaN/Inf/huge/negative (with the checksum fixed, so they reach
the value checks), bytes appended, or random bytes. The property: a valid result (finite,
the shape the header gives) or the reader's own error, a ``ValueError`` subclass, whose message
names the file and the byte offset (or line); never another exception.

The fast suite runs a few hundred examples per reader, derandomized (the same inputs each run).
``make fuzz`` runs thousands, random: ``READER_FUZZ_EXAMPLES=5000 pytest tests/test_reader_fuzz.py``.
"""

from __future__ import annotations

import math
import os
import re
import struct
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness.core import brdf_io
from harness.core.paths import BinaryNotFound, brdftool
from harness.tools import cost
from harness.tools.scatter_fit import ProfileError, read_profile_csv

REPO = Path(__file__).resolve().parent.parent
CORPUS = REPO / "shading" / "fuzz" / "corpus"
EXAMPLES = int(os.environ.get("READER_FUZZ_EXAMPLES", "0"))
LONG = EXAMPLES > 0
FUZZ = settings(max_examples=EXAMPLES or 250, deadline=None, derandomize=not LONG, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large], print_blob=LONG)

_TMP = tempfile.TemporaryDirectory(prefix="reader-fuzz-")
TMP = Path(_TMP.name)


def _fix_checksum(d: bytes) -> bytes:
    """The checksum field (bytes 88..95) set to FNV-1a-64 of the bytes from the header's
    payload offset to the end, as the C++ fuzzers' fix_checksum does."""
    if len(d) < 112:
        return d
    off = struct.unpack_from("<I", d, 12)[0]
    if off > len(d):
        return d
    b = bytearray(d)
    struct.pack_into("<Q", b, 88, brdf_io.fnv1a64(bytes(b[off:])))
    return bytes(b)


def _brdf_seeds() -> list[bytes]:
    out = []
    rng = np.random.default_rng(7)
    for n, C, nan in ((4, 3, False), (5, 1, False), (4, 3, True)):
        f = rng.uniform(0.0, 2.0, (n, n, 2 * n - 1, C)).astype(np.float32)
        if nan:
            f[1, 2, 3] = np.nan
        out.append(brdf_io.write_brdf(TMP / "seed.brdf", f, "seed é").read_bytes())
    out += [p.read_bytes() for p in sorted((CORPUS / "table").glob("*.brdf")) if not p.name.startswith("bad-")]
    return out


BRDF_SEEDS = _brdf_seeds()

# Header fields: (offset, struct format) and values worth trying in each.
U32_EDGE = [0, 1, 2, 3, 4, 7, 90, 91, 181, 9000, 9001, 9002, 18001, 36000, 36001, 0x7FFFFFFF, 0xFFFFFFFF]
U64_EDGE = [0, 1, 4, 1488, 2 << 30, (2 << 30) + 4, 1 << 62, (1 << 64) - 1]
F64_EDGE = [0.0, -0.0, 1.0, 30.0, 45.0, 90.0, 1e-300, 1e300, math.inf, -math.inf, math.nan]
F32_EDGE = [0.0, -0.0, 1e-45, 0.5, 1e10, 10000001024.0, 1e30, 1e38, 3.4028235e38, math.inf, -math.inf, math.nan, -1.0,
            -1e-30, -1e38]
F32_VALUES = st.sampled_from(F32_EDGE) | st.floats(width=32)
FIELDS = [(8, "<I"), (12, "<I"), (16, "<I"), (20, "<I"), (24, "<I"), (28, "<I"), (32, "<I"), (36, "<I"),
          (40, "<I"), (44, "<I"), (48, "<d"), (56, "<d"), (64, "<d"), (72, "<d"), (80, "<Q"), (88, "<Q"),
          (96, "<Q"), (104, "<I"), (108, "<I")]


@st.composite
def mutated_brdf(draw: st.DrawFn) -> bytes:
    d = bytearray(draw(st.sampled_from(BRDF_SEEDS)))
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["truncate", "bytes", "field", "value", "append", "random"]))
        if op == "truncate":
            d = d[:draw(st.integers(0, len(d)))]
        elif op == "bytes" and d:
            at = draw(st.integers(0, len(d) - 1))
            b = draw(st.binary(min_size=1, max_size=8))
            d[at:at + len(b)] = b
        elif op == "field" and len(d) >= 112:
            at, fmt = draw(st.sampled_from(FIELDS))
            edge = U32_EDGE if fmt == "<I" else U64_EDGE if fmt == "<Q" else F64_EDGE
            old = struct.unpack_from(fmt, d, at)[0]
            v = draw(st.sampled_from(edge) | st.just(old + 1 if fmt != "<d" else old * (1 + 1e-8)))
            if fmt != "<d":
                v %= 1 << (8 * struct.calcsize(fmt))
            struct.pack_into(fmt, d, at, v)
        elif op == "value" and len(d) >= 116:
            off = struct.unpack_from("<I", d, 12)[0]
            if off + 4 <= len(d):
                k = draw(st.integers(0, (len(d) - off) // 4 - 1))
                struct.pack_into("<f", d, off + 4 * k, draw(F32_VALUES))
        elif op == "append":
            d += draw(st.binary(min_size=1, max_size=32))
        elif op == "random":
            d = bytearray(draw(st.sampled_from([b"", brdf_io.MAGIC])) + draw(st.binary(max_size=300)))
    d = bytes(d)
    return _fix_checksum(d) if draw(st.booleans()) else d


def _expected_shape(d: bytes) -> tuple[int, ...]:
    layout, C = struct.unpack_from("<2I", d, 16)
    n = struct.unpack_from("<4I", d, 32)
    if layout == brdf_io.ANISOTROPIC:
        return (*n, C)
    return (*n[:3], C)


OFFSET = re.compile(r": offset (\d+): expected ")


def _check_brdf(d: bytes, nodata: str) -> None:
    path = TMP / "fuzz.brdf"
    path.write_bytes(d)
    try:
        t = brdf_io.read_table(path, nodata=nodata)
    except brdf_io.TableFormatError as e:
        msg = str(e)
        assert msg.startswith(f"{path}: offset "), msg
        m = OFFSET.search(msg)
        assert m and int(m.group(1)) == e.offset and 0 <= e.offset <= len(d), msg
        return
    assert t.f.shape == _expected_shape(d) and t.f.dtype == np.float32
    ok = t.f[~np.isnan(t.f)] if nodata == "keep" else t.f
    assert np.isfinite(ok).all() and (ok >= 0).all() and (ok <= brdf_io.MAX_VALUE).all()
    assert t.layout in (1, 2, 3) and isinstance(t.description, str)


@FUZZ
@given(d=mutated_brdf(), nodata=st.sampled_from(["reject", "keep"]))
def test_brdf_reader_refuses_or_reads(d: bytes, nodata: str):
    _check_brdf(d, nodata)


def _small_table() -> bytes:
    """A 30 deg RGB table (4 x 4 x 7 nodes) of 0.25/sr, description "m": payload at 128."""
    return brdf_io.write_brdf(TMP / "small.brdf", np.full((4, 4, 7, 3), 0.25, np.float32), "m").read_bytes()


def _with_value(d: bytes, k: int, v: float) -> bytes:
    b = bytearray(d)
    struct.pack_into("<f", b, 128 + 4 * k, v)
    return _fix_checksum(bytes(b))


DAMAGED = "The file is damaged (cut short, appended to or changed after it was written)"
BRDF_CASES = [
    ("short", lambda d: d[:60], 60, "expected 112-byte header, found end of data after 60 bytes. " + DAMAGED),
    ("empty", lambda d: b"", 0, "expected 112-byte header, found end of data after 0 bytes"),
    ("magic", lambda d: b"PVBRDX\0\0" + d[8:], 0,
     'expected magic "PVBRDF\\x00\\x00", found "PVBRDX\\x00\\x00". The file is not a table'),
    ("version", lambda d: d[:8] + b"\2" + d[9:], 8, "expected version 1, found 2"),
    ("nan", lambda d: _with_value(d, 5, math.nan), 148,
     "expected a value >= 0 at theta_i=0 theta_r=0 phi=30 deg, channel 2 (no-data policy: reject), found nan. "
     "The table has no-data cells: fill them with `brdftool fill FILE -o FILLED.brdf`"),
    ("negative", lambda d: _with_value(d, 3 * 7 * 4 + 2, -1.0), 128 + 4 * 86,
     "expected a value >= 0 at theta_i=30 theta_r=0 phi=0 deg, channel 2 (no-data policy: reject), found -1"),
    ("huge", lambda d: _with_value(d, 9, 1e38), 164, "expected a value <= 1e+10 (1/sr) at theta_i=0 theta_r=0 "
     "phi=90 deg, channel 0 (larger is a unit or scale error, or damage: brdf_data/README.md), found 9.99999968e+37. "
     "The table holds a value no render can use"),
    ("huge-before-nan", lambda d: _with_value(_with_value(d, 9, 2e10), 10, math.nan), 164, "expected a value <= 1e+10"),
    ("nan-before-huge", lambda d: _with_value(_with_value(d, 9, math.nan), 10, 2e10), 164, "expected a value >= 0"),
    ("inf", lambda d: _with_value(d, 0, math.inf), 128, "expected a finite value at theta_i=0 theta_r=0 phi=0 deg, "
     "channel 0, found inf. The table holds a value no render can use"),
    ("truncated", lambda d: d[:-3], len(_small_table()) - 3, "expected 1472 bytes (1344-byte payload at offset 128), "
     "found end of data. " + DAMAGED),
    ("trailing", lambda d: d + b"\0", 1472, "expected end of data, found 1 trailing bytes"),
    ("checksum", lambda d: d[:-4] + struct.pack("<f", 0.5), 88, "expected payload FNV-1a-64 0x"),
]


@pytest.mark.parametrize("name, mutate, offset, text", BRDF_CASES, ids=[c[0] for c in BRDF_CASES])
def test_brdf_reader_names_the_byte_offset(name, mutate, offset, text, tmp_path):
    p = tmp_path / f"{name}.brdf"
    p.write_bytes(mutate(_small_table()))
    with pytest.raises(brdf_io.TableFormatError) as e:
        brdf_io.read_table(p)
    assert e.value.offset == offset and str(e.value).startswith(f"{p}: offset {offset}: {text}"), str(e.value)


def test_brdf_reader_keeps_nodata_only_when_asked(tmp_path):
    p = tmp_path / "nan.brdf"
    p.write_bytes(_with_value(_with_value(_small_table(), 5, math.nan), 6, -2.0))
    f = brdf_io.read_table(p, nodata="keep").f
    assert np.isnan(f[0, 0, 1, 2]) and np.isnan(f[0, 0, 2, 0]) and np.isnan(f).sum() == 2
    assert np.all(f[~np.isnan(f)] == np.float32(0.25))


@pytest.mark.parametrize("value", [1e38, 3.4028235e38, 2e10, 10000001024.0, brdf_io.MAX_VALUE, 9999998976.0],
                         ids=["1e38", "float-max", "2e10", "next-above-max", "max", "next-below-max"])
def test_huge_values_follow_the_loader(value, tmp_path):
    """A finite but huge value: the Python reader accepts it exactly when the C++ loader
    (``brdftool info``) does, and refuses it at the same offset (MAX_VALUE is the loader's rule)."""
    p = tmp_path / "huge.brdf"
    p.write_bytes(_with_value(_small_table(), 9, value))
    proc = subprocess.run([str(_tool()), "info", str(p)], capture_output=True, text=True)
    try:
        f = brdf_io.read_table(p).f
        assert np.float32(value) <= brdf_io.MAX_VALUE and f[0, 0, 3, 0] == np.float32(value)
        assert proc.returncode == 0, proc.stderr
    except brdf_io.TableFormatError as e:
        assert e.offset == 128 + 36 and f": offset {128 + 36}: " in proc.stderr, (str(e), proc.stderr)


# ---------------------------------------------------------------- cost files

FAMILIES = sorted(cost.FAMILY_SPECS) + ["table"]
RATIO_WORDS = ["1", "1.0", "1.25", ".5", "5.", "+2", "1e-6", "1e6", "1e-7", "1000001", "0", "-1", "inf", "nan",
               "Infinity", "1e999", "1e-400", "0x1p2", "1_0", "1,5", "1.5.2", "e5", "1e", "١", "1.5\x00x", "-0"]
SPACES = [" ", "  ", "\t", "\r", "\v", "\f", "\x00", "\xa0", "\u2028", "\x1c", "\x85"]
KEYS = st.sampled_from(FAMILIES) | st.text(min_size=1, max_size=12)
RATIOS = (st.sampled_from(RATIO_WORDS) | st.floats(allow_nan=True).map(repr)
          | st.floats(1e-7, 2e6).map(lambda v: f"{v:.4f}"))
COMMENTS = st.text(max_size=20)


@st.composite
def cost_text(draw: st.DrawFn) -> bytes:
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=200))
    lines = []
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.integers(0, 5))
        if kind == 0:
            lines.append("# " + draw(COMMENTS))
        elif kind == 1:
            lines.append(draw(st.sampled_from(["", " ", "\t\r"])))
        else:
            key, ratio = draw(KEYS), draw(RATIOS)
            sep = draw(st.sampled_from(SPACES))
            tail = draw(st.sampled_from(["", " # measured", "#", " "]))
            lines.append(f"{draw(st.sampled_from(['', ' ', chr(9)]))}{key}{sep}{ratio}{tail}")
    text = draw(st.sampled_from(["\n", "\r\n", "\r"])).join(lines)
    data = bytearray(text.encode("utf-8", "surrogatepass"))
    if data and draw(st.booleans()):
        at = draw(st.integers(0, len(data) - 1))
        data[at:at + 1] = draw(st.binary(min_size=0, max_size=3))
    return bytes(data)


COST_OFFSET = re.compile(r": line (\d+), offset (\d+): expected ")


def _check_costs(data: bytes) -> dict[str, float] | None:
    path = TMP / "costs.txt"
    path.write_bytes(data)
    try:
        c = cost.read_costs(path)
    except cost.CostFileError as e:
        m = COST_OFFSET.search(str(e))
        assert str(e).startswith(f"{path}: line ") and m, str(e)
        line, off = int(m.group(1)), int(m.group(2))
        assert (line, off) == (e.line, e.offset) and 0 <= off < len(data)
        assert data[:off].count(b"\n") + 1 == line  # the offset lies on the line named
        return None
    for k, v in c.items():
        assert k and k == " ".join(k.split()) and all(0x21 <= ord(ch) <= 0x7E for ch in k.replace(" ", ""))
        assert math.isfinite(v) and cost.MIN_RATIO <= v <= cost.MAX_RATIO
    # what brdf-cost writes from it reads back the same
    path.write_text(cost.format_costs(c))
    assert cost.read_costs(path) == pytest.approx(c, rel=1e-4)
    return c


@FUZZ
@given(data=cost_text())
def test_cost_reader_refuses_or_reads(data: bytes):
    _check_costs(data)


def test_cost_writer_writes_what_the_readers_read(tmp_path):
    """Regression (Hypothesis, the long run): format_costs wrote 1e-6 as "0.0000", a line both
    readers refuse; it now writes 5 significant digits and refuses what no reader accepts."""
    p = tmp_path / "c.txt"
    want = {"lafortune k=1": 1e-6, "ward": 0.012345, "table": 1e6}
    p.write_text(cost.format_costs(want))
    assert cost.read_costs(p) == pytest.approx(want, rel=5e-5)
    for bad in ({"lambert": 0.0}, {"lambert": 2e6}, {"lam\x01bert": 1.0}, {"lambert # x": 1.0}, {"": 1.0}):
        with pytest.raises(ValueError):
            cost.format_costs(bad)


# ---------------------------------------------------------------- measured profiles

PROFILES = [
    "# a profile\nradius [mm], Rd [1/mm^2], Rd_err [1/mm^2]\n"
    + "".join(f"{0.1 * (k + 1):.3f}, {1.0 / (k + 1):.5f}, 0.01\n" for k in range(8)),
    "r_inner [mm], r_outer [mm], Rd\n" + "".join(f"{0.1 * k:.2f}, {0.1 * (k + 1):.2f}, {1.0 / (k + 1):.4f}\n"
                                                 for k in range(7)),
    "radius, Rd [arb]\n" + "".join(f"{k + 1}, {10 - k}\n" for k in range(6)),
]
PROFILE_INSERTS = [b"nan", b"inf", b"1e999", b"1e308", b"-1", b"0", b"\x00", b",", b"\n", b'"', b"\r", b"\xff",
                   b"[", b"]", b"[m]", b"[um]", b"1/um^2", b"#", b" "]


@st.composite
def mutated_profile(draw: st.DrawFn) -> bytes:
    d = bytearray(draw(st.sampled_from(PROFILES)).encode())
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.integers(0, 3))
        at = draw(st.integers(0, len(d)))
        if op == 0:
            d[at:at + 1] = draw(st.binary(min_size=1, max_size=2))
        elif op == 1:
            d = d[:at]
        elif op == 2:
            d[at:at] = draw(st.sampled_from(PROFILE_INSERTS))
        else:
            d[at:at + draw(st.integers(1, 6))] = b""
    return bytes(d)


@FUZZ
@given(d=mutated_profile(), units=st.sampled_from([None, "mm", "cm"]))
def test_profile_reader_refuses_or_reads(d: bytes, units):
    path = TMP / "profile.csv"
    path.write_bytes(d)
    try:
        p = read_profile_csv(path, units)
    except ProfileError as e:
        msg = str(e)
        assert msg.startswith(f"{path}: "), msg
        assert re.match(r": line \d+", msg[len(str(path)):]) or "data lines" in msg or "no header" in msg \
            or "cannot read it as text" in msg, msg
        return
    assert len(p.r) == len(p.rd) >= 5
    assert np.isfinite(p.r).all() and np.isfinite(p.rd).all() and (np.diff(p.r) > 0).all()
    if p.err is not None:
        assert np.isfinite(p.err).all()


# ---------------------------------------------------------------- the C++ readers agree

def _tool() -> Path:
    try:
        return brdftool()
    except BinaryNotFound as e:
        pytest.skip(f"brdftool not built: {e}")


@pytest.mark.parametrize("path", sorted((CORPUS / "table").glob("*.brdf")), ids=lambda p: p.name)
def test_brdf_reader_agrees_with_the_loader(path: Path):
    """Every committed seed of the C++ fuzzers: the Python reader and ``brdftool info`` (the C++
    header parser and value scan) refuse the same files, a header at the same byte offset, and
    an Inf value both. (info reports no-data values and exits 1; Python reads with nodata='keep'.)"""
    proc = subprocess.run([str(_tool()), "info", str(path)], capture_output=True, text=True)
    try:
        t, err = brdf_io.read_table(path, nodata="keep"), None
    except brdf_io.TableFormatError as e:
        t, err = None, e
    m = re.search(r": offset (\d+): expected ", proc.stderr)
    if err is None:
        # (info also fills no-data values; an all-NaN channel cannot be filled: no reader's check)
        assert (m is None or " to fill " in proc.stderr) and not re.search(r"[1-9][0-9]* Inf", proc.stdout), \
            proc.stdout + proc.stderr
        assert proc.returncode == 0 or np.isnan(t.f).any(), proc.stdout + proc.stderr
    elif m:
        assert int(m.group(1)) == err.offset, (str(err), proc.stderr)
    else:  # a value the header parser does not look at: info's scan counts it
        assert "a finite value" in str(err) and re.search(r"[1-9][0-9]* Inf", proc.stdout), (str(err), proc.stdout)


COST_CASES = [
    (b"# c\nlambert 1.02\nmicrofacet d=tr   1.3  # x\n", {"lambert": 1.02, "microfacet d=tr": 1.3}),
    (b"lambert\t1.5\r\nward\x0b2\x0c\n", {"lambert": 1.5, "ward": 2.0}),
    (b"lambert .5\nlambert +5.\n", {"lambert": 5.0}),
    (b"lambert 1.5\x00junk\n", (1, 8)),       # a NUL ends no word (brdftool's strtod stopped there)
    (b"lambert inf\n", (1, 8)),
    (b"lambert nan\n", (1, 8)),
    (b"lambert 1e999\n", (1, 8)),
    (b"lambert 0x1p2\n", (1, 8)),
    (b"lambert 1_0\n", (1, 8)),
    (b"ok 1\nlambert 0\n", (2, 13)),
    (b"ok 1\n\nward x\n", (3, 11)),
    (b"lambert\n", (1, 0)),
    (b"lamb\xc3\xa9rt 1.0\n", (1, 4)),
    (b"lambert\xa01.0\n", (1, 0)),    # NBSP is no space: one word
]


@pytest.mark.parametrize("data, want", COST_CASES, ids=[repr(c[0][:16]) for c in COST_CASES])
def test_cost_grammar(data: bytes, want, tmp_path):
    """The grammar, with the line and byte offset named for the lines refused."""
    p = tmp_path / "c.txt"
    p.write_bytes(data)
    if isinstance(want, dict):
        assert cost.read_costs(p) == want
        return
    with pytest.raises(cost.CostFileError) as e:
        cost.read_costs(p)
    assert (e.value.line, e.value.offset) == want, str(e.value)
    assert f"c.txt: line {want[0]}, offset {want[1]}: expected " in str(e.value)


def _brdftool_costs(data: bytes, tmp: Path) -> tuple[bool, str]:
    """brdftool's verdict on a cost file: ``recommend`` reads --costs before the table (missing here)."""
    p = tmp / "c.txt"
    p.write_bytes(data)
    proc = subprocess.run([str(_tool()), "recommend", str(tmp / "none.brdf"), "--costs", str(p)],
                          capture_output=True, text=True, errors="replace")
    return "c.txt: line " not in proc.stderr, proc.stderr


@pytest.mark.parametrize("data, want", COST_CASES, ids=[repr(c[0][:16]) for c in COST_CASES])
def test_cost_grammar_agrees_with_brdftool(data: bytes, want, tmp_path):
    ok, err = _brdftool_costs(data, tmp_path)
    assert ok == isinstance(want, dict), err
    if not ok:
        assert f"c.txt: line {want[0]}, offset {want[1]}: expected " in err, err
