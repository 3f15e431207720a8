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


def render_task(scene: str, options: dict[str, Any], binary_path: str, tag: str = "") -> Any:
    """:func:`harness.core.runner.render` of ``scene`` with the fork at ``binary_path``.

    ``POVRAY_BRDF`` in the worker's environment overrides the client's path. The result
    records the worker's process id in ``stats["worker_pid"]``. The renderer runs under
    ``tag`` (:func:`stop`) and dies with the worker process (even one killed with SIGKILL:
    :func:`harness.core.runner.render` gives it a parent-death signal).
    """
    from pathlib import Path

    from harness.core import runner
    from harness.core.paths import Binary

    runner.sweep_stale_jobs()  # job folders of a worker that was killed on this machine
    path = os.environ.get("POVRAY_BRDF") or binary_path
    res = runner.render(scene, Binary(Path(path), "fork"), tag=tag, **options)
    res.stats["worker_pid"] = float(os.getpid())
    return res


def stop(tag: str) -> int:
    """Kill this worker's renderers running under ``tag`` (a study that was interrupted sends
    this with ``Client.run``: cancelling a Dask task does not stop its thread). Returns how many."""
    from harness.core import runner

    return runner.stop_renders(tag)
