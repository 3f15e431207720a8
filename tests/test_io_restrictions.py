"""POV-Ray's I/O restrictions apply to table files.

The fork's ``povray.conf`` (``conf/povray.conf.in`` -> ``build/conf``) says ``restricted``:
scenes may read only the permitted paths and the current directory. POV-Ray 3.7.0.10's unix
front end enforces none of it (four bugs in ``vfe/unix/unixoptions.cpp`` and
``vfeplatform.cpp``): stock still reads ``/etc/passwd`` as happily as a table in
``brdf_data/``. Patch 0008 (``patches/0008-unix-io-restrictions.patch``) fixes them for the fork.

With the fix, POV resolves symlinks before it checks a path, which is why
:func:`harness.core.runner.render` stages files as hard links or copies, never symlinks.

The permitted paths follow Debian's ``povray.conf`` (read ``$HOME``, POV's includes and
examples; read+write the temporary folder and ``.``) plus the fork's folders; the scene's own
folder is readable (patch 0012); a user's ``~/.povray/3.7/povray.conf`` adds paths (0011) and
a user's ``povray.ini`` adds to the fork's (0014); refusals say which path, why and the line
that permits it, with no "Unknown error code" after them (0013); a table that cannot be read
says whether it was found and where POV looked (0003). Those tests run the fork directly in
folders under ``/var/tmp`` (outside the temporary folder the conf permits), each with a
temporary ``HOME`` there.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

from harness.core import exr, runner, tables
from harness.core.paths import repo_root

SCENE = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location -3*z look_at 0 }}
light_source {{ <-3, 4, -5> rgb 1 }}
sphere {{ 0, 1 pigment {{ rgb 1 }} finish {{ brdf_table {{ "{name}" }} }} }}
"""


@pytest.fixture()
def outside_table():
    """A valid table in a directory no permitted path covers (not /tmp's job dir either)."""
    d = Path(tempfile.mkdtemp(prefix="brdf-outside-", dir="/var/tmp"))
    path = d / "outside.brdf"
    shutil.copyfile(tables.tabulated("lambert rho=0.5", step=15.0), path)
    yield path
    shutil.rmtree(d, ignore_errors=True)


def test_conf_is_restricted():
    conf = (repo_root() / "build" / "conf" / "povray" / "3.7" / "povray.conf").read_text()
    body = [ln.split(";")[0].strip() for ln in conf.splitlines()]
    assert "restricted" in body
    assert not any(ln.startswith("read") and ln.endswith("= /") for ln in body)


def test_table_in_the_current_directory_loads(fork):
    path = tables.tabulated("lambert rho=0.5", step=15.0)
    res = runner.render(SCENE.format(name="t.brdf"), fork, width=8, height=8, files={"t.brdf": path})
    assert res.image.max() > 0


def test_table_outside_the_permitted_paths_is_refused(fork, outside_table):
    with pytest.raises(runner.RenderError) as ei:
        runner.render(SCENE.format(name=outside_table), fork, width=8, height=8)
    e = ei.value
    assert (e.file, e.line) == ("scene.pov", 5), e.stderr[-1500:]
    assert f"IO Restrictions prohibit read access to '{outside_table}'" in e.message, e.message
    assert f"reading from '{outside_table}' is not permitted" in e.stderr


def test_symlink_to_a_table_outside_is_refused(fork, outside_table, tmp_path):
    job = tmp_path / "job"
    job.mkdir()
    os.symlink(outside_table, job / "link.brdf")
    with pytest.raises(runner.RenderError) as ei:
        runner.render(SCENE.format(name="link.brdf"), fork, width=8, height=8, workdir=job)
    assert "IO Restrictions prohibit read access" in ei.value.message, ei.value.message


# ---------------------------------------------------------------- where users keep their files

PLAIN = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
{includes}
camera {{ orthographic location <0, 0, -3> direction z right x * 2 up y * 2 }}
light_source {{ <-3, 4, -5> rgb 1 }}
sphere {{ 0, 1 pigment {{ rgb {colour} }} {finish} }}
"""


@pytest.fixture()
def site():
    """A user's world outside the temporary folder: ``home/`` (HOME), ``proj/`` (the current
    folder), ``sib/`` (a sibling with scenes), ``elsewhere/`` (permitted by nothing)."""
    root = Path(tempfile.mkdtemp(prefix="brdf-site-", dir="/var/tmp"))
    for d in ("home", "proj", "sib", "elsewhere"):
        (root / d).mkdir()
    yield root
    shutil.rmtree(root, ignore_errors=True)


def run_fork(fork, site, scene_path, out, *extra, home=None, env_extra=None):
    """The fork on ``scene_path`` from ``site/proj`` with HOME = ``site/home`` (or ``home``)."""
    env = {k: v for k, v in os.environ.items() if k not in ("POVINI", "POVINC")}
    env["HOME"] = str(site / "home") if home is None else home
    env.update(env_extra or {})
    cmd = [str(fork.path), f"+I{scene_path}", f"+O{out}", "+FE32", "-A", "-D", "-V", "-UA", "+W16", "+H16", "+WT1",
           *extra]
    return subprocess.run(cmd, cwd=site / "proj", env=env, capture_output=True, text=True, timeout=120)


def rendered(p, out) -> np.ndarray:
    assert p.returncode == 0, p.stderr[-2500:]
    img = exr.read_exr(out)
    assert img.max() > 0.05
    return img


def test_conf_follows_debian_and_adds_the_forks_folders():
    conf = (repo_root() / "build" / "conf" / "povray" / "3.7" / "povray.conf").read_text()
    body = {ln.split(";")[0].strip() for ln in conf.splitlines()} - {""}
    debian = {ln.split(";")[0].strip() for ln in Path("/etc/povray/3.7/povray.conf").read_text().splitlines()
              if ln.strip().startswith("read")} if Path("/etc/povray/3.7/povray.conf").is_file() else set()
    # Debian's entries (its %INSTALLDIR% is /usr/share/povray-3.7; it writes `.` without descent)
    want = {"read* = /usr/share/povray-3.7/include", "read* = /usr/share/doc/povray/examples", "read* = /etc/povray",
            "read* = %HOME%", "read+write* = /tmp", "read+write* = %TMPDIR%", "read+write* = ."}
    assert want <= body
    assert {d.replace("%INSTALLDIR%", "/usr/share/povray-3.7").replace("read+write  = .", "read+write = .")
            for d in debian} - {"read+write = ."} <= body
    top = repo_root()
    for d in ("scenes", "brdf_data", "build/brdf_data", "build/conf"):
        assert f"read* = {top}/{d}" in body
    assert f"read+write* = {top}/out" in body


def test_scene_in_a_sibling_folder_with_output_to_the_temporary_folder(fork, site):
    (site / "sib" / "plain.pov").write_text(PLAIN.format(includes="", colour="<1, 0.5, 0.2>", finish=""))
    out = Path(tempfile.gettempdir()) / f"brdf-site-{os.getpid()}.exr"
    try:
        p = run_fork(fork, site, "../sib/plain.pov", out)
        img = rendered(p, out)
        assert img[8, 8, 0] > img[8, 8, 2]  # the scene's own colour
    finally:
        out.unlink(missing_ok=True)


def test_include_under_home_renders_and_one_elsewhere_is_refused(fork, site):
    for d in ("home/inc", "elsewhere"):
        (site / d).mkdir(exist_ok=True)
        (site / d / "mine.inc").write_text("#declare C = <0.2, 0.9, 0.4>;\n")
    (site / "sib" / "inc.pov").write_text(PLAIN.format(includes='#include "mine.inc"', colour="C", finish=""))
    out = site / "proj" / "inc.exr"
    rendered(run_fork(fork, site, "../sib/inc.pov", out, f"+L{site / 'home' / 'inc'}"), out)
    out.unlink()
    p = run_fork(fork, site, "../sib/inc.pov", out, f"+L{site / 'elsewhere'}")
    assert p.returncode != 0 and not out.exists()
    inc = site / "elsewhere" / "mine.inc"
    # which path, why, and the line that permits it (in the user's conf, which adds paths)
    assert f"reading from '{inc}' is not permitted: the I/O restrictions permit reading only" in p.stderr, p.stderr
    assert f"[Permitted Paths] in {site / 'home' / '.povray' / '3.7' / 'povray.conf'}" in p.stderr
    assert f'read* = "{site / "elsewhere"}"' in p.stderr
    assert "Unknown error code" not in p.stderr


def test_refused_output_says_why_and_how_and_no_unknown_error_code(fork, site):
    (site / "proj" / "plain.pov").write_text(PLAIN.format(includes="", colour="1", finish=""))
    out = site / "elsewhere" / "o.exr"
    p = run_fork(fork, site, "plain.pov", out)
    assert p.returncode != 0 and not out.exists()
    err = p.stderr
    assert f"writing to '{out}' is not permitted: the I/O restrictions permit writing only into the read+write" in err
    assert f'read+write* = "{site / "elsewhere"}"' in err
    assert f"IO Restrictions prohibit write access to '{out}'" in err  # POV's own message, printed once
    assert err.count("IO Restrictions prohibit write access") == 1
    assert "Unknown error code" not in err
    assert "cannot open the user configuration file" not in err  # a user conf is optional


def test_user_conf_adds_a_folder_and_keeps_the_forks(fork, site):
    (site / "elsewhere" / "mine.inc").write_text("#declare C = <0.9, 0.9, 0.2>;\n")
    shutil.copyfile(tables.tabulated("lambert rho=0.5", step=15.0), site / "elsewhere" / "mine.brdf")
    conf = site / "home" / ".povray" / "3.7" / "povray.conf"
    conf.parent.mkdir(parents=True)
    conf.write_text(f"[File I/O Security]\nrestricted\n[Permitted Paths]\nread* = \"{site / 'elsewhere'}\"\n")
    # the user's folder, the fork's include files (its povray.ini must stay readable) and its tables
    two = PLAIN.format(includes='#include "mine.inc"\n#include "brdf_metals.inc"', colour="C",
                       finish="finish { F_BRDF_Gold_Polished }")
    two += f'sphere {{ <0.5, 0.5, -1>, 0.3 finish {{ brdf_table {{ "{site / "elsewhere" / "mine.brdf"}" }} }} }}\n'
    two += 'sphere { <-0.5, -0.5, -1>, 0.3 finish { brdf_table { "gold.brdf" } } }\n'
    (site / "proj" / "two.pov").write_text(two)
    out = site / "proj" / "two.exr"
    p = run_fork(fork, site, "two.pov", out, f"+L{site / 'elsewhere'}")
    rendered(p, out)
    assert "BRDF tables:" in p.stderr


def test_user_ini_adds_to_the_forks_ini(fork, site):
    (site / "elsewhere" / "mine.inc").write_text("#declare C = <0.9, 0.3, 0.2>;\n")
    cfg = site / "home" / ".povray" / "3.7"
    cfg.mkdir(parents=True)
    (cfg / "povray.conf").write_text(f"[Permitted Paths]\nread* = {site / 'elsewhere'}\n")
    (cfg / "povray.ini").write_text(f"Library_Path={site / 'elsewhere'}\n")
    (site / "proj" / "ini.pov").write_text(PLAIN.format(includes='#include "mine.inc"\n#include "brdf_metals.inc"',
                                                          colour="C", finish="finish { F_BRDF_Copper_Satin }"))
    out = site / "proj" / "ini.exr"
    rendered(run_fork(fork, site, "ini.pov", out), out)  # no +L: both from the two INI files


def test_home_entry_without_home_is_ignored(fork, site):
    """Debian's `read* = %HOME%` must not become `read* = /` when HOME is unset."""
    (site / "elsewhere" / "mine.inc").write_text("#declare C = 1;\n")
    (site / "proj" / "h.pov").write_text(PLAIN.format(includes=f'#include "{site / "elsewhere" / "mine.inc"}"',
                                                        colour="C", finish=""))
    p = run_fork(fork, site, "h.pov", site / "proj" / "h.exr", home="")
    assert "ignored entry: it names %HOME% and HOME is not set" in p.stderr, p.stderr[-2000:]
    assert p.returncode != 0 and f"reading from '{site / 'elsewhere' / 'mine.inc'}' is not permitted" in p.stderr


def test_missing_table_says_where_it_looked(fork, site):
    (site / "proj" / "m.pov").write_text(PLAIN.format(includes="", colour="1",
                                                      finish='finish { brdf_table { "no-such.brdf" } }'))
    p = run_fork(fork, site, "m.pov", site / "proj" / "m.exr", f"+L{site / 'elsewhere'}")
    msg, f, line = runner.parse_error(p.stderr)
    assert (f, line) == ("m.pov", 6), p.stderr[-1500:]
    assert msg.startswith(f"Parse Error: brdf_table: cannot read 'no-such.brdf': not found: looked in the current "
                          f"folder ({site / 'proj'}) and the library paths "), msg
    assert f"{repo_root()}/build/brdf_data" in msg and str(site / "elsewhere") in msg
    assert "+L<folder>" in msg


# ---------------------------------------------------------------- writes from the scene (#fopen)

FOPEN = """#version 3.7;
global_settings {{ assumed_gamma 1.0 }}
camera {{ location -3*z look_at 0 }}
light_source {{ <-3, 4, -5> rgb 1 }}
#fopen Log "{path}" write
#write (Log, "written by the scene\\n")
#fclose Log
sphere {{ 0, 1 pigment {{ rgb 1 }} }}
"""


def test_scene_write_outside_the_permitted_paths_is_refused(fork, site):
    # Debian's conf permits writing only into the temporary folder and the current one; a
    # scene's #fopen ... write elsewhere is refused at its line and nothing is written.
    target = site / "elsewhere" / "leak.txt"
    (site / "proj" / "w.pov").write_text(FOPEN.format(path=target))
    out = site / "proj" / "w.exr"
    p = run_fork(fork, site, "w.pov", out)
    assert p.returncode != 0, p.stderr[-2000:]
    assert not target.exists() and not out.exists()
    err = p.stderr
    assert f"writing to '{target}' is not permitted" in err, err[-2000:]
    assert f'read+write* = "{site / "elsewhere"}"' in err  # the line that would permit it
    assert "File 'w.pov' line 5: Possible Parse Error: IO Restrictions prohibit write access" in err  # the #fopen
    assert "Unknown error code" not in p.stderr


@pytest.mark.parametrize("where", ["current folder", "temporary folder"])
def test_scene_write_inside_the_permitted_paths_is_allowed(fork, site, where):
    if where == "current folder":
        target = site / "proj" / "log.txt"
    else:
        target = Path(tempfile.gettempdir()) / f"brdf-fopen-{os.getpid()}.txt"
    (site / "proj" / "w.pov").write_text(FOPEN.format(path=target))
    out = site / "proj" / "w.exr"
    try:
        p = run_fork(fork, site, "w.pov", out)
        rendered(p, out)
        assert target.read_text() == "written by the scene\n"
    finally:
        target.unlink(missing_ok=True)


# ---------------------------------------------------------------- pipes, devices (0016)

@pytest.mark.parametrize("how", ["scene", "include"])
def test_a_fifo_is_refused_at_once_not_read(fork, site, how):
    """Upstream (and Debian's stock) hang on a FIFO given as the scene or an include file:
    opening it waits for a writer. The fork refuses it before opening it."""
    fifo = site / "proj" / ("f.pov" if how == "scene" else "f.inc")
    os.mkfifo(fifo)
    if how == "include":
        (site / "proj" / "s.pov").write_text(PLAIN.format(includes='#include "f.inc"', colour="1", finish=""))
    p = run_fork(fork, site, fifo.name if how == "scene" else "s.pov", site / "proj" / "o.exr")  # timeout 120 s
    assert p.returncode != 0
    assert f"reading from '{fifo.name}' refused: it is a FIFO (named pipe), not a regular file" in p.stderr, \
        p.stderr[-1500:]


def test_a_device_is_not_read_as_an_include_file(fork, site):
    (site / "proj" / "z.pov").write_text(PLAIN.format(includes='#include "/dev/zero"', colour="1", finish=""))
    p = run_fork(fork, site, "z.pov", site / "proj" / "o.exr")
    assert p.returncode != 0
    assert "reading from '/dev/zero' refused: it is a character device, not a regular file" in p.stderr, \
        p.stderr[-1500:]


# ---------------------------------------------------------------- library path order (0018)

def test_the_users_library_folders_come_before_the_forks_own(fork, site):
    """A user's +L folder with a table named like one of the fork's ready tables (gold.brdf)
    is the one the scene gets; POV's standard include folder still comes first (stock's order)."""
    mine = site / "home" / "mine"
    mine.mkdir()
    shutil.copyfile(tables.tabulated("lambert rho=0.5", step=15.0), mine / "gold.brdf")
    (mine / "colors.inc").write_text("#declare Red = <0, 0, 1>;\n")  # must not shadow POV's own
    def scene(t):
        return PLAIN.format(includes='#include "colors.inc"', colour="Red", finish=f'finish {{ brdf_table {{ "{t}" }} }}')
    out = site / "proj" / "o.exr"
    (site / "proj" / "by_name.pov").write_text(scene("gold.brdf"))
    (site / "proj" / "by_path.pov").write_text(scene(mine / "gold.brdf"))
    by_name = rendered(run_fork(fork, site, "by_name.pov", out, f"+L{mine}"), out)
    out.unlink()
    by_path = rendered(run_fork(fork, site, "by_path.pov", out, f"+L{mine}"), out)
    out.unlink()
    fork_gold = rendered(run_fork(fork, site, "by_name.pov", out), out)
    assert np.array_equal(by_name, by_path)          # the user's gold.brdf
    assert not np.allclose(by_name, fork_gold, atol=1e-3)  # not the fork's
    # the table's grey plus ambient 0.1 x pigment: POV's Red <1, 0, 0>, not the user's <0, 0, 1>
    assert by_name[8, 8, 0] - by_name[8, 8, 2] > 0.05, by_name[8, 8]
