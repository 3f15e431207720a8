"""The study, regress and report pages in a real browser (issue 33): at 1366, 1400 and 1920 px
windows none scrolls sideways, no element reaches past the window (a wide table or plot may
scroll inside its own box), every image loads, no text is under 10 px, every plot is shown at
its natural size so its smallest label (recorded in the PNG by harness.core.plotting.save) is
at least 10 px on screen, and no number breaks across lines. Headless Debian Chromium through
Playwright (tests/pagelayout.py); full-page screenshots go to build/screens/test/PAGE-WIDTH.png.

Slow (renders a small study, two regression scenes and the report's model and table parts,
about a minute on two cores): run by `make test-security` and `make test-pages`, which install
Chromium (apt) and Playwright (the venv's test extra) first.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from harness.core.paths import REPO_ROOT

from tests import pagelayout

pytestmark = pytest.mark.slow

SCREENS = REPO_ROOT / "build" / "screens" / "test"


@pytest.fixture(scope="module")
def pages(tmp_path_factory, fork):
    if not pagelayout.CHROMIUM.is_file():
        pytest.fail(f"{pagelayout.CHROMIUM} is missing: `make test-pages` (or test-security) installs Debian's "
                    "chromium as root")
    pytest.importorskip("playwright", reason="the venv's test extra installs playwright (make venv)")
    from harness.reports import regress, report, study

    root = tmp_path_factory.mktemp("pages")
    # A study like the tutorial's and as wide as the example's: a table (its polar plot), a model
    # with a long spec, a stock finish; three shapes under two lights.
    (root / "study.toml").write_text(textwrap.dedent("""\
        title = "Browser check: a table, a model and POV's phong"
        size = [144, 120]
        shapes = ["sphere", "torus", "blob"]
        lights = ["key", "rim"]
        [[material]]
        name = "gold, 1 deg table"
        table = "gold.brdf"
        [[material]]
        name = "fit: Cook-Torrance"
        model = "microfacet d=beckmann g=smith m=0.189406 f=schlick f0=0.040428 kd=0.260047,0.0900469,0.0600469 rho_s=0.650689"
        [[material]]
        name = "POV phong, by eye"
        pov = "pigment { rgb <0.26, 0.09, 0.06> } finish { diffuse 1 phong 0.4 phong_size 60 }"
        """))
    assert study.main([str(root / "study.toml"), "--out", str(root / "study"), "--jobs", "2", "-q"]) == 0
    # Two regression scenes (a failing comparison would still write its page: the status is not checked here).
    regress.main(["--only", "table_interpolate", "model_families", "--out", str(root / "regress"), "--jobs", "2", "-q"])
    assert report.main(["--quick", "--only", "models,tables", "--no-time", "-o", str(root / "report"), "-q"]) == 0
    return {name: root / name / "index.html" for name in ("study", "regress", "report")}


@pytest.mark.parametrize("name", ["study", "regress", "report"])
def test_page_fits_the_window_and_its_text_is_readable(pages, name):
    layouts = pagelayout.measure([pages[name]], pagelayout.WIDTHS, screens=SCREENS)
    for lay in layouts:
        print(lay.summary())
    problems = [f"{lay.width} px: {p}" for lay in layouts for p in lay.problems()]
    assert not problems, "\n".join(problems)
    for lay in layouts:
        assert lay.scroll_width <= lay.inner_width
        assert lay.images and all(i["natural_width"] > 0 for i in lay.images)
        assert lay.smallest_text_px >= pagelayout.MIN_TEXT_PX
        # every page shows figures with text, and each is shown at its natural size
        assert lay.plots, f"{name}: no plot on the page to check"
        assert all(p["shown_text_px"] >= pagelayout.MIN_TEXT_PX for p in lay.plots)
        assert lay.screenshot is not None and lay.screenshot.stat().st_size > 10_000
