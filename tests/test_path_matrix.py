"""No way out of the permitted folders: every entry point x every path form
(:mod:`harness.reports.path_matrix`), attacked from a scene three folders below a project.

Patch 0015 (``patches/0015-unix-canonical-paths.patch``) walks a path as the kernel does before
the I/O restrictions compare it with the permitted folders; upstream's canonicaliser let
``a/b/c/../../..`` keep a ``..`` and climb out. The fast test attacks the fork with the forms
upstream got wrong (consecutive ``..`` relative and after an absolute permitted prefix, ``..``
after a symlink, a symlink loop, a name beginning with ``..``) through every entry point.
``make test-security`` runs the whole matrix on the fork and on Debian's stock binary and
prints both columns (``python -m harness.reports.path_matrix``: exit 1 if the fork lets one
through or refuses a permitted case).
"""

from __future__ import annotations

import pytest

from harness.core import tables
from harness.reports import path_matrix as pm

FAST_FORMS = ("consecutive ..", "consecutive .. below /tmp", "abs. permitted prefix + ..", ".. after a symlink", "symlink loop",
              "name beginning with ..", "symlink inside + ..")


@pytest.fixture(scope="module")
def table():
    return tables.tabulated("lambert rho=0.5", step=15.0)


def _check(outcomes):
    bad = [f"{o.entry} / {o.form}: {'escaped' if o.escaped else 'refused'} ({o.detail})"
           for o in outcomes if not o.ok]
    assert bad == [], pm.format_matrix(outcomes)
    # a refusal is the restrictions' (or the file system's), never a hang
    assert all(o.returncode is not None for o in outcomes)


def test_the_forms_upstream_got_wrong_cannot_escape_through_any_entry_point(fork, table):
    forms = [f for f in pm.FORMS if f.name in FAST_FORMS]
    assert len(forms) == len(FAST_FORMS)
    outcomes = pm.run_matrix([fork], table=table, forms=forms, jobs=3)
    assert len(outcomes) == len(pm.ENTRIES) * len(forms)
    _check(outcomes)
    # the escapes were refused by the I/O restrictions, and the refusal names the file
    consec = [o for o in outcomes if o.form == "consecutive .." and o.entry == "#include"]
    assert "reading from '../../../../secret/y.inc'" in consec[0].detail, consec[0].detail
    assert "is not permitted" in consec[0].detail
