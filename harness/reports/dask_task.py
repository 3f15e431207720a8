"""The render task of the Dask backend of :mod:`harness.reports.study` (``--scheduler``).

Kept apart and light: a Dask scheduler deserialises the task graph and so imports this
module (never :mod:`harness.reports.study`, which needs numpy, OpenEXR and matplotlib at import); the
runner is imported only when a worker runs the task. :func:`harness.reports.study.render_dask`
uploads the ``harness`` package to the scheduler and workers, so they need no checkout of
their own, only the fork binary and the staged files at the paths the client sends.
"""

from __future__ import annotations

import os
from typing import Any


def render_task(scene: str, options: dict[str, Any], binary_path: str) -> Any:
    """:func:`harness.core.runner.render` of ``scene`` with the fork at ``binary_path``.

    ``POVRAY_BRDF`` in the worker's environment overrides the client's path. The result
    records the worker's process id in ``stats["worker_pid"]``.
    """
    from pathlib import Path

    from harness.core import runner
    from harness.core.paths import Binary

    path = os.environ.get("POVRAY_BRDF") or binary_path
    res = runner.render(scene, Binary(Path(path), "fork"), **options)
    res.stats["worker_pid"] = float(os.getpid())
    return res
