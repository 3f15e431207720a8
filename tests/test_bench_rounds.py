"""The bench's rounds (harness.reports.bench): bands of rows that cover the image, every band
rendered by every side back to back in a rotating order, and a round's time per side as the
sum over its bands. POV itself is replaced by a recorder (no renders)."""

import pytest

from harness.reports import bench


@pytest.mark.parametrize("height,bands", [(1536, 12), (1536, 24), (100, 7), (10, 5), (9, 1)])
def test_bands_cover_every_row_once_with_two_rows_or_more(height, bands):
    rows = bench.band_rows(height, bands)
    assert len(rows) == bands
    assert rows[0][0] == 1 and rows[-1][1] == height
    for (a, b), (c, _) in zip(rows, rows[1:]):
        assert c == b + 1  # contiguous, no overlap
    assert all(b - a + 1 >= 2 for a, b in rows)  # +ER1 would be read as the whole image
    assert max(b - a for a, b in rows) - min(b - a for a, b in rows) <= 1


@pytest.mark.parametrize("bands", [0, 6])
def test_too_many_or_no_bands_are_refused(bands):
    with pytest.raises(ValueError):
        bench.band_rows(10, bands)


def fake_sides(n):
    return [bench.Side("stock" if k == 0 else "fork", f"// side {k}\n") for k in range(n)]


def test_a_round_renders_each_band_by_every_side_back_to_back(monkeypatch):
    calls = []
    cost = {0: 1.0, 1: 1.5, 2: 2.0}  # seconds per row, by side

    def trace(side, r, band=None):
        k = int(side.scene.split()[2])
        calls.append((k, band))
        rows = band[1] - band[0] + 1
        return cost[k] * rows, 2 * cost[k] * rows

    monkeypatch.setattr(bench, "trace_render", trace)
    sides = fake_sides(3)
    r = bench.Row("r", sides[0], sides[1], width=8, height=12, bands=4)
    times = [bench.RoundTimes() for _ in sides]
    bench.measure_round(sides, r, 1, times)
    bands = bench.band_rows(12, 4)
    assert len(calls) == 12
    for k, band in enumerate(bands):
        group = calls[3 * k:3 * k + 3]
        assert {b for _, b in group} == {band}  # all sides on this band before the next one
        assert [s for s, _ in group] == [(m + 1 + k) % 3 for m in range(3)]  # rotating order
    # the round's time is the whole image's: the sum over the bands
    assert [t[0] for t in times] == [12.0, 18.0, 24.0]
    assert [t.cpu[0] for t in times] == [24.0, 36.0, 48.0]


def test_group_ratios_divide_by_the_same_rounds_baseline(monkeypatch):
    rounds = iter([[2.0, 2.2, 3.0], [1.0, 1.05, 1.4], [4.0, 4.0, 6.0]])

    def fake_round(sides, r, i, into):
        for t, w in zip(into, next(rounds)):
            t.append(w)
            t.cpu.append(w)

    monkeypatch.setattr(bench, "trace_render", lambda side, r, band=None: (1.0, 1.0))  # the warm-up
    monkeypatch.setattr(bench, "measure_round", fake_round)
    sides = fake_sides(3)
    rows = [bench.Row("a", sides[0], sides[1], group="g"), bench.Row("b", sides[0], sides[2], group="g")]
    a, b = bench.measure_group(rows, repeat=3)
    assert a.ratios == pytest.approx([1.1, 1.05, 1.0])
    assert b.ratios == pytest.approx([1.5, 1.4, 1.5])
    assert a.ratio == pytest.approx(1.05) and b.ratio == pytest.approx(1.5)


def test_grid_rows_are_banded_and_have_their_control():
    grid = [r for r in bench.ROWS if r.group in ("grid", "grid 2 threads")]
    assert grid and all(r.bands == bench.GRID_BANDS for r in grid)
    controls = [r for r in grid if r.baseline == r.candidate]
    assert {r.group for r in controls} == {"grid", "grid 2 threads"}
