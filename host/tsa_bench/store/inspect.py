"""Read back a run file's metadata and statistics (for `tsa-bench info` and summaries).

Contract: :func:`inspect_run` reads any file meeting the run-file contract (through
:func:`tsa_bench.store.reader.read_run`, which checks it) and returns plain Python data;
a file that breaks the contract raises :class:`RunFileError` naming the file and what
is wrong. :class:`RunningStats` gives the same summary from the rows as they are
written (the run writer keeps one), so a run's closing summary never reads the file back.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.store.reader import RunFileError, read_run

__all__ = ["ColumnStats", "RunFileError", "RunInfo", "RunningStats", "inspect_run"]


@dataclass
class ColumnStats:
    units: str
    count: int
    finite: int
    min: float
    max: float
    mean: float


@dataclass
class RunInfo:
    path: str
    attrs: dict[str, Any]
    n_samples: int
    columns: dict[str, ColumnStats]
    segment_kinds: dict[str, int]
    segments_completed: int
    n_segments: int
    n_events: int
    event_kinds: dict[str, int]
    t_range: tuple[float, float]
    counter_gaps: int
    extra: dict[str, Any] = field(default_factory=dict)


def _kind_counts(rows: np.ndarray | None) -> Counter[str]:
    """How many rows of a /segments or /events table have each ``kind``."""
    counts: Counter[str] = Counter()
    if rows is not None and len(rows) and "kind" in (rows.dtype.names or ()):
        counts.update(k.decode() if isinstance(k, bytes) else str(k) for k in rows["kind"])
    return counts


class RunningStats:
    """The statistics of :func:`inspect_run`, kept while a file is written (memory flat in
    run length): fed the rows as they are stored, it gives the same :class:`RunInfo`
    without reading the file back."""

    def __init__(self, units: dict[str, str]) -> None:
        self.units = dict(units)
        self.n = 0
        self._finite = dict.fromkeys(units, 0)
        self._min = dict.fromkeys(units, float("inf"))
        self._max = dict.fromkeys(units, float("-inf"))
        self._sum = dict.fromkeys(units, 0.0)
        self.t_first = self.t_last = float("nan")
        self._last_counter: float | None = None
        self.counter_gaps = 0
        self.segment_kinds: Counter[str] = Counter()
        self.segments = self.segments_completed = 0
        self.event_kinds: Counter[str] = Counter()
        self.events = 0

    def add_samples(self, columns: dict[str, np.ndarray]) -> None:
        k = len(columns["t"])
        if not k:
            return
        for name in self.units:
            x = columns[name].astype(float)
            ok = np.isfinite(x)
            finite = int(ok.sum())
            if finite:
                xs = x[ok] if finite < k else x
                self._finite[name] += finite
                self._min[name] = min(self._min[name], float(xs.min()))
                self._max[name] = max(self._max[name], float(xs.max()))
                self._sum[name] += float(xs.sum())
        t = columns["t"]
        if self.n == 0:
            self.t_first = float(t[0])
        self.t_last = float(t[-1])
        c = columns["counter"].astype(float)
        c = c[np.isfinite(c)]
        if len(c):
            if self._last_counter is not None:
                c = np.concatenate([[self._last_counter], c])
            if len(c) > 1:
                self.counter_gaps += int(np.clip(np.diff(c) - 1, 0, None).sum())
            self._last_counter = float(c[-1])
        self.n += k

    def add_segments(self, rows: np.ndarray, kind_names: list[str] | None = None) -> None:
        """Rows of /segments; with ``kind_names``, ``kind`` holds codes into it (the stored layout)."""
        self.segments += len(rows)
        self.segments_completed += int(rows["completed"].sum())
        if kind_names is None:
            self.segment_kinds.update(_kind_counts(rows))
        else:
            codes, counts = np.unique(rows["kind"], return_counts=True)
            self.segment_kinds.update({kind_names[c]: int(n) for c, n in zip(codes, counts)})

    def add_events(self, rows: np.ndarray) -> None:
        self.events += len(rows)
        self.event_kinds.update(_kind_counts(rows))

    def info(self, path: str, attrs: dict[str, Any]) -> RunInfo:
        """The summary, with the file's attributes ``attrs`` (as :func:`inspect_run` gives them)."""
        nan = float("nan")
        columns = {}
        for name, units in self.units.items():
            f = self._finite[name]
            columns[name] = ColumnStats(units, self.n, f, self._min[name] if f else nan,
                                        self._max[name] if f else nan, self._sum[name] / f if f else nan)
        return RunInfo(path, _decoded(attrs), self.n, columns, dict(self.segment_kinds), self.segments_completed,
                       self.segments, self.events, dict(self.event_kinds),
                       (self.t_first, self.t_last) if self.n else (nan, nan), self.counter_gaps)


def _decoded(attrs: dict[str, Any]) -> dict[str, Any]:
    attrs = dict(attrs)
    for key in ("device_identity", "metadata"):
        if isinstance(attrs.get(key), str):
            try:
                attrs[key] = json.loads(attrs[key])
            except json.JSONDecodeError:
                pass
    return attrs


def inspect_run(path: str | Path) -> RunInfo:
    """Summary statistics of a run file checked against the contract (see :func:`read_run`)."""
    run = read_run(path)
    columns = {}
    for name, data in run.samples.items():
        x = data.astype(float)
        ok = np.isfinite(x)
        columns[name] = ColumnStats(
            units=run.units[name], count=len(x), finite=int(ok.sum()),
            min=float(x[ok].min()) if ok.any() else float("nan"),
            max=float(x[ok].max()) if ok.any() else float("nan"),
            mean=float(x[ok].mean()) if ok.any() else float("nan"))
    t = run.t_s
    gaps = 0
    counter = run.samples.get("counter")
    if counter is not None and len(run) > 1:
        c = counter.astype(float)
        c = c[np.isfinite(c)]  # a foreign file's float counter may hold NaN
        gaps = int(np.clip(np.diff(c) - 1, 0, None).sum()) if len(c) > 1 else 0
    segs, events = run.segments, run.events
    completed = int(segs["completed"].sum()) if segs is not None and "completed" in (segs.dtype.names or ()) else 0
    attrs = _decoded(run.attrs)
    return RunInfo(run.path, attrs, len(run), columns, dict(_kind_counts(segs)), completed,
                   0 if segs is None else len(segs), 0 if events is None else len(events),
                   dict(_kind_counts(events)),
                   (float(t[0]), float(t[-1])) if len(t) else (float("nan"), float("nan")), gaps)
