"""The one matplotlib set-up of the harness: off-screen (Agg), one style, one way to save.

    plt = plotting.pyplot()
    fig, ax = plt.subplots(...)
    ...
    plotting.save(fig, path)      # creates the folder, writes, closes the figure

pyplot is not thread-safe: callers that plot from several threads hold :data:`LOCK`.
"""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any, Union

#: Held around pyplot calls made from worker threads.
LOCK = threading.RLock()

_STYLE = {
    "figure.dpi": 100,
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


def save(fig: Any, path: Union[str, os.PathLike], **kwargs: Any) -> Path:
    """Write ``fig`` to ``path`` whole (its folder created; :func:`harness.core.files.write_whole`:
    a failed write leaves no partial file and names ``path``), close it, return the path. The
    format is the file name's suffix unless ``format=`` says otherwise."""
    from harness.core.files import write_whole

    out = Path(path)
    kwargs.setdefault("format", out.suffix.lstrip(".").lower() or "png")
    try:
        write_whole(out, lambda f: fig.savefig(f, **kwargs))
    finally:
        pyplot().close(fig)
    return out
