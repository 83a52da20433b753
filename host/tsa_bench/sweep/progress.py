"""Progress of a sweep: points done, failures and ETA.

Contract: on a terminal a rich live line (bar, ``done/total points``, failures,
elapsed, ETA) on stderr; elsewhere (a pipe, a CI log, a test) a plain line at most every
``every_s`` seconds and at the end, never wrapped (:func:`tsa_bench.console.output.make_console`).
"""

from __future__ import annotations

import time

from rich.console import Console

from tsa_bench.console.output import make_console
from tsa_bench.console.progress import hms


class SweepProgress:
    """Call with (done, failed, total) after each point; use as a context manager."""

    def __init__(self, label: str, console: Console | None = None, every_s: float = 10.0) -> None:
        self.console = console or make_console(stderr=True)
        self.label = label
        self.every_s = every_s
        self._t0 = time.monotonic()
        self._last = -1e9
        self._progress = None
        self._task = None

    def __enter__(self) -> SweepProgress:
        if self.console.is_terminal:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, \
                TimeRemainingColumn

            self._progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                      TextColumn("points, {task.fields[failed]} failed"), TimeElapsedColumn(),
                                      TextColumn("ETA"), TimeRemainingColumn(), console=self.console, transient=False)
            self._progress.start()
            self._task = self._progress.add_task(self.label, total=None, failed=0)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()

    def line(self, done: int, failed: int, total: int) -> str:
        n = done + failed
        elapsed = time.monotonic() - self._t0
        eta = elapsed / n * (total - n) if n else float("nan")
        return f"{self.label}: {n}/{total} points, {failed} failed, elapsed {hms(elapsed)}, ETA {hms(eta)}"

    def __call__(self, done: int, failed: int, total: int) -> None:
        if self._progress is not None:
            self._progress.update(self._task, completed=done + failed, total=total, failed=failed)
            return
        now = time.monotonic()
        if now - self._last >= self.every_s or done + failed >= total:
            self._last = now
            self.console.print(self.line(done, failed, total), soft_wrap=True)
