"""Read back a run file's metadata and statistics (for `tsa-bench info` and summaries).

Contract: :func:`inspect_run` opens any file meeting the run-file contract read-only
and returns plain Python data; a missing file, a non-HDF5 file or a file that is not a
tsa-bench run raises :class:`RunFileError` naming the file and what is wrong.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tsa_bench.store.hdf5 import FORMAT


class RunFileError(ValueError):
    """A file that is not a readable tsa-bench run file."""


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


def _attr(v: Any) -> Any:
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v


def _kind_counts(rows: np.ndarray | None) -> Counter[str]:
    """How many rows of a /segments or /events table have each ``kind``."""
    counts: Counter[str] = Counter()
    if rows is not None and len(rows) and "kind" in (rows.dtype.names or ()):
        counts.update(k.decode() if isinstance(k, bytes) else str(k) for k in rows["kind"])
    return counts


def inspect_run(path: str | Path) -> RunInfo:
    p = Path(path)
    if not p.exists():
        raise RunFileError(f"{p}: no such file")
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise RunFileError(f"{p}: not a readable HDF5 file ({exc})") from None
    with f:
        attrs = {k: _attr(v) for k, v in f.attrs.items()}
        if attrs.get("format") != FORMAT:
            raise RunFileError(f"{p}: root attribute format is {attrs.get('format')!r}, expected {FORMAT!r}")
        if "samples" not in f:
            raise RunFileError(f"{p}: no /samples group")
        columns = {}
        n = None
        for name, ds in f["samples"].items():
            data = ds[()]
            n = len(data) if n is None else n
            if len(data) != n:
                raise RunFileError(f"{p}: /samples/{name} has {len(data)} rows, other columns {n}")
            x = data.astype(float)
            ok = np.isfinite(x)
            columns[name] = ColumnStats(
                units=str(_attr(ds.attrs.get("units", "?"))), count=len(x), finite=int(ok.sum()),
                min=float(x[ok].min()) if ok.any() else float("nan"),
                max=float(x[ok].max()) if ok.any() else float("nan"),
                mean=float(x[ok].mean()) if ok.any() else float("nan"))
        n = n or 0
        t = f["samples/t"][()] if "t" in f["samples"] else np.array([])
        gaps = 0
        if "counter" in f["samples"] and n > 1:
            c = f["samples/counter"][()].astype(np.int64)
            gaps = int(np.clip(np.diff(c) - 1, 0, None).sum())
        segs = f["segments"][()] if "segments" in f else None
        seg_kinds = _kind_counts(segs)
        completed = int(segs["completed"].sum()) if segs is not None and "completed" in (segs.dtype.names or ()) else 0
        events = f["events"][()] if "events" in f else None
        ev_kinds = _kind_counts(events)
        n_seg = 0 if segs is None else len(segs)
        n_ev = 0 if events is None else len(events)
        for key in ("device_identity", "metadata"):
            if isinstance(attrs.get(key), str):
                try:
                    attrs[key] = json.loads(attrs[key])
                except json.JSONDecodeError:
                    pass
        return RunInfo(str(p), attrs, n, columns, dict(seg_kinds), completed, n_seg, n_ev, dict(ev_kinds),
                       (float(t[0]), float(t[-1])) if len(t) else (float("nan"), float("nan")), gaps)
