"""Progress with an ETA on the harness's long jobs (harness.core.progress, tqdm): renders,
studies, regressions, the report's parts, Monte Carlo runs; ``-q/--quiet`` silences them.

tqdm writes its bar to stderr with "\\r" between updates; the last state reads
``what: 100%|...| N/N [elapsed<left, rate]``.
"""

from __future__ import annotations

import re

from harness.core import progress, runner
from harness.reference.mc_subsurface import simulate
from harness.reports import regress, report, study

from test_regress import copy_scene
from test_study import SMALL

DONE = r"{what}: 100%\|[^|]*\| {n}/{n} \[\d\d:\d\d<00:00"


def final(err: str, what: str) -> str:
    """The last state of the bar ``what`` in ``err``."""
    states = [s for s in re.split(r"[\r\n]", err) if s.startswith(f"{what}:")]
    assert states, err[-1500:]
    return states[-1]


def test_bar_counts_and_is_silent_when_disabled(capsys):
    with progress.bar(3, "job", unit="step") as b:
        for _ in range(3):
            b.update(1)
    assert re.match(DONE.format(what="job", n=3), final(capsys.readouterr().err, "job"))
    with progress.bar(3, "job", enabled=False) as b:
        b.update(3)
    assert capsys.readouterr().err == ""


def test_render_many_shows_renders_done_and_failed(fork, capsys):
    scene = "camera { location -3*z look_at 0 } light_source { <1, 1, -1> rgb 1 } sphere { 0, 1 pigment { rgb 1 } }"
    res = runner.render_many([scene, "sphere {", scene], binary=fork, width=8, height=8, max_workers=2,
                             return_exceptions=True, progress_label="render")
    assert [isinstance(r, Exception) for r in res] == [False, True, False]
    last = final(capsys.readouterr().err, "render")
    assert re.match(DONE.format(what="render", n=3), last) and last.endswith("1 failed]"), last


def test_study_cli_shows_progress_and_quiet_silences_it(fork, tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(SMALL)
    assert study.main([str(path), "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert re.match(DONE.format(what="study", n=3), final(err, "study")), err
    assert study.main([str(path), "--out", str(tmp_path / "b"), "-q"]) == 0
    assert capsys.readouterr().err == ""


def test_regress_cli_shows_progress(fork, tmp_path, capsys):
    d = copy_scene(tmp_path / "scenes").parent
    assert regress.main(["--scenes-dir", str(d), "--out", str(tmp_path / "o")]) == 0
    assert re.match(DONE.format(what="regress", n=1), final(capsys.readouterr().err, "regress"))


def test_report_parts_show_progress(capsys):
    assert report.run_parallel(lambda x: x * x, [1, 2, 3], 2, "report: models", "model", True) == [1, 4, 9]
    assert re.match(DONE.format(what="report: models", n=3), final(capsys.readouterr().err, "report: models"))
    assert report.run_parallel(lambda x: x, [1, 2], 2, "report: models", "model", False) == [1, 2]
    assert capsys.readouterr().err == ""


def test_monte_carlo_shows_photons_and_is_unchanged_by_it(capsys):
    quiet = simulate(1.0, 0.05, eta=1.3, n_photons=2000, seed=4)
    assert capsys.readouterr().err == ""
    talk = simulate(1.0, 0.05, eta=1.3, n_photons=2000, seed=4, progress=True)
    assert re.match(DONE.format(what="Monte Carlo", n=2000), final(capsys.readouterr().err, "Monte Carlo"))
    assert talk.total == quiet.total and (talk.rd_r == quiet.rd_r).all()
