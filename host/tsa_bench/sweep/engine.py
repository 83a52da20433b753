"""Running a study's points on Dask distributed.

Contract of :func:`run_study`:

* the points whose key already has a row in the results table are skipped (failed ones
  too, unless ``retry_failed``); the others are submitted to the cluster at once, one
  task per point (:func:`tsa_bench.sweep.points.run_point`, which never raises);
* the cluster is ``scheduler`` (``tcp://HOST:PORT`` of a running ``dask scheduler``) or,
  by default, a :class:`distributed.LocalCluster` of ``workers`` processes (default: the
  machine's cores) with one thread each (the point runners are NumPy loops that hold
  the GIL), started for the sweep and closed after it;
* each finished point is added to the table as it arrives (a worker lost mid-point is a
  failed row with the cluster's message); ``progress(done, failed, total)`` is called
  after each;
* KeyboardInterrupt cancels the pending points, writes the finished ones and raises
  :class:`Interrupted`; an unreachable scheduler raises :class:`SchedulerUnreachable`
  naming the address, before any point runs.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass

from tsa_bench.sweep.study import Study
from tsa_bench.sweep.table import ResultsTable

Progress = Callable[[int, int, int], None]


class SchedulerUnreachable(Exception):
    """No Dask scheduler answered at the address (``str()`` names it)."""


class Interrupted(Exception):
    """The sweep was interrupted; ``summary`` holds what was finished and written."""

    def __init__(self, summary: SweepSummary) -> None:
        super().__init__("interrupted")
        self.summary = summary


@dataclass
class SweepSummary:
    """What one sweep did: points in the study, skipped (already in the table), run, failed."""

    total: int
    skipped: int
    done: int = 0
    failed: int = 0
    workers: int = 0
    wall_s: float = 0.0
    work_s: float = 0.0          # sum of the points' own work, s


def default_workers() -> int:
    """Worker processes of the default local cluster: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def connect(scheduler: str | None, workers: int | None, timeout_s: float = 10.0):
    """(client, cluster or None) for a scheduler address or a new local cluster (module contract)."""
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout=f"{timeout_s}s"), None
        except (OSError, TimeoutError) as exc:
            raise SchedulerUnreachable(f"no Dask scheduler answered at {scheduler} ({type(exc).__name__}: "
                                       f"{' '.join(str(exc).split())[:200]})") from None
    # a point's errors become rows; what the workers log themselves (a heartbeat to a scheduler
    # that is shutting down after Ctrl-C) is noise with a traceback, so only CRITICAL passes
    cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.CRITICAL)
    return Client(cluster), cluster


def run_study(study: Study, table: ResultsTable, *, scheduler: str | None = None, workers: int | None = None,
              retry_failed: bool = False, progress: Progress | None = None, client=None,
              timeout_s: float = 10.0) -> SweepSummary:
    """Run the study's missing points (module contract). ``client``: an existing Dask client to use."""
    import time

    from distributed import as_completed

    from tsa_bench.sweep.points import run_point

    finished = table.finished_keys(include_failed=not retry_failed)
    todo = [p for p in study.points if p.key not in finished]
    summary = SweepSummary(total=len(study.points), skipped=len(study.points) - len(todo))
    if not todo:
        return summary
    own = client is None
    cluster = None
    if own:
        client, cluster = connect(scheduler, workers, timeout_s)
    t0 = time.perf_counter()
    futures = []
    try:
        summary.workers = len(client.scheduler_info().get("workers", {}))
        by_key = {p.key: p for p in todo}
        futures = [client.submit(run_point, study.runner, p.key, p.config, key=f"sweep-point-{p.key}", pure=False)
                   for p in todo]
        for fut in as_completed(futures):
            point = by_key[fut.key.removeprefix("sweep-point-")]
            try:
                result = fut.result()
            except Exception as exc:  # the worker died or the cluster lost the task
                result = {"key": point.key, "status": "failed", "figures": {},
                          "error": f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:500]}
            table.add(point.index, point.config, point.varied, result, study.keep)
            summary.done += result["status"] == "done"
            summary.failed += result["status"] != "done"
            summary.work_s += float(result.get("work_s") or 0.0)
            if progress is not None:
                progress(summary.done, summary.failed, len(todo))
    except KeyboardInterrupt:
        client.cancel([f for f in futures if not f.done()])
        table.flush()
        summary.wall_s = time.perf_counter() - t0
        raise Interrupted(summary) from None
    finally:
        table.flush()
        if own:
            client.close()
            if cluster is not None:
                cluster.close()
    summary.wall_s = time.perf_counter() - t0
    return summary
