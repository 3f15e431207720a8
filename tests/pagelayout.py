"""Layout of the harness's HTML pages in a real browser (headless Debian Chromium through
Playwright): what ``tests/test_pages_browser.py`` asserts, and a command line for any page.

    .venv/bin/python -m tests.pagelayout out/study/example/index.html --widths 1366,1400,1920 \
        --screens build/screens

For each window width it loads the page and measures, in the page itself:

* ``scroll_width``: ``document.documentElement.scrollWidth`` (the page scrolls sideways when it
  exceeds ``inner_width``, the viewport's width);
* ``overflowing``: elements whose box reaches past the viewport's right edge (or left of 0),
  except those inside a box that clips or scrolls them (``overflow-x`` not ``visible``) and
  that box itself fits;
* ``images``: every ``img``: loaded (``naturalWidth`` > 0), natural and displayed size, and for a
  plot (a PNG whose ``min-text-px`` text chunk :func:`harness.core.plotting.save` wrote) the
  size its smallest text has on screen: that chunk times displayed / natural width;
* ``smallest_text_px``: the smallest computed ``font-size`` of an element that shows text;
* ``wrapped_numbers``: table cells whose number (a word with a digit, ``2.757e-08``) is
  broken across lines.

Chromium runs with a fresh profile, no network services, no GPU and no sandbox (the tests run
as root in a container); the page is a local file.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional, Sequence

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
WIDTHS = (1366, 1400, 1920)
HEIGHT = 1000
#: The smallest text, in CSS pixels, a page or a plot on it may show.
MIN_TEXT_PX = 10.0
#: How far a plot's displayed width may differ from its natural width (relative).
PLOT_SCALE_TOL = 0.02

_MEASURE = r"""
() => {
  const vw = window.innerWidth;
  const clips = (el) => { const s = getComputedStyle(el); return s.overflowX !== 'visible'; };
  const describe = (el) => {
    let d = el.tagName.toLowerCase();
    if (el.className && typeof el.className === 'string') d += '.' + el.className.trim().split(/\s+/).join('.');
    const t = (el.getAttribute('src') || el.textContent || '').trim().slice(0, 40);
    return d + (t ? ' "' + t + '"' : '');
  };
  const overflowing = [];
  for (const el of document.body.querySelectorAll('*')) {
    const r = el.getBoundingClientRect();
    if (r.width === 0 && r.height === 0) continue;
    if (r.right <= vw + 0.5 && r.left >= -0.5) continue;
    let clipped = false;
    for (let a = el.parentElement; a && a !== document.body; a = a.parentElement) {
      if (clips(a)) { const ar = a.getBoundingClientRect(); clipped = ar.right <= vw + 0.5 && ar.left >= -0.5; break; }
    }
    if (!clipped) overflowing.push({el: describe(el), left: r.left, right: r.right});
  }
  const images = [...document.images].map(img => ({
    src: img.getAttribute('src'), complete: img.complete, natural_width: img.naturalWidth,
    natural_height: img.naturalHeight, width: img.getBoundingClientRect().width,
    height: img.getBoundingClientRect().height}));
  let smallest = Infinity, smallest_el = '';
  for (const el of document.body.querySelectorAll('*')) {
    const own = [...el.childNodes].some(n => n.nodeType === 3 && n.textContent.trim());
    if (!own) continue;
    const r = el.getBoundingClientRect();
    if (r.width === 0 && r.height === 0) continue;
    const px = parseFloat(getComputedStyle(el).fontSize);
    if (px < smallest) { smallest = px; smallest_el = describe(el); }
  }
  const wrapped = [];
  for (const td of document.querySelectorAll('td, th')) {
    const walker = document.createTreeWalker(td, NodeFilter.SHOW_TEXT);
    for (let n = walker.nextNode(); n; n = walker.nextNode()) {
      const re = /\S*\d\S*/g; let m;
      while ((m = re.exec(n.textContent)) !== null) {
        if (m[0].length < 3) continue;
        const range = document.createRange();
        range.setStart(n, m.index); range.setEnd(n, m.index + m[0].length);
        const lines = new Set([...range.getClientRects()].map(q => Math.round(q.top)));
        if (lines.size > 1) wrapped.push(m[0]);
      }
    }
  }
  return {inner_width: vw, scroll_width: document.documentElement.scrollWidth,
          overflowing: overflowing.slice(0, 20), overflow_count: overflowing.length,
          images, smallest_text_px: smallest, smallest_text_el: smallest_el,
          wrapped_numbers: wrapped.slice(0, 20)};
}
"""


def min_text_px(png: Path) -> Optional[float]:
    """The ``min-text-px`` text chunk of a PNG written by :func:`harness.core.plotting.save`
    (its smallest text in pixels of the image), or None."""
    from PIL import Image  # matplotlib's own dependency

    try:
        with Image.open(png) as im:
            v = getattr(im, "text", {}).get("min-text-px")
    except OSError:
        return None
    return float(v) if v is not None else None


@dataclass
class Layout:
    """What one page measured at one window width."""

    page: Path
    width: int
    inner_width: int
    scroll_width: int
    overflowing: list[dict[str, Any]]
    overflow_count: int
    images: list[dict[str, Any]]
    smallest_text_px: float
    smallest_text_el: str
    wrapped_numbers: list[str]
    screenshot: Optional[Path] = None
    plots: list[dict[str, Any]] = field(default_factory=list)

    def problems(self) -> list[str]:
        """Every way this layout fails the pages' rules (empty when it holds)."""
        out = []
        if self.scroll_width > self.inner_width:
            out.append(f"the page scrolls sideways: scrollWidth {self.scroll_width} > innerWidth {self.inner_width}")
        if self.overflow_count:
            out.append(f"{self.overflow_count} element(s) reach past the viewport, e.g. {self.overflowing[:3]}")
        for im in self.images:
            if not (im["complete"] and im["natural_width"] > 0):
                out.append(f"image not loaded: {im['src']}")
        if self.smallest_text_px < MIN_TEXT_PX:
            out.append(f"text at {self.smallest_text_px:g} px < {MIN_TEXT_PX:g} px: {self.smallest_text_el}")
        small = [p for p in self.plots if abs(p["scale"] - 1) > PLOT_SCALE_TOL]
        if small:
            worst = min(small, key=lambda p: p["scale"])
            out.append(f"{len(small)} plot(s) not shown at their natural width, e.g. {worst['src']} at "
                       f"{worst['scale']:.3f} ({worst['width']:.0f} of {worst['natural_width']} px)")
        unknown = [p["src"] for p in self.plots if p["min_text_px"] is None]
        if unknown:
            out.append(f"{len(unknown)} plot(s) without a min-text-px record (not written by plotting.save), "
                       f"e.g. {unknown[:3]}")
        tiny = [p for p in self.plots if p["min_text_px"] is not None and p["shown_text_px"] < MIN_TEXT_PX]
        if tiny:
            worst = min(tiny, key=lambda p: p["shown_text_px"])
            out.append(f"{len(tiny)} plot(s) with text under {MIN_TEXT_PX:g} px on screen, e.g. {worst['src']}: "
                       f"{worst['shown_text_px']:.1f} px")
        if self.wrapped_numbers:
            out.append(f"numbers broken across lines: {self.wrapped_numbers[:5]}")
        return out

    def summary(self) -> str:
        plots = [p for p in self.plots if p["min_text_px"] is not None]
        shown = min((p["shown_text_px"] for p in plots), default=float("nan"))
        scales = [p["scale"] for p in self.plots]
        return (f"{self.page} @ {self.width}px: scrollWidth {self.scroll_width} vs innerWidth {self.inner_width}, "
                f"{self.overflow_count} overflowing, {len(self.images)} images "
                f"({sum(1 for i in self.images if i['natural_width'] > 0)} loaded), smallest text "
                f"{self.smallest_text_px:g} px, plots shown at {', '.join(f'{s:.2f}' for s in sorted(set(scales))) or '-'}"
                f" of natural width, smallest plot text on screen {shown:.1f} px, "
                f"{len(self.wrapped_numbers)} wrapped numbers")


def is_plot(png: Path, patterns: Sequence[str] = ()) -> bool:
    """A figure with text: a PNG that records ``min-text-px`` (:func:`harness.core.plotting.save`),
    or one whose path relative to its page matches one of ``patterns`` (for pages made before
    figures recorded it)."""
    if min_text_px(png) is not None:
        return True
    return any(png.match(p) for p in patterns)


def measure(pages: Sequence[Path], widths: Sequence[int] = WIDTHS, screens: Optional[Path] = None,
            height: int = HEIGHT, plot_patterns: Sequence[str] = (),
            names: Optional[Sequence[str]] = None) -> list[Layout]:
    """Load each page at each width in headless Chromium; a full-page screenshot of each goes to
    ``screens/<name>-<width>.png`` when ``screens`` is given (``names``, by default each page's
    folder name)."""
    from playwright.sync_api import sync_playwright

    out: list[Layout] = []
    profile = Path(tempfile.mkdtemp(prefix="pagelayout-profile-"))
    try:
        with sync_playwright() as pw:
            ctx = pw.chromium.launch_persistent_context(
                str(profile), executable_path=str(CHROMIUM), args=CHROMIUM_ARGS, headless=True,
                viewport={"width": widths[0], "height": height}, offline=True)
            try:
                tab = ctx.new_page()
                for i, page_path in enumerate(pages):
                    page_path = Path(page_path).resolve()
                    name = names[i] if names else page_path.parent.name
                    for w in widths:
                        tab.set_viewport_size({"width": w, "height": height})
                        tab.goto(page_path.as_uri(), wait_until="load")
                        m = tab.evaluate(_MEASURE)
                        lay = Layout(page=page_path, width=w, **m)
                        for im in lay.images:
                            src = (page_path.parent / im["src"]).resolve() if im["src"] else None
                            if src is None or src.suffix.lower() != ".png" or not src.is_file() or not is_plot(src, plot_patterns):
                                continue
                            px = min_text_px(src)
                            scale = im["width"] / im["natural_width"] if im["natural_width"] else 0.0
                            lay.plots.append({"src": im["src"], "min_text_px": px, "scale": scale,
                                              "width": im["width"], "natural_width": im["natural_width"],
                                              "shown_text_px": (px or 0.0) * scale})
                        if screens is not None:
                            screens.mkdir(parents=True, exist_ok=True)
                            shot = screens / f"{name}-{w}.png"
                            tab.screenshot(path=str(shot), full_page=True)
                            lay.screenshot = shot
                        out.append(lay)
            finally:
                ctx.close()
    finally:
        shutil.rmtree(profile, ignore_errors=True)
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.pagelayout", description=__doc__.split("\n\n")[0])
    ap.add_argument("pages", nargs="+", type=Path, help="HTML pages")
    ap.add_argument("--widths", default=",".join(map(str, WIDTHS)), help="window widths in CSS px")
    ap.add_argument("--screens", type=Path, default=None, help="folder for full-page screenshots")
    ap.add_argument("--plots", default="", help="comma-separated globs of images to treat as plots "
                    "(pages made before figures recorded min-text-px), e.g. 'plots/*.png,sheet.png'")
    ap.add_argument("--names", default="", help="comma-separated screenshot names, one per page "
                    "(default: each page's folder name)")
    ap.add_argument("--json", action="store_true", help="print the measurements as JSON")
    a = ap.parse_args(argv)
    names = [n for n in a.names.split(",") if n] or None
    if names and len(names) != len(a.pages):
        ap.error("--names: one name per page")
    layouts = measure(a.pages, [int(w) for w in a.widths.split(",")], a.screens,
                      plot_patterns=[p for p in a.plots.split(",") if p], names=names)
    bad = 0
    for lay in layouts:
        if a.json:
            print(json.dumps({**lay.__dict__, "page": str(lay.page), "screenshot": str(lay.screenshot)}, default=str))
        print(lay.summary())
        for p in lay.problems():
            print(f"  FAIL {p}")
            bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
