"""Registering a run as it is recorded: a run consumer that never holds the run up.

Contract: :class:`CatalogueRecorder` is a :class:`~tsa_bench.rundocs.RunConsumer` placed
after the run-file writer. ``on_start`` and ``on_stop`` only put a job on a queue; one
background thread opens the catalogue and writes: at the start a row "running" (plan,
bench, backend, port, rig, sample, load, operator, metadata, start time, this process's
pid), at the end the facts of the closed file itself (:func:`~.runfiles.file_facts`:
status, device time, samples, lost samples, segments, size, SHA-256). The device loop
never waits on the database, and no catalogue failure reaches the run: it becomes one
warning (``warn``) saying the run file is complete and how to register it later.
:meth:`CatalogueRecorder.close` waits for the thread at most ``timeout_s``.
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tsa_bench.catalogue.database import CatalogueError, now_utc, open_catalogue, shown_url
from tsa_bench.catalogue.runfiles import bench_name, file_facts, meta_fields
from tsa_bench.rundocs import EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord


class CatalogueRecorder:
    """See the module contract. ``load_g`` is the protocol's load (g) when the metadata gives none."""

    def __init__(self, target: str, path: str | Path, *, kind: str = "recorded", load_g: float | None = None,
                 warn: Callable[[str], None] | None = None) -> None:
        self.target, self.path = target, Path(path).resolve()
        self.kind, self.load_g = kind, load_g
        self._warn = warn
        self._jobs: queue.Queue[tuple[str, Any] | None] = queue.Queue()
        self._thread: threading.Thread | None = None
        self.run_id: int | None = None
        self.failed: str | None = None

    # -- the consumer (called by the runner: only queues) ----------------------
    def on_start(self, start: RunStart) -> None:
        fields = dict(path=str(self.path), status="running", kind=self.kind, plan=start.plan_name,
                      bench=bench_name(start.bench_text), backend=start.backend, port=start.port,
                      started=now_utc(), n_segments=start.n_segments, meta=dict(start.metadata), pid=os.getpid(),
                      resumed_from=start.extra_attrs.get("resumed_from"))
        fields.update(meta_fields(start.metadata, self.load_g))
        self._put(("start", fields))

    def on_samples(self, block: SampleBlock) -> None:
        pass

    def on_segment(self, segment: SegmentRecord) -> None:
        pass

    def on_event(self, event: EventRecord) -> None:
        pass

    def on_stop(self, stop: RunStop) -> None:
        self._put(("stop", stop))

    def refresh(self, path: str | Path) -> None:
        """Re-read another run file this command changed (the run a resume continues)."""
        self._put(("refresh", Path(path)))

    def close(self, timeout_s: float = 30.0) -> None:
        """Let the queued writes finish (at most ``timeout_s``); warn if they could not."""
        if self._thread is None:
            return
        self._jobs.put(None)
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            self._fail(f"still not written after {timeout_s:g} s")

    # -- the thread -----------------------------------------------------------
    def _put(self, job: tuple[str, Any]) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._work, name="catalogue", daemon=True)
            self._thread.start()
        self._jobs.put(job)

    def _fail(self, why: str) -> None:
        if self.failed is None:
            self.failed = why
            if self._warn is not None:
                self._warn(f"catalogue {shown_url(self.target)}: {why}; the run file {self.path} is complete "
                           f"(register it later: tsa-bench catalogue rebuild {self.path.parent})")

    def _work(self) -> None:
        cat = None
        try:
            cat = open_catalogue(self.target)
            while (job := self._jobs.get()) is not None:
                if self.failed is None:
                    self._do(cat, *job)
        except CatalogueError as exc:
            self._fail(str(exc).removeprefix(f"catalogue {shown_url(self.target)}: "))
        except Exception as exc:  # never let a catalogue problem surface as anything but a warning
            self._fail(f"{type(exc).__name__}: {exc}")
        finally:
            if cat is not None:
                cat.close()

    def _do(self, cat, what: str, arg: Any) -> None:
        if what == "start":
            self.run_id = cat.upsert(arg)
        elif what == "stop":
            stop: RunStop = arg
            if self.path.exists():
                facts = file_facts(self.path)
                facts.update(status=stop.exit_status if facts["status"] in ("running", "killed") else facts["status"])
            else:
                facts = dict(path=str(self.path), status=stop.exit_status, reason=stop.reason, samples=0)
            facts.update(ended=now_utc(), pid=None)
            if self.load_g is not None and facts.get("load_g") is None:
                facts["load_g"] = self.load_g
            if self.run_id is not None:   # the row's start is when the run began, not the file's stamp
                facts.pop("started", None)
            self.run_id = cat.upsert(facts)
        elif what == "refresh":
            if arg.exists():
                cat.upsert(file_facts(arg))
