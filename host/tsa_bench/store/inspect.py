"""Read back a run file's metadata and statistics (for `tsa-bench info` and summaries).

Contract: :func:`inspect_run` reads any file meeting the run-file contract (through
:func:`tsa_bench.store.reader.read_run`, which checks it) and returns plain Python data;
a file that breaks the contract raises :class:`RunFileError` naming the file and what
is wrong.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.store.reader import RunFileError, read_run

__all__ = ["ColumnStats", "RunFileError", "RunInfo", "inspect_run"]


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
    attrs = dict(run.attrs)
    for key in ("device_identity", "metadata"):
        if isinstance(attrs.get(key), str):
            try:
                attrs[key] = json.loads(attrs[key])
            except json.JSONDecodeError:
                pass
    return RunInfo(run.path, attrs, len(run), columns, dict(_kind_counts(segs)), completed,
                   0 if segs is None else len(segs), 0 if events is None else len(events),
                   dict(_kind_counts(events)),
                   (float(t[0]), float(t[-1])) if len(t) else (float("nan"), float("nan")), gaps)
