"""Point runners: what one study point does, returning its figures of merit.

Each runner is ``run(config, plant) -> dict[str, value]`` (numbers, booleans or text),
with the unit in each figure's name (``_s``, ``_mm``, ``_ohm``, ``_ohm_per_h``,
``_percent``) or, for a count, a rate or a verdict, none. Contract of :func:`run_point`
(what a Dask worker calls): it never raises; a failure becomes a row with
``status = "failed"`` and the exception's message, and the study goes on.
"""

from __future__ import annotations

import importlib
import os
import socket
import time
from collections.abc import Callable
from typing import Any

#: runner -> "module:function" inside this package (imported on the worker, when needed)
RUNNERS = {
    "simulate": "simulate:run",
    "diagnose": "diagnose:run",
    "fit": "fit:run",
    "reproduce": "reproduce:run",
}


def runner_function(name: str):
    module, attr = RUNNERS[name].split(":")
    return getattr(importlib.import_module(f"{__name__}.{module}"), attr)


def run_point(runner: str | Callable[[dict[str, Any], Any], dict[str, Any]], key: str, config: dict[str, Any]
              ) -> dict[str, Any]:
    """Run one point; a row: key, status, error, work_s (s of this point's own work), worker, figures.

    ``runner`` is a name of :data:`RUNNERS` or, for studies built in code (not from a
    file), a function ``(config, None) -> figures`` that the workers can unpickle."""
    from tsa_bench.sweep.plant import resolved_plant

    t0 = time.perf_counter()
    row: dict[str, Any] = {"key": key, "status": "done", "error": "",
                           "worker": f"{socket.gethostname()}:{os.getpid()}"}
    try:
        if callable(runner):
            row["figures"] = runner(config, None)
        else:
            row["figures"] = runner_function(runner)(config, resolved_plant(runner, config))
    except Exception as exc:  # a bad combination or a plant error is a result, not the end of the study
        row.update(status="failed", error=f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:500],
                   figures={})
    row["work_s"] = time.perf_counter() - t0
    return row
