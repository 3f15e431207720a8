"""Stability suite: the hard cases of every finish (``harness.reports.stability``), one test per case.

Each case renders with the fork and must be free of NaN, Inf and negative samples, with its
error within its limit where it has one (grazing light and view, roughness 1e-4, eta 1.0001,
albedo 1 in a white furnace and a non-absorbing dipole, r = 0 on a dipole sample, all-zero and
broken tables). ``python -m harness.reports.stability`` prints the same table; ``make report`` shows it.
About 20 s in all on two cores.
"""

from __future__ import annotations

import pytest

from harness.reports import stability


@pytest.mark.parametrize("key", list(stability.CASES))
def test_case(fork, key):
    r = stability.run_case(key)
    print(stability.markdown([r]))
    assert r.n_nan in (0, None) and r.n_inf in (0, None) and r.n_negative in (0, None), r
    if r.limit is not None:
        assert r.error is not None and r.error <= r.limit, r
    assert r.ok, r
