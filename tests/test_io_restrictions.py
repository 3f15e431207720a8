"""POV-Ray's I/O restrictions apply to table files.

The fork's ``povray.conf`` (``conf/povray.conf.in`` -> ``build/conf``) says ``restricted``:
scenes may read only the permitted paths and the current directory. POV-Ray 3.7.0.10's unix
front end enforces none of it (four bugs in ``vfe/unix/unixoptions.cpp`` and
``vfeplatform.cpp``): stock still reads ``/etc/passwd`` as happily as a table in
``brdf_data/``. Patch 0008 (``patches/0008-unix-io-restrictions.patch``) fixes them for the fork.

With the fix, POV resolves symlinks before it checks a path, which is why
:func:`harness.core.runner.render` stages files as hard links or copies, never symlinks.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

from harness.core import runner, tables
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
