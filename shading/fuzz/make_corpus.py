#!/usr/bin/env python3
"""Writes the fuzzers' seed corpus (committed; re-run to regenerate, stdlib only).

    python3 shading/fuzz/make_corpus.py build/shading/brdftool shading/fuzz/corpus

table/: coarse tables made by brdftool (15 and 30 deg steps: isotropic, folded, 1 channel,
anisotropic, a simulated measurement with filled cells, a description; half/difference
tables, RGB and grey, a few nodes per axis), then broken variants of one of them
(truncated, wrong magic, version, layout, node counts, steps, payload size, padding,
trailing bytes, checksum) and of a half/difference one (folded flag, n[3], each node count
and step, a NaN value), and valid-checksum payloads with NaN, negative and infinite values
(the no-data paths).
merl/: small non-standard MERL .binary files (dims 2x2x4 and 3x4x6), with no-data samples,
plus broken ones (truncated header, zero/negative/huge dims, short, long, +Inf).
ssp/: small exact-profile tables made by sstool (next to brdftool: 4 albedo nodes, a few hundred
photons; one node, 2 x 2 nodes, slabs), then broken variants (truncated, magic, version, flags,
counts, reserved field, settings, axes, payload offset and size, checksum) and valid-checksum
payloads with NaN, negative and inconsistent values.
costs/: cost files (`brdftool recommend --costs`): the form `brdf-cost` writes, comments, tabs,
CRLF, keys of several words, repeated families; then refused lines (one word, non-decimal,
out-of-range and non-finite ratios, a NUL inside the ratio, non-ASCII families), and the
regression inputs of the parser's findings (see shading/tests/fit_test.cpp, Fit.CostFileGrammar).
"""
import math
import os
import struct
import subprocess
import sys
import tempfile


def fnv1a64(data):
    h = 0xCBF29CE484222325
    for b in data:
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def refresh_checksum(d):
    d = bytearray(d)
    off = struct.unpack_from("<I", d, 12)[0]
    struct.pack_into("<Q", d, 88, fnv1a64(d[off:]))
    return bytes(d)


def ssp_fix(d):
    """An .ssp image with its checksum (bytes 24..31: FNV-1a of the file, those bytes as zeros) made right."""
    d = bytearray(d)
    struct.pack_into("<Q", d, 24, 0)
    struct.pack_into("<Q", d, 24, fnv1a64(d))
    return bytes(d)


def broken_framing(base, header_cut, payload_cut, magic):
    """The damage every format gets: empty, the magic alone, the header cut at `header_cut`,
    `payload_cut` bytes missing at the end, four trailing bytes, another `magic`."""
    return {"empty": b"", "magic-only": base[:8], "truncated-header": base[:header_cut],
            "truncated-payload": base[:len(base) - payload_cut], "trailing-bytes": base + b"\0\0\0\0",
            "wrong-magic": magic + base[8:]}


#: Where make_files puts the output file in a command.
OUT = object()


def patcher(base, fixer):
    """patched(fmt, at, value, fix=False): `base` with one field overwritten (struct format
    `fmt` at byte `at`), its checksum made right by `fixer` when `fix`."""
    def patched(fmt, at, value, fix=False):
        d = bytearray(base)
        struct.pack_into(fmt, d, at, value)
        return fixer(d) if fix else bytes(d)
    return patched


def make_files(runs, ext, directory, stdout=None, stderr=None):
    """Runs each command of `runs` ({name: argv, OUT where the output file goes}), stores each
    output as NAME.EXT in `directory`; returns {name: its bytes}."""
    made = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, argv in runs.items():
            path = os.path.join(tmp, name + ext)
            subprocess.run([path if a is OUT else a for a in argv], check=True, stdout=stdout, stderr=stderr)
            with open(path, "rb") as f:
                made[name] = f.read()
            with open(os.path.join(directory, name + ext), "wb") as f:
                f.write(made[name])
    return made


def main(brdftool, out):
    tdir, mdir = os.path.join(out, "table"), os.path.join(out, "merl")
    os.makedirs(tdir, exist_ok=True)
    os.makedirs(mdir, exist_ok=True)

    def put(directory, name, data):
        with open(os.path.join(directory, name), "wb") as f:
            f.write(data)

    tables = {
        "lambert-30": ["tabulate", "lambert rho=0.5", "--step", "30"],
        "lambert-30-fold": ["tabulate", "lambert rho=0.5", "--step", "30", "--fold"],
        "phong-15-grey": ["tabulate", "phong_normalized kd=0.2 ks=0.5 n=30", "--step", "15", "--channels", "1"],
        "microfacet-30-fold-grey": ["tabulate", "microfacet m=0.3 f=dielectric eta=1.5", "--step", "30",
                                    "--fold", "--channels", "1"],
        "ward-aniso-30-90": ["tabulate", "ward ax=0.05 ay=0.3 rho_s=0.25", "--layout", "aniso",
                             "--step", "30", "--phi-step", "90"],
        "measured-15": ["measured-like", "lambert rho=0.4", "--step", "15", "--missing", "0.1", "--seed", "3"],
        "halfdiff-8x6x10": ["tabulate", "microfacet m=0.2 f=dielectric eta=1.5 kd=0.2 rho_s=0.8", "--layout",
                            "halfdiff", "--nodes", "8,6,10"],
        "halfdiff-6x4x8-grey": ["tabulate", "microfacet m=0.05 f=conductor n=0.2 k=3", "--layout", "halfdiff",
                                "--nodes", "6,4,8", "--channels", "1"],
    }
    good = make_files({name: [brdftool, a[0], a[1], "-o", OUT, *a[2:]] for name, a in tables.items()}, ".brdf", tdir,
                      stdout=subprocess.DEVNULL)

    base = good["lambert-30"]
    off = struct.unpack_from("<I", base, 12)[0]

    patched = patcher(base, refresh_checksum)

    bad = {
        **broken_framing(base, 60, 7, b"PVBRDX\0\0"),
        "version-2": patched("<I", 8, 2),
        "layout-4": patched("<I", 16, 4),
        "channels-2": patched("<I", 20, 2),
        "flags-unknown": patched("<I", 24, 4),
        "n0-huge": patched("<I", 32, 0xFFFFFFFF),
        "n0-one": patched("<I", 32, 1),
        "step-nan": patched("<d", 48, math.nan),
        "payload-bytes-huge": patched("<Q", 80, 1 << 62),
        "nodata-filled-huge": patched("<Q", 96, 1 << 40),
        "description-huge": patched("<I", 104, 1 << 20),
        "reserved-nonzero": patched("<I", 108, 1),
        "checksum-wrong": patched("<Q", 88, 0),
        "value-nan": patched("<f", off + 40, math.nan, fix=True),
        "value-negative": patched("<f", off + 4, -1.0, fix=True),
        "value-inf": patched("<f", off + 8, math.inf, fix=True),
        "all-nan": refresh_checksum(base[:off] + struct.pack("<f", math.nan) * ((len(base) - off) // 4)),
    }
    hd = good["halfdiff-8x6x10"]
    hd_off = struct.unpack_from("<I", hd, 12)[0]

    hd_patched = patcher(hd, refresh_checksum)

    bad.update({
        "hd-folded": hd_patched("<I", 24, 1),
        "hd-n0-one": hd_patched("<I", 32, 1),
        "hd-n1-huge": hd_patched("<I", 36, 9001),
        "hd-n2-huge": hd_patched("<I", 40, 18001),
        "hd-n3-two": hd_patched("<I", 44, 2),
        "hd-step0": hd_patched("<d", 48, 90.0 / 7),
        "hd-step2": hd_patched("<d", 64, 180.0 / 11),
        "hd-step3": hd_patched("<d", 72, 1.0),
        "hd-value-nan": hd_patched("<f", hd_off + 4 * 100, math.nan, fix=True),
        "hd-value-negative": hd_patched("<f", hd_off + 4 * 7, -1.0, fix=True),
    })
    for name, data in bad.items():
        put(tdir, "bad-" + name + ".brdf", data)

    # MERL: dims, then 3 channel-major planes of doubles.
    def merl(dims, fill):
        n = dims[0] * dims[1] * dims[2]
        vals = [fill(c, k) for c in range(3) for k in range(n)]
        return struct.pack("<3i", *dims) + struct.pack("<%dd" % len(vals), *vals)

    put(mdir, "small-2x2x4.binary", merl((2, 2, 4), lambda c, k: 100.0 + 10 * c + k))
    put(mdir, "small-3x4x6.binary", merl((3, 4, 6), lambda c, k: 0.5 * (k % 7) + c))
    put(mdir, "nodata-3x4x6.binary", merl((3, 4, 6), lambda c, k: -1.0 if k % 5 == 0 else 50.0))
    put(mdir, "nan-2x2x4.binary", merl((2, 2, 4), lambda c, k: math.nan if k == 3 else 1.0))
    put(mdir, "all-nodata-2x2x4.binary", merl((2, 2, 4), lambda c, k: -1.0))
    ok = merl((2, 2, 4), lambda c, k: 1.0)
    put(mdir, "bad-empty.binary", b"")
    put(mdir, "bad-header-short.binary", ok[:9])
    put(mdir, "bad-truncated.binary", ok[:-3])
    put(mdir, "bad-trailing.binary", ok + b"\0")
    put(mdir, "bad-dim-zero.binary", struct.pack("<3i", 0, 2, 4) + ok[12:])
    put(mdir, "bad-dim-negative.binary", struct.pack("<3i", 2, -2, 4) + ok[12:])
    put(mdir, "bad-dim-huge.binary", struct.pack("<3i", 4096, 4096, 4096) + ok[12:])
    put(mdir, "bad-dim-standard-short.binary", struct.pack("<3i", 90, 90, 180) + ok[12:])
    put(mdir, "bad-inf.binary", merl((2, 2, 4), lambda c, k: math.inf if k == 5 else 1.0))

    # Exact-profile tables (.ssp, format 6): checksum of the whole file (its own 8 bytes read as
    # zeros) at 24..31, payload offset at 12..15.
    sdir = os.path.join(out, "ssp")
    os.makedirs(sdir, exist_ok=True)
    sstool = os.path.join(os.path.dirname(brdftool), "sstool")

    profiles = {
        "one-node": ["--g", "0", "--eta", "1"],
        "two-by-two": ["--g", "0,0.5", "--eta", "1,1.5"],
        "slabs": ["--g", "0", "--eta", "1.33", "--thickness", "1,4"],
    }
    sgood = make_files({name: [sstool, "build", "-o", OUT, "--albedos", "4", "--photons", "300", "--short-photons", "0",
                               "--threads", "1", "--quiet", *a] for name, a in profiles.items()}, ".ssp", sdir,
                       stderr=subprocess.DEVNULL)
    sb = sgood["one-node"]
    soff = struct.unpack_from("<I", sb, 12)[0]
    sp = patcher(sb, ssp_fix)

    sbad = {
        **broken_framing(sb, 100, 5, b"PVSSPROX"),
        "truncated-axes": sb[:178],
        "version-2": sp("<I", 8, 2, fix=True),
        "flags-unknown": sp("<I", 36, 4, fix=True),
        "flags-slab-one-face": sp("<I", 36, 1, fix=True),
        "g-count-zero": sp("<I", 40, 0, fix=True),
        "albedo-count-huge": sp("<I", 52, 0xFFFFFFFF, fix=True),
        "radial-count-3": sp("<I", 56, 3, fix=True),
        "band-edges-16": sp("<I", 76, 16, fix=True),
        "band-edges-in-slabs": patcher(sgood["slabs"], ssp_fix)("<I", 76, 1, fix=True),
        "rho0-nan": sp("<d", 80, math.nan, fix=True),
        "u-step-zero": sp("<d", 96, 0.0, fix=True),
        "radiance-orders-huge": sp("<d", 152, 1e9, fix=True),
        "g-out-of-range": sp("<d", 168, 1.5, fix=True),
        "oblique-azimuths-1": sp("<I", 160, 1, fix=True),
        "oblique-orders-0": sp("<I", 164, 0, fix=True),
        "oblique-in-slabs": patcher(sgood["slabs"], ssp_fix)("<I", 160, 7, fix=True),
        "oblique-negative": sp("<f", len(sb) - 4, -1.0, fix=True),
        "payload-offset": sp("<I", 12, soff + 16, fix=True),
        "payload-bytes": sp("<Q", 16, 1 << 60, fix=True),
        "checksum-wrong": sp("<Q", 24, 0),
        "header-byte-60": sp("<I", 60, 11),  # radial nodes per decade, checksum left: format 2 missed it
        "total-nan": sp("<f", soff, math.nan, fix=True),
        "total-negative": sp("<f", soff, -0.5, fix=True),
        "band-ratio-negative": sp("<f", len(sb) - 4 * (1 + 7 * 7 * 8), -1.0, fix=True),
        "angle-huge": sp("<f", soff + 24, 1e30, fix=True),
    }
    for name, data in sbad.items():
        put(sdir, "bad-" + name + ".ssp", data)

    # Cost files: FAMILY RATIO lines (shading/src/fit/fit.cpp, parse_costs).
    cdir = os.path.join(out, "costs")
    os.makedirs(cdir, exist_ok=True)
    costs = {
        "measured.txt": b"# trace-time ratio vs stock POV phong (harness/tools/cost.py): sphere 640x640\n"
                        b"# measured 2026-01-01 in 300 s\nlambert 1.0200\noren_nayar 1.0612\nward 1.1000\n"
                        b"lafortune k=1 1.1310\nmicrofacet d=tr 1.3000\n"
                        b"microfacet d=tr g=smith f=conductor 1.5521\ntable 1.2500\n",
        "spaces.txt": b"  lambert\t1.5\r\nward\x0b2\x0c# x\r\n\n\t\n#\nmicrofacet   d=tr  +.5e1\n",
        "repeated.txt": b"lambert 1\nlambert 2\nlamb 3\n",
        "no-newline.txt": b"table 1e-6",
        "empty.txt": b"",
        "bad-one-word.txt": b"lambert\n",
        "bad-ratio-word.txt": b"ok 1\nward x\n",
        "bad-ratio-zero.txt": b"lambert 0\n",
        "bad-ratio-huge.txt": b"lambert 1000001\n",
        "bad-ratio-inf.txt": b"lambert inf\n",
        "bad-ratio-nan.txt": b"lambert nan\n",
        "bad-ratio-overflow.txt": b"lambert 1e999\n",
        "bad-ratio-hex.txt": b"lambert 0x1p2\n",
        "bad-family-utf8.txt": b"lamb\xc3\xa9rt 1.0\n",
        "bad-family-nbsp.txt": b"lambert\xa01.0\n",
        # Regression: the old parser stopped the ratio at a NUL (strtod on c_str) and accepted 1.5.
        "bad-ratio-nul.txt": b"lambert 1.5\x00junk\n",
        # Regression: the old parser took a NUL inside a family as part of the key; the
        # harness's reader could not (not UTF-8 text it splits the same way).
        "bad-family-nul.txt": b"lam\x00bert 1.5\n",
    }
    for name, data in costs.items():
        put(cdir, name, data)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
