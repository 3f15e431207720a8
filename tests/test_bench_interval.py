"""The bench's verdicts (harness.reports.bench): the interval that holds a median ratio,
checked against exact binomial sums and by simulation, and the verdict read from it."""

import math
import random

import pytest

from harness.reports import bench


def exact_coverage(n: int, k: int) -> float:
    """P(k-th smallest <= median <= k-th largest) for n draws of a continuous distribution:
    1 - 2 P(fewer than k draws below the median), the binomial sum written out."""
    return 1 - 2 * sum(math.comb(n, i) for i in range(k)) / 2 ** n


@pytest.mark.parametrize("n,k", [(6, 1), (8, 1), (9, 2), (11, 2), (12, 3), (17, 5), (25, 8), (31, 10)])
def test_interval_is_the_narrowest_with_the_confidence(n, k):
    # k from the binomial sums by hand: the k-th order statistics cover >= 95 %, the
    # (k+1)-th do not.
    assert exact_coverage(n, k) >= 0.95 > exact_coverage(n, k + 1)
    values = [10.0 + i for i in range(n)][::-1]  # order does not matter
    lo, hi, coverage = bench.median_interval(values)
    assert (lo, hi) == (10.0 + k - 1, 10.0 + n - k)
    assert coverage == pytest.approx(exact_coverage(n, k), abs=1e-12)


@pytest.mark.parametrize("n", [1, 2, 5])
def test_too_few_values_give_the_range_and_its_smaller_coverage(n):
    lo, hi, coverage = bench.median_interval([float(i) for i in range(n)])
    assert (lo, hi) == (0.0, float(n - 1))
    assert coverage == pytest.approx(1 - 2.0 ** (1 - n))
    assert coverage < bench.CONFIDENCE


def test_interval_holds_the_median_as_often_as_it_says():
    # Skewed draws (lognormal: median 1, mean above it), 11 rounds as `make bench` uses:
    # the interval must hold the true median in about its coverage (98.8 %) of 4000 runs.
    rng = random.Random(5)
    hits, runs = 0, 4000
    for _ in range(runs):
        lo, hi, coverage = bench.median_interval([rng.lognormvariate(0.0, 0.3) for _ in range(11)])
        hits += lo <= 1.0 <= hi
    assert coverage == pytest.approx(exact_coverage(11, 2))
    # binomial sd of the hit rate: sqrt(p (1 - p) / runs) = 0.0017; 4 sd either side
    assert abs(hits / runs - coverage) < 4 * math.sqrt(coverage * (1 - coverage) / runs)


@pytest.mark.parametrize("lo,hi,verdict", [(0.95, 1.05, "met"), (0.98, 1.049, "met"), (1.0, 1.12, "not shown"),
                                           (1.051, 1.2, "missed")])
def test_verdict_reads_the_whole_interval(lo, hi, verdict):
    assert bench.goal_verdict(lo, hi, 1.05) == verdict


def test_table_prints_interval_and_verdict():
    r = next(x for x in bench.ROWS if x.goal == 1.05)
    base = [1.0] * 11
    res = bench.Result(r, base, [1.01, 1.02, 1.03, 1.04, 1.04, 1.045, 1.05, 1.06, 1.07, 1.2, 1.3])
    assert res.interval[:2] == (1.02, 1.2)
    assert res.verdict == "not shown"
    text = bench.format_table([res])
    assert "1.020.. 1.200" in text and "not shown" in text and "too few rounds" not in text
    few = bench.Result(r, base[:4], [0.9, 0.91, 0.92, 0.93])
    assert few.verdict == "met"
    assert "too few rounds" in bench.format_table([few])
