"""Bad values of the fork's finish keywords are POV-style scene errors at the right file and line.

Every case renders a one-sphere scene whose finish sits on line 5 and checks the
:class:`harness.core.runner.RenderError`: POV's message (what was wrong, in the loader's
``NAME: offset N: expected X, found Y`` form for table files), ``file == "scene.pov"`` and
``line == 5``. Broken tables are made from a valid 15-degree table (header fields patched,
the checksum refreshed where the point is to reach a later check).

``tests/test_brdf_finish.py`` already covers a missing file, a non-table file, a truncated
table, ``interpolate 2``, an unknown microfacet ``d=`` and ``interpolate`` in ``brdf_model``;
``tests/test_analytic_finishes.py`` covers ``samples`` -1 / 2.5 / 5000 in ``brdf_model``.
A directory named as a table, an infinite scale and a fractional interpolate were bugs of
patch 0003, found here and fixed there.
"""

from __future__ import annotations

import math
import struct

import pytest

from harness.core import runner, tables
from harness.core.brdf_io import fnv1a64

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location -3*z look_at 0 }}
light_source {{ <-3, 4, -5> rgb 1 }}
sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ {finish} }} }}
"""
LINE = 5



@pytest.fixture(scope="module")
def table_files(tmp_path_factory):
    good = tables.tabulated("lambert rho=0.5", step=15.0).read_bytes()
    off = struct.unpack_from("<I", good, 12)[0]

    def patched(fmt, at, value, refresh=False):
        d = bytearray(good)
        struct.pack_into(fmt, d, at, value)
        if refresh:
            struct.pack_into("<Q", d, 88, fnv1a64(bytes(d[off:])))
        return bytes(d)

    files = {
        "good.brdf": good,
        "empty.brdf": b"",
        "header-only.brdf": good[:50],
        "wrong-magic.brdf": b"PVBRDX\0\0" + good[8:],
        "version-2.brdf": patched("<I", 8, 2),
        "layout-4.brdf": patched("<I", 16, 4),  # 3 is the half/difference layout
        "nodes-huge.brdf": patched("<I", 32, 0xFFFFFFFF),
        "payload-huge.brdf": patched("<Q", 80, 1 << 62),
        "half.brdf": good[:len(good) // 2],
        "trailing.brdf": good + b"\0" * 4,
        "checksum.brdf": good[:off] + bytes([good[off] ^ 1]) + good[off + 1:],
        "nan.brdf": patched("<f", off + 8, math.nan, refresh=True),
        "negative.brdf": patched("<f", off + 8, -0.5, refresh=True),
        "inf.brdf": patched("<f", off + 8, math.inf, refresh=True),
    }
    hd = bytearray(tables.tabulated_halfdiff("lambert rho=0.5", (8, 8, 8)).read_bytes())
    struct.pack_into("<I", hd, 24, 1)  # the folded flag on a half/difference table
    files["halfdiff-folded.brdf"] = bytes(hd)
    d = tmp_path_factory.mktemp("tables")
    paths = {}
    for name, data in files.items():
        (d / name).write_bytes(data)
        paths[name] = d / name
    (d / "a-directory").mkdir()
    paths["a-directory.brdf"] = d / "a-directory"
    return paths


def scene_error(fork, finish, files=None):
    with pytest.raises(runner.RenderError) as ei:
        runner.render(SCENE.format(finish=finish), fork, width=8, height=8, files=files)
    e = ei.value
    assert (e.file, e.line) == ("scene.pov", LINE), f"{e.file} line {e.line}: {e.message}\n{e.stderr[-1500:]}"
    return e.message


# ---------------------------------------------------------------- brdf_table files

@pytest.mark.parametrize("name, message", [
    ("empty.brdf", "brdf_table: empty.brdf: offset 0: expected 112-byte header, found end of data after 0 bytes"),
    ("header-only.brdf", "brdf_table: header-only.brdf: offset 50: expected 112-byte header, found end of data after 50"),
    ("wrong-magic.brdf", 'brdf_table: wrong-magic.brdf: offset 0: expected magic "PVBRDF\\x00\\x00", found "PVBRDX\\x00\\x00"'),
    ("version-2.brdf", "brdf_table: version-2.brdf: offset 8: expected version 1, found 2"),
    ("layout-4.brdf", "offset 16: expected layout 1 (isotropic), 2 (anisotropic) or 3 (half/difference), found 4"),
    ("halfdiff-folded.brdf", "offset 24: expected no reciprocity-folded flag on a half/difference table"),
    ("nodes-huge.brdf", "offset 32: expected theta_i node count in [2, 9001], found 4294967295"),
    ("payload-huge.brdf", "offset 80: expected payload size 7644 bytes"),
    ("half.brdf", "brdf_table: half.brdf: offset 3894: expected 7788 bytes (7644-byte payload at offset 144), found end of data"),
    ("trailing.brdf", "offset 7788: expected end of data, found 4 trailing bytes"),
    ("checksum.brdf", "offset 88: expected payload FNV-1a-64"),
    ("nan.brdf", "offset 152: expected a value >= 0 at theta_i=0 theta_r=0 phi=0 deg, channel 2 (no-data policy: reject), found nan"),
    ("negative.brdf", "offset 152: expected a value >= 0 at theta_i=0 theta_r=0 phi=0 deg, channel 2 (no-data policy: reject), found -0.5"),
    ("inf.brdf", "offset 152: expected a finite value at theta_i=0 theta_r=0 phi=0 deg, channel 2, found inf"),
])
def test_broken_table(fork, table_files, name, message):
    msg = scene_error(fork, f'brdf_table {{ "{name}" }}', table_files)
    assert message in msg, msg


def test_table_named_by_a_missing_absolute_path(fork):
    msg = scene_error(fork, 'brdf_table { "/nonexistent/dir/gold.brdf" }')
    assert "cannot read '/nonexistent/dir/gold.brdf'" in msg, msg


def test_directory_as_table_is_an_error_at_the_line(fork, table_files):
    msg = scene_error(fork, 'brdf_table { "a-directory.brdf" }', table_files)
    assert msg.startswith("Parse Error: brdf_table:"), msg


def test_directory_as_table_names_the_file(fork, table_files):
    msg = scene_error(fork, 'brdf_table { "a-directory.brdf" }', table_files)
    assert "brdf_table: a-directory.brdf: offset 0: expected a .brdf file, found a folder: give the path of a " \
           "table file in it" in msg, msg  # not "9223372036854775807 bytes (a directory?)"


def test_a_sample_spacing_far_too_small_says_what_to_do_and_no_uncategorized_error(fork):
    """Refused when the render builds the object's point cloud: one message, then POV's
    parameter error (it was "Uncategorized error.", patch 0006)."""
    with pytest.raises(runner.RenderError) as ei:
        runner.render(SCENE.format(finish='dipole { "Marble" profile dipole sample_spacing 1e-9 }'), fork,
                      width=8, height=8)
    err = " ".join(ei.value.stderr.split())
    assert "dipole: a sample spacing of 1e-09 units needs 1.2e+19 sample lines across an object 2 units wide " \
           "(at most 5e7): give a larger sample_spacing" in err, err[-1500:]
    assert err.count("give a larger sample_spacing") == 1
    assert "Uncategorized error" not in err


# ---------------------------------------------------------------- brdf_table / brdf_model options

@pytest.mark.parametrize("finish, message", [
    ('brdf_table { "good.brdf" interpolate -1 }', "interpolate must be 0 (nearest node) or 1 (trilinear), found -1"),
    ('brdf_table { "good.brdf" scale -1 }', "brdf_table: scale must be finite, >= 0 and at most 1e6, found"),
    ('brdf_table { "good.brdf" scale <1, -0.1, 1> }', "brdf_table: scale must be finite, >= 0 and at most 1e6, found"),
    ('brdf_model { "lambert" scale (1e308*10)-(1e308*10) }', "brdf_model: scale must be finite, >= 0 and at most 1e6, found"),
    ('brdf_table { "good.brdf" samples -1 }', "brdf_table: samples must be a whole number from 0 (off) to 4096, found -1."),
    ('brdf_model { "lambert" samples (1e308*10)-(1e308*10) }', "brdf_model: samples must be a whole number"),
    ('brdf_model { "lambert" scale 1e308*10 }', "brdf_model: scale must be finite, >= 0 and at most 1e6, found"),
    ('brdf_model { "lambert rho=1" scale 3e38 }', "brdf_model: scale must be finite, >= 0 and at most 1e6, found <3e+38, 3e+38, 3e+38>"),
    ('brdf_table { "good.brdf" interpolate 0.5 }', "interpolate must be 0 (nearest node) or 1 (trilinear), found 0.5"),
])
def test_bad_option(fork, table_files, finish, message):
    msg = scene_error(fork, finish, table_files)
    assert message in msg, msg


# ---------------------------------------------------------------- brdf_model specs

@pytest.mark.parametrize("spec, message", [
    ("", "brdf_model: make_brdf: empty spec; expected '<model> key=value ...'"),
    ("nosuchmodel", "brdf_model: make_brdf: unknown model 'nosuchmodel'; known: lambert,"),
    ("lambert colour=1", "lambert: unknown key 'colour'"),
    ("lambert rho=0.5 rho=0.6", "lambert: key 'rho': given more than once"),
    ("lambert rho=", "lambert: key 'rho': empty number"),
    ("lambert rho=abc", "lambert: key 'rho': not a number: 'abc'"),
    ("lambert rho=1,2", "lambert: key 'rho': expected a scalar or r,g,b triple, got 2 numbers"),
    ("lambert rho=2", "lambert: key 'rho': value 2 out of range [0, 1]"),
    ("microfacet m=0", "microfacet: key 'm': value 0 out of range [0.0001, 1]"),
    ("microfacet m=nan", "microfacet: key 'm': not finite: 'nan'"),
    ("microfacet m=inf", "microfacet: key 'm': not finite: 'inf'"),
    ("microfacet f=dielectric eta=0", "microfacet: key 'eta': value 0 out of range [0.01, 10]"),
    ("microfacet f=dielectric eta=-1", "microfacet: key 'eta': value -1 out of range [0.01, 10]"),
    ("microfacet f=conductor", "microfacet: key 'n': required"),
    ("microfacet f=conductor n=0.2", "microfacet: key 'k': required"),
    ("microfacet f=conductor k=3", "microfacet: key 'n': required"),
    ("ward ax=0 ay=0.1", "ward: key 'ax': value 0 out of range"),
])
def test_bad_model_spec(fork, spec, message):
    msg = scene_error(fork, f'brdf_model {{ "{spec}" }}')
    assert message in msg, msg


# ---------------------------------------------------------------- errors inside an include file

INCLUDE = """// materials of a user's own include file
#declare F_Paint = finish {{
  diffuse 0.2
  {finish}
}}
"""
INCLUDE_LINE = 4
SCENE_WITH_INCLUDE = """#version 3.7;
global_settings { assumed_gamma 1.0 }
#include "materials.inc"
camera { location -3*z look_at 0 }
light_source { <-3, 4, -5> rgb 1 }
sphere {
  0, 1
  pigment { rgb 1 }
  finish { F_Paint }
}
"""


@pytest.mark.parametrize("finish, message", [
    ('brdf_model { "lambert rho=2" }', "lambert: key 'rho': value 2 out of range [0, 1]"),
    ('brdf_table { "negative.brdf" }', "negative.brdf: offset 152: expected a value >= 0"),
    ('brdf_model { "lambert" samples 5000 }', "brdf_model: samples must be a whole number from 0 (off) to 4096"),
    ('dipole { sigma_s_prime -1 sigma_a 0.1 }', "dipole medium: sigma_s.r = -1: expected a finite value >= 0 (1/mm)"),
])
def test_error_in_an_included_file_names_that_file_and_line(fork, table_files, tmp_path, finish, message):
    """The finish is declared over several lines of an include file and used in the scene: the
    error points at the include file and the line of the bad keyword, not at scene.pov."""
    inc = tmp_path / "materials.inc"
    inc.write_text(INCLUDE.format(finish=finish))
    with pytest.raises(runner.RenderError) as ei:
        runner.render(SCENE_WITH_INCLUDE, fork, width=8, height=8,
                      files={**table_files, "materials.inc": inc})
    e = ei.value
    assert (e.file, e.line) == ("materials.inc", INCLUDE_LINE), f"{e.file} line {e.line}: {e.message}"
    assert message in e.message, e.message
