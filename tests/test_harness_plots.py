"""The harness's figures carry readable, whole text (issue 33): ``brdf-plot`` wraps a long
table description instead of cutting it, and every figure :func:`harness.core.plotting.save`
writes records its smallest text, which must be at least 10 px (the pages show figures at
their natural size, so that is the size on screen; ``tests/test_pages_browser.py`` checks the
display scale in a browser)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from PIL import Image

from harness.core import brdf_io, plotting
from harness.tools import brdfplot

# A description as long as brdftool convert writes for a folded MERL file, ending in words a
# cut would lose.
LONG = ("MERL out/tutorial/synthetic.binary (90x90x180, reference bin lookup); symmetrised when folded "
        "(reciprocity error max 407.477121 1/sr, rel 0.300856424) END-OF-DESCRIPTION")


def min_text_px(png) -> float:
    with Image.open(png) as im:
        return float(im.text["min-text-px"])


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    n = 19  # 5 deg
    f = np.full((n, n, 2 * n - 1, 3), 0.2 / np.pi, dtype=np.float32)
    return brdf_io.write_brdf(tmp_path_factory.mktemp("plots") / "long.brdf", f, description=LONG)


def capture(monkeypatch):
    """Keep the figure plotting.save is given (it is still written and closed)."""
    seen = []
    real = plotting.save

    def keep(fig, path, **kw):
        fig.canvas.draw()
        seen.append((fig.get_window_extent(), fig._suptitle.get_window_extent() if fig._suptitle else None,
                     fig._suptitle.get_text() if fig._suptitle else ""))
        return real(fig, path, **kw)

    monkeypatch.setattr(plotting, "save", keep)
    return seen


@pytest.mark.parametrize("angles", [(0, 30, 60, 75), (45,)])
def test_brdf_plot_subtitle_is_whole_and_inside_the_figure(table, tmp_path, monkeypatch, angles):
    seen = capture(monkeypatch)
    out = brdfplot.plot(table, tmp_path / "p.png", theta_i=angles)
    (fig_box, title_box, text), = seen
    # every word of the description is there, in order (wrapped, not cut)
    assert " ".join(text.split()).endswith(" ".join(LONG.split())), text
    assert "END-OF-DESCRIPTION" in text
    # and every line of it lies inside the figure
    assert title_box.x0 >= 0 and title_box.x1 <= fig_box.x1, (title_box, fig_box)
    assert title_box.y1 <= fig_box.y1, (title_box, fig_box)
    assert min_text_px(out) >= plotting.MIN_TEXT_PX


def test_heading_lines_never_cut():
    words = ("word " * 200).strip()
    lines = brdfplot.heading_lines("title", words, 400, 9)
    assert " ".join(lines[1:]) == words
    assert max(len(s) for s in lines) <= 400 / (0.55 * 9 * 100 / 72)


def test_save_records_the_smallest_text(tmp_path):
    plt = plotting.pyplot()
    fig, ax = plt.subplots(figsize=(3, 2))
    ax.set_title("title", fontsize=12)
    ax.text(0.5, 0.5, "small", fontsize=6)
    ax.set_xticks([])
    ax.set_yticks([])
    out = plotting.save(fig, tmp_path / "f.png")
    assert min_text_px(out) == pytest.approx(6 * 100 / 72, abs=0.01)  # 8.33 px: too small, and measured so


def test_study_polar_plot_text_is_readable(tmp_path):
    from harness.reports import study as study_mod
    from harness.core.paths import REPO_ROOT

    table = REPO_ROOT / "build" / "brdf_data" / "gold.brdf"
    if not table.is_file():
        pytest.skip("needs make brdf-data")
    png = brdfplot.plot(table, tmp_path / "gold.png", theta_i=study_mod.POLAR_ANGLES, title="gold")
    with Image.open(png) as im:
        assert im.size[0] <= 1000, im.size  # shown at its natural size, it fits a 1366 px window
    assert min_text_px(png) >= plotting.MIN_TEXT_PX


def test_error_map_colorbar_is_readable(tmp_path):
    from harness.core.compare import error_map_png

    a = np.random.default_rng(1).random((40, 50, 3))
    out = error_map_png(tmp_path / "e.png", a, a * 1.001, relative=True, title="t")
    assert min_text_px(out) >= plotting.MIN_TEXT_PX
    out = error_map_png(tmp_path / "s.png", a, a * 1.001, title="t")
    assert min_text_px(out) >= plotting.MIN_TEXT_PX
    text = Image.open(out).text["min-text-px"]
    assert re.fullmatch(r"\d+\.\d\d", text)
