"""The one matplotlib set-up of the harness: off-screen (Agg), one style, one way to save.

    plt = plotting.pyplot()
    fig, ax = plt.subplots(...)
    ...
    plotting.save(fig, path)      # creates the folder, writes, closes the figure

pyplot is not thread-safe: callers that plot from several threads hold :data:`LOCK`.

Figures are made at the size a page shows them (one figure pixel per CSS pixel at
:data:`DPI`), so their text is as large on screen as it is in the file: :data:`MIN_TEXT_PX`
(10 px, i.e. 7.2 pt at 100 dpi) is the smallest any of them may use. :func:`save` measures the
smallest visible text of the figure and records it in the PNG (a ``min-text-px`` text chunk),
which the pages' browser test (``tests/pagelayout.py``) multiplies by the scale the page shows
the image at.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any, Union

#: Held around pyplot calls made from worker threads.
LOCK = threading.RLock()

#: Figure pixels per inch: one figure pixel is one CSS pixel on the pages.
DPI = 100
#: The smallest text, in pixels of the image, a figure may carry (10 px = 7.2 pt at 100 dpi).
MIN_TEXT_PX = 10.0
#: The smallest point size a figure uses: 7.5 pt = 10.4 px at DPI.
SMALL_PT = 7.5

_STYLE = {
    "figure.dpi": DPI,
    "savefig.dpi": "figure",
    "font.size": 9,
    "axes.titlesize": 10,
    "axes.grid": False,
    "legend.fontsize": 8,
    "legend.frameon": False,
    "image.interpolation": "nearest",
}
_configured = False


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend with the harness style (set once)."""
    global _configured
    import matplotlib
    if not _configured:
        matplotlib.use("Agg")
        matplotlib.rcParams.update(_STYLE)
        _configured = True
    import matplotlib.pyplot as plt
    return plt


def smallest_text_px(fig: Any, dpi: float) -> float:
    """The font size, in pixels at ``dpi``, of the smallest visible non-empty text of ``fig``
    (titles, labels, tick labels, legends, colorbars, annotations); inf when it has none."""
    from matplotlib.text import Text

    fig.canvas.draw()  # tick labels exist only once drawn
    sizes = [t.get_fontsize() for t in fig.findobj(Text)
             if t.get_visible() and t.get_text().strip() and _shown(t)]
    return min(sizes) * dpi / 72.0 if sizes else float("inf")


def _shown(t: Any) -> bool:
    """Whether a text artist is drawn: it and every ancestor axes visible, inside the figure."""
    ax = t.axes
    if ax is not None and not ax.get_visible():
        return False
    try:
        bb = t.get_window_extent()
    except (RuntimeError, ValueError):
        return True
    w, h = t.figure.bbox.width, t.figure.bbox.height
    return bb.x1 > 0 and bb.y1 > 0 and bb.x0 < w and bb.y0 < h


def save(fig: Any, path: Union[str, os.PathLike], **kwargs: Any) -> Path:
    """Write ``fig`` to ``path`` whole (its folder created; :func:`harness.core.files.write_whole`:
    a failed write leaves no partial file and names ``path``), close it, return the path. The
    format is the file name's suffix unless ``format=`` says otherwise. A PNG records its
    smallest text in pixels (:func:`smallest_text_px`) as the text chunk ``min-text-px``."""
    from harness.core.files import write_whole

    out = Path(path)
    kwargs.setdefault("format", out.suffix.lstrip(".").lower() or "png")
    if kwargs["format"] == "png":
        dpi = kwargs.get("dpi", "figure")
        dpi = fig.dpi if dpi == "figure" else float(dpi)
        meta = dict(kwargs.get("metadata") or {})
        meta.setdefault("min-text-px", f"{smallest_text_px(fig, dpi):.2f}")
        kwargs["metadata"] = meta
    try:
        write_whole(out, lambda f: fig.savefig(f, **kwargs))
    finally:
        pyplot().close(fig)
    return out
