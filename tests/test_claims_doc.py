"""``docs/claims.md`` is kept true by this test (issue 19).

Every row of the claims table names the test that proves the claim (a pytest node id, or
``ctest Suite.Name`` for a unit test), the tolerance as ``NAME = value`` where NAME is the
constant that test asserts (read from the test module, or from the C++ test source), and the
measured value. A row fails when its test is gone, when the written tolerance differs from
the constant, or when the measured value is outside the tolerance (above it; below it for a
row marked ``(at least)``, a negative control's minimum).
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import pytest

from harness.core.paths import REPO_ROOT

CLAIMS = REPO_ROOT / "docs" / "claims.md"
HEADER = ["claim", "test", "tolerance", "measured"]
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


@dataclass
class Row:
    line: int
    claim: str
    test: str
    tolerance: str
    measured: str


def parse(text: str) -> list[Row]:
    """The rows of every table whose header is ``| claim | test | tolerance | measured |``."""
    rows, in_table = [], False
    for no, line in enumerate(text.splitlines(), 1):
        cells = [c.strip() for c in line.strip().strip("|").split("|")] if line.lstrip().startswith("|") else None
        if cells is None:
            in_table = False
            continue
        if [c.lower() for c in cells] == HEADER:
            in_table = True
            continue
        if in_table and not set("".join(cells)) <= set("-: "):
            if len(cells) != 4:
                raise ValueError(f"claims.md:{no}: expected 4 cells, found {len(cells)}")
            rows.append(Row(no, *cells))
    return rows


def _code(cell: str) -> str:
    m = re.fullmatch(r"`([^`]+)`", cell)
    if not m:
        raise ValueError(f"expected one `code` span, found {cell!r}")
    return m[1]


def _module(path: Path):
    """The test module at path, imported as ``tests.<stem>`` (the repository root is on the path)."""
    return importlib.import_module(f"tests.{path.stem}")


_MODULES: dict[Path, object] = {}


def resolve_test(test: str, root: Path = REPO_ROOT) -> tuple[str, object]:
    """('pytest', module) or ('ctest', source text of the file that defines the test); raises
    LookupError when the test does not exist."""
    if test.startswith("ctest "):
        suite, _, name = test[len("ctest "):].partition(".")
        pat = re.compile(rf"\bTEST(?:_F|_P)?\(\s*{re.escape(suite)}\s*,\s*{re.escape(name)}\s*\)")
        for cpp in sorted((root / "shading" / "tests").glob("*.cpp")):
            text = cpp.read_text()
            if pat.search(text):
                return "ctest", text
        raise LookupError(f"no TEST({suite}, {name}) in shading/tests/*.cpp")
    file, sep, node = test.partition("::")
    path = root / file
    if not sep or not path.is_file():
        raise LookupError(f"no test file {file}")
    func = node.split("[")[0].split("::")[-1]
    if path not in _MODULES:
        _MODULES[path] = _module(path)
    mod = _MODULES[path]
    if "::" in node:  # Class::test
        cls = getattr(mod, node.split("::")[0], None)
        ok = cls is not None and hasattr(cls, func)
    else:
        ok = callable(getattr(mod, func, None))
    if not ok:
        raise LookupError(f"{file} has no test {node}")
    return "pytest", mod


def constant(kind: str, where: object, name: str) -> float:
    if kind == "pytest":
        if not hasattr(where, name):  # the suite's shared tolerances live in conftest.py
            conf = REPO_ROOT / "tests" / "conftest.py"
            if conf not in _MODULES:
                _MODULES[conf] = _module(conf)
            where = _MODULES[conf]
        if not hasattr(where, name):
            raise LookupError(f"the test module (and conftest.py) has no constant {name}")
        return float(getattr(where, name))
    m = re.search(rf"\b{re.escape(name)}\s*=\s*({NUMBER})\s*;", where)
    if not m:
        raise LookupError(f"the C++ test source has no constant {name} = <number>;")
    return float(m[1])


def check(row: Row, root: Path = REPO_ROOT) -> Optional[str]:
    """None when the row holds, else what is wrong."""
    try:
        kind, where = resolve_test(_code(row.test), root)
        tol = row.tolerance
        if tol.lower().startswith("exact"):
            if row.measured.split()[0] not in ("0", "exact", "equal", "identical"):
                return f"exact claim with measured value {row.measured!r}"
            m = re.search(r"`([A-Za-z_]\w*)`", tol)
            if m and constant(kind, where, m[1]) != 0:
                return f"{m[1]} is not 0 in the test"
            return None
        m = re.fullmatch(rf"`([A-Za-z_]\w*)` = ({NUMBER})(?: \(at least\))?", tol)
        if not m:
            return f"tolerance {tol!r} is not `NAME` = value [(at least)]"
        name, written = m[1], float(m[2])
        actual = constant(kind, where, name)
        if abs(actual - written) > 1e-12 * max(abs(actual), 1e-300):
            return f"the row says {name} = {written:g}, the test asserts {actual:g}"
        mm = re.match(NUMBER, row.measured)
        if not mm:
            return f"measured value {row.measured!r} is not a number"
        measured = float(mm[0])
        lower = tol.endswith("(at least)")
        if lower and not measured >= written:
            return f"measured {measured:g} is below the minimum {written:g}"
        if not lower and not measured <= written:
            return f"measured {measured:g} is above the tolerance {written:g}"
    except (LookupError, ValueError) as e:
        return str(e)
    return None


ROWS = parse(CLAIMS.read_text()) if CLAIMS.is_file() else []


def test_claims_table_exists_and_is_not_trivial():
    assert CLAIMS.is_file()
    assert len(ROWS) >= 30
    assert len({r.test for r in ROWS}) >= 20


@pytest.mark.parametrize("row", ROWS, ids=[f"line{r.line}" for r in ROWS])
def test_claim_row_holds(row):
    problem = check(row)
    assert problem is None, f"docs/claims.md:{row.line}: {row.claim}: {problem}"


@pytest.mark.parametrize("bad, why", [
    ("| x | `tests/test_claims_doc.py::test_no_such_test` | `ROWS` = 1 | 0 |", "has no test"),
    ("| x | `ctest NoSuch.Test` | exact | 0 |", "no TEST(NoSuch, Test)"),
    ("| x | `tests/test_analytic_finishes.py::test_model_matches_closed_form` | `CLOSED_FORM_TOL` = 2e-4 | 1e-7 |",
     "the test asserts 0.0001"),
    ("| x | `tests/test_analytic_finishes.py::test_model_matches_closed_form` | `CLOSED_FORM_TOL` = 1e-4 | 2e-4 |",
     "above the tolerance"),
    ("| x | `tests/test_analytic_finishes.py::test_model_matches_closed_form` | `NO_SUCH` = 1e-4 | 0 |",
     "no constant NO_SUCH"),
    ("| x | `ctest Dipole.ClosedFormTotalReproducesCsvCheckColumns` | `kNoSuch` = 1 | 0 |", "no constant kNoSuch"),
])
def test_checker_rejects_a_false_row(bad, why):
    # The checker itself can fail: a vanished test, a tolerance that differs from the code,
    # a measured value above its tolerance.
    rows = parse("| claim | test | tolerance | measured |\n| --- | --- | --- | --- |\n" + bad + "\n")
    assert len(rows) == 1
    problem = check(rows[0])
    assert problem is not None and why in problem, problem
