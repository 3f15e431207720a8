"""Shared fixtures: the two renderers and the tolerances that go with their EXR output.

The stock POV-Ray must be installed: a missing stock binary is an error. The fork is being
built: tests that need it are skipped (with the reason) until ``build/bin/povray-brdf`` exists.
"""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from harness.core.compare import HALF_REL_EPS
from harness.core.paths import Binary, BinaryNotFound, fork_binary, stock_binary

#: rel-RMSE tolerance against closed forms when POV writes half-float EXR (stock). An exact
#: render rounded to half has rel-RMSE <= 2^-11 = 4.88e-4 (every value moves by at most that
#: fraction); measured 1.9e-4 .. 2.2e-4 on the sphere scenes. 5e-4 = the bound plus 2 %.
HALF_TOL = 5.0e-4
#: The same for float32 EXR (fork, +FE32): float rounding 6e-8 plus POV's float colour
#: arithmetic; 1e-5 leaves a wide margin and is still 50x tighter than half.
FLOAT_TOL = 1.0e-5
#: Per-sample relative bound: half rounding (2^-11) + 5 %; for float32 output a few float
#: ulps of POV's single-precision colour arithmetic (1e-6 = ~17 ulps).
HALF_SAMPLE_REL = 1.05 * HALF_REL_EPS
FLOAT_SAMPLE_REL = 1.0e-6


@dataclass(frozen=True)
class Renderer:
    """A binary plus how to render with it and how close it must come to a closed form."""

    binary: Binary
    float_exr: bool
    rel_tol: float
    sample_rel: float

    @property
    def name(self) -> str:
        return self.binary.flavour


@pytest.fixture(scope="session")
def stock() -> Binary:
    """Debian's stock POV-Ray 3.7 (required)."""
    try:
        return stock_binary()
    except BinaryNotFound as e:
        pytest.fail(f"stock POV-Ray is required: {e}")


@pytest.fixture(scope="session")
def fork() -> Binary:
    """The fork; skips the test while it is not built."""
    try:
        return fork_binary()
    except BinaryNotFound as e:
        pytest.skip(f"fork not built yet: {e}")


@pytest.fixture(scope="session", params=["stock", "fork"])
def renderer(request: pytest.FixtureRequest) -> Renderer:
    """Each renderer in turn: stock (half EXR) and the fork (float32 EXR, skipped if absent)."""
    if request.param == "stock":
        return Renderer(request.getfixturevalue("stock"), False, HALF_TOL, HALF_SAMPLE_REL)
    return Renderer(request.getfixturevalue("fork"), True, FLOAT_TOL, FLOAT_SAMPLE_REL)
