"""Progress with an ETA for every job of the harness that can run longer than a few seconds.

One place sets up :mod:`tqdm` (pinned in ``pyproject.toml``) the same way for renders
(:func:`harness.core.runner.render_many`), studies, reports, regressions and Monte Carlo
runs: on stderr, ``what: 3/12 renders [00:04<00:11, ...]`` (done/total, elapsed<time left),
rewritten in place on a terminal; in a log or a pipe tqdm still writes its updates, at most
every ``mininterval`` seconds (5 s there, 0.5 s on a terminal). ``enabled=False`` (the tools'
``-q/--quiet``) makes a bar that prints nothing. Messages printed while a bar runs go through
:func:`write` so they do not tear the bar.
"""

from __future__ import annotations

import sys
from typing import Any, Optional

from tqdm import tqdm


def bar(total: Optional[int], what: str, unit: str = "render", enabled: bool = True, **kw: Any) -> tqdm:
    """A progress bar for ``total`` items (None: unknown total; no ETA then)."""
    tty = sys.stderr.isatty()
    opts: dict[str, Any] = dict(total=total, desc=what, unit=unit, file=sys.stderr, dynamic_ncols=True,
                                mininterval=0.5 if tty else 5.0, smoothing=0.1, leave=True,
                                disable=not enabled or total == 0)
    opts.update(kw)
    return tqdm(**opts)


def write(message: str) -> None:
    """Print a line on stderr without breaking a running bar."""
    tqdm.write(message, file=sys.stderr)
