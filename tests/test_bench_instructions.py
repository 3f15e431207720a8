"""The bench's instruction counts (harness.reports.bench, ``instr ratio``): valgrind's
report parsed, the two-size difference, and one real count on a small scene."""

import pytest

from harness.reports import bench

REPORT = """==4242== Callgrind, a call-graph generating cache profiler
==4242== Command: povray +Iscene.pov
==4242==
==4242== Events    : Ir
==4242== Collected : 1972344635
==4242==
==4242== I   refs:      1,972,344,635
"""


def test_parse_takes_the_summary_line():
    assert bench.parse_instructions(REPORT) == 1972344635
    # POV's own output around it does not matter
    assert bench.parse_instructions("Trace Time: 1.2 s\n" + REPORT + "POV-Ray finished\n") == 1972344635


@pytest.mark.parametrize("text", ["", "I refs: 12\n", REPORT + REPORT])
def test_parse_refuses_anything_but_one_summary(text):
    with pytest.raises(ValueError):
        bench.parse_instructions(text)


def test_difference_is_the_larger_minus_the_smaller():
    assert bench.instruction_difference(314_242_553, 1_121_995_460) == 807_752_907
    with pytest.raises(ValueError):
        bench.instruction_difference(10, 10)  # the larger render must cost more


def test_each_distinct_side_is_counted_once_and_staged_files_count_by_content(monkeypatch, tmp_path):
    # The same scene text with a different table staged under the same name (the grid's 1 deg
    # and half/difference rows both stage t.brdf) is a different side: counted, not reused.
    a, b = tmp_path / "a.brdf", tmp_path / "b.brdf"
    a.write_bytes(b"a")
    b.write_bytes(b"b")
    counts = {str(a): 100, str(b): 200}
    calls = []

    def fake(side, r):
        calls.append(side)
        files = side.resolved_files()
        return counts[str(files["t.brdf"])] if files else 50

    monkeypatch.setattr(bench, "trace_instructions", fake)
    scene = 'brdf_table { "t.brdf" }'
    stock = bench.Side("stock", "phong")
    rows = [bench.Row("one", stock, bench.Side("fork", scene, files={"t.brdf": lambda: a})),
            bench.Row("two", stock, bench.Side("fork", scene, files={"t.brdf": b}))]
    results = [bench.Result(r, [1.0], [1.0]) for r in rows]
    bench.count_instructions(results)
    assert [x.candidate_instructions for x in results] == [100, 200]
    assert [x.baseline_instructions for x in results] == [50, 50]
    assert len(calls) == 3  # the shared baseline once


@pytest.mark.slow
@pytest.mark.skipif(not bench.have_valgrind(), reason="valgrind is not installed")
def test_a_scene_counts_the_same_in_both_binaries_and_a_table_costs_more():
    # The stock binary and the fork trace the stock phong grid with the same instructions
    # (within 1 %: the fork's per-hit tests for its finishes); a table finish costs more.
    row = bench.Row("t", bench.grid_side("phong", "stock"), bench.grid_side("phong"), width=160, height=160)
    stock = bench.trace_instructions(row.baseline, row)
    fork = bench.trace_instructions(row.candidate, row)
    table = bench.trace_instructions(bench.grid_side("table"), row)
    assert abs(fork / stock - 1) < 0.01
    assert table > fork
