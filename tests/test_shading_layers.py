"""The shading library's layers hold: ``shading/tools/check_layers.py`` (also ctest's
``layers.includes``) passes on the tree and the patches, and fails, naming the file, the line and
what the rule allows, on a tree with one include that runs upward, one that runs sideways
(tables <-> subsurface), one by a bare name, and on a patch that includes more than the facade.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CHECK = ROOT / "shading" / "tools" / "check_layers.py"


def run(*args):
    return subprocess.run([sys.executable, str(CHECK), *map(str, args)], capture_output=True, text=True)


def test_tree_and_patches_keep_the_rule():
    r = run(ROOT / "shading", ROOT / "patches")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "keep the include rule" in r.stdout


@pytest.fixture
def copy(tmp_path):
    dst = tmp_path / "shading"
    shutil.copytree(ROOT / "shading", dst, ignore=shutil.ignore_patterns("fuzz", "tests", "tools", "*.md"))
    return dst


def add_include(path: Path, include: str):
    text = path.read_text()
    path.write_text(include + "\n" + text)


@pytest.mark.parametrize("file, include, expect", [
    # upward: the brdf layer reaching into the finish facade
    ("src/brdf/brdf.cpp", '#include "shading/finish/finish.h"',
     'src/brdf/brdf.cpp:1: layer brdf includes "shading/finish/finish.h" from layer finish; brdf may include only brdf, core'),
    # upward from the ground floor
    ("include/shading/core/vec.h", '#include "shading/brdf/brdf.h"',
     'include/shading/core/vec.h:1: layer core includes "shading/brdf/brdf.h" from layer brdf; core may include only core'),
    # sideways: tables and subsurface stand on the same floor
    ("src/subsurface/ss_profile.cpp", '#include "shading/tables/table.h"',
     'src/subsurface/ss_profile.cpp:1: layer subsurface includes "shading/tables/table.h" from layer tables'),
    # a bare private name hides which layer it comes from
    ("src/tables/merl.cpp", '#include "bytes.h"', 'src/tables/merl.cpp:1: includes "bytes.h" by a bare name'),
    # the old flat path names no layer
    ("src/fit/fit.cpp", '#include "shading/table.h"', 'src/fit/fit.cpp:1: includes "shading/table.h", which names no layer'),
])
def test_a_broken_rule_is_named(copy, file, include, expect):
    add_include(copy / file, include)
    r = run(copy)
    assert r.returncode == 1
    assert expect in r.stdout, r.stdout
    assert "1 include(s) break the layer rule" in r.stderr


def test_a_file_outside_the_layer_folders_is_named(copy):
    (copy / "src" / "stray.cpp").write_text("int x;\n")
    r = run(copy)
    assert r.returncode == 1 and "src/stray.cpp: stands in no layer folder" in r.stdout


def test_a_patch_that_reaches_past_the_facade_is_named(tmp_path):
    patches = tmp_path / "patches"
    shutil.copytree(ROOT / "patches", patches)
    (patches / "9999-test.patch").write_text('--- a/x.cpp\n+++ b/x.cpp\n@@ -1 +1,2 @@\n+#include "shading/tables/table.h"\n x\n')
    r = run(ROOT / "shading", patches)
    assert r.returncode == 1
    assert '9999-test.patch:4: a POV-Ray patch includes "shading/tables/table.h"' in r.stdout
