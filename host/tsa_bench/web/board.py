"""The live board: every run being recorded, followed from its sidecars, in bounded memory.

Units: ``t`` and durations in s of device time (``eta_s`` in wall-clock s), length in mm,
resistance in ohm (None where not measured), twist in turns, heater in V, load in N.

Contract: :class:`Board` finds the runs being recorded (``*.h5.live`` in the runs folder,
and the live sidecars of the catalogue's running rows, :meth:`Board.add_sidecar`) and
follows each with :class:`~tsa_bench.store.live.LiveTail` (samples, and the events the
sidecar's journal carries): read-only, no lock, never the run file, so the recording
process never waits for the board. :meth:`Board.poll` returns one update per
run that changed (new points, new events, new state) and :meth:`Board.snapshot` the
whole board, both JSON-ready. Memory is bounded whatever the run's length: at most
:data:`MAX_POINTS` points per run (when full, every other point is dropped, so the whole
run stays in view at a coarser step), at most :data:`POINTS_PER_POLL` new points per run
per poll (evenly spread, the newest always kept), :data:`MAX_EVENTS` events per run,
:data:`MAX_RUNS` runs; an ended run stays on the board :data:`KEEP_ENDED_S` (wall) with its
final status, then leaves it (the catalogue lists it).
"""

from __future__ import annotations

import collections
import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.store.live import LiveFormatError, LiveTail

#: Channels plotted, as (column of the sidecar, key on the page).
CHANNELS = (("length", "length"), ("resistance", "resistance"), ("turns", "twist"),
            ("heater_voltage", "heater"), ("load", "load"))
MAX_POINTS = 4000
POINTS_PER_POLL = 16
MAX_EVENTS = 200
#: Characters of an event's detail shown.
MAX_DETAIL_CHARS = 1000
MAX_RUNS = 64
KEEP_ENDED_S = 600.0
#: Wall-clock window (s) over which the device-time rate behind the ETA is measured.
RATE_WINDOW_S = 20.0

_FAULT_KINDS = {"fault", "fault_at_start", "limit_hit", "motor_released", "position_suspect", "killed"}
_WARNING_KINDS = {"sample_gap", "queue_underrun", "step_underrun", "not_settled", "i2c_recovered",
                  "sensor_restarted", "stopped", "stop_sent", "events_truncated", "unreadable"}


def severity(kind: str) -> str:
    """"fault", "warning" or "info" for an event kind (the page colours it)."""
    if kind in _FAULT_KINDS or ("fault" in kind and kind != "fault_cleared"):
        return "fault"
    if kind in _WARNING_KINDS or any(w in kind for w in ("warn", "lost", "gap", "underrun", "error")):
        return "warning"
    return "info"


def _number(x: float) -> float | None:
    """JSON has no NaN: a value not measured is None."""
    x = float(x)
    return round(x, 6) if math.isfinite(x) else None


class History:
    """At most ``cap`` points of ``t`` and the channels; when full, every other point goes."""

    def __init__(self, cap: int = MAX_POINTS) -> None:
        self.cap = cap
        self.cols: dict[str, list[float | None]] = {"t": [], **{key: [] for _, key in CHANNELS}}

    def __len__(self) -> int:
        return len(self.cols["t"])

    def extend(self, points: dict[str, list[float | None]]) -> None:
        for key, values in points.items():
            self.cols[key].extend(values)
        if len(self) > self.cap:
            for key in self.cols:
                self.cols[key] = self.cols[key][::2]


def pick(n: int, k: int) -> np.ndarray:
    """Indices of at most ``k`` of ``n`` records, evenly spread, the last always among them."""
    if n <= k:
        return np.arange(n)
    return np.unique(np.linspace(n - 1, 0, k).round().astype(int))


@dataclass
class LiveRun:
    """One run being followed (module contract)."""

    key: str
    run_path: Path
    tail: LiveTail
    info: dict[str, Any] = field(default_factory=dict)   # from the catalogue: rig, sample, load_g, id, reason
    history: History = field(default_factory=History)
    event_log: collections.deque = field(default_factory=lambda: collections.deque(maxlen=MAX_EVENTS))
    samples: int = 0
    latest: dict[str, float | None] = field(default_factory=dict)
    segment: int | None = None
    status: str = "running"
    ended_wall: float | None = None
    first_sample_wall: float | None = None
    counts: dict[str, int] = field(default_factory=lambda: {"fault": 0, "warning": 0})
    _rate: collections.deque = field(default_factory=collections.deque)   # (wall s, device t)

    @property
    def header(self) -> dict[str, Any]:
        return self.tail.header

    def poll(self, now: float) -> dict[str, Any] | None:
        """The run's update since the last call, or None when nothing changed."""
        if self.status != "running":
            return None
        update: dict[str, Any] = {}
        rec, new_events = self._read()
        if len(rec):
            if self.first_sample_wall is None:
                self.first_sample_wall = now
            self.samples += len(rec)
            idx = pick(len(rec), POINTS_PER_POLL)
            points = {"t": [_number(x) for x in rec["t"][idx]]}
            for column, key in CHANNELS:
                points[key] = [_number(x) for x in rec[column][idx]]
            self.history.extend(points)
            update["points"] = points
            last = rec[-1]
            self.latest = {"t": _number(last["t"]), **{key: _number(last[column]) for column, key in CHANNELS}}
            self.segment = int(last["segment"])
            self._rate.append((now, float(last["t"])))
            while len(self._rate) > 2 and now - self._rate[0][0] > RATE_WINDOW_S:
                self._rate.popleft()
        if self.tail.ended:
            self._end(self.tail.ended, now)
        elif self.tail.writer_alive() is False:
            rec, late = self._read()   # whatever it wrote before dying is not plotted; the end is what matters
            self.samples += len(rec)
            new_events += late
            if not self.tail.ended:
                new_events.append({"t": self.latest.get("t"), "kind": "killed",
                                   "detail": f"the recording process {self.header.get('pid')} is gone without "
                                             "ending the run; the run file holds the data up to its last flush"})
            self._end(self.tail.ended or "killed", now)
        if new_events:
            for e in new_events:
                e["severity"] = severity(e["kind"])
                if e["severity"] in self.counts:
                    self.counts[e["severity"]] += 1
            self.event_log.extend(new_events)
            update["events"] = new_events
        if not update and self.status == "running":
            return None
        update["state"] = self.state(now)
        return update

    def _read(self) -> tuple[np.ndarray, list[dict[str, Any]]]:
        """The sidecar's new sample records and events (the newest :data:`MAX_EVENTS`)."""
        parts: list[np.ndarray] = []
        events: collections.deque = collections.deque(maxlen=MAX_EVENTS)
        for kind, value in self.tail.items():
            if kind == "samples":
                parts.append(value)
            elif kind == "event":
                t, name, detail = value
                t = _number(t) if isinstance(t, (int, float)) and not isinstance(t, bool) else None
                events.append({"t": t, "kind": str(name)[:64], "detail": str(detail)[:MAX_DETAIL_CHARS]})
        if not parts:
            rec = np.zeros(0, dtype=self.tail.dtype)
        else:
            rec = parts[0] if len(parts) == 1 else np.concatenate(parts)
        return rec, list(events)

    def _end(self, status: str, now: float) -> None:
        self.status = status
        self.ended_wall = now
        self.tail.close()

    def eta_s(self, now: float) -> float | None:
        """Wall-clock seconds to the plan's estimated end at the device-time rate of late."""
        est = self.header.get("estimated_duration_s")
        t = self.latest.get("t")
        if self.status != "running" or not isinstance(est, (int, float)) or t is None or len(self._rate) < 2:
            return None
        (w0, t0), (w1, t1) = self._rate[0], self._rate[-1]
        if w1 - w0 <= 0 or t1 <= t0:
            return None
        return max(0.0, float(est) - t) / ((t1 - t0) / (w1 - w0))

    def state(self, now: float) -> dict[str, Any]:
        h = self.header
        return {"status": self.status, "reason": self.info.get("reason") or "", "samples": self.samples,
                "segment": None if self.segment is None else self.segment + 1, "n_segments": h.get("n_segments"),
                "latest": self.latest, "eta_s": self.eta_s(now), "estimated_duration_s": h.get("estimated_duration_s"),
                "faults": self.counts["fault"], "warnings": self.counts["warning"],
                "rig": self.info.get("rig"), "sample": self.info.get("sample"), "load_g": self.info.get("load_g"),
                "id": self.info.get("id")}

    def snapshot(self, now: float) -> dict[str, Any]:
        h = self.header
        return {"key": self.key, "run_file": self.run_path.name, "plan": h.get("plan_name"), "host": h.get("host"),
                "started": h.get("started"), "points": {k: list(v) for k, v in self.history.cols.items()}, "events": list(self.event_log),
                "state": self.state(now)}


class Board:
    """Every run being recorded (module contract)."""

    def __init__(self, runs_dir: str | Path | None) -> None:
        self.runs_dir = Path(runs_dir) if runs_dir is not None else None
        self.runs: dict[Path, LiveRun] = {}
        self._refused: dict[Path, str] = {}   # sidecars that are not ones, said once
        self._extra: set[Path] = set()        # sidecars named by the catalogue
        self._keys = 0
        self._lock = threading.Lock()   # poll in a worker thread, snapshot for a new page: one at a time

    def add_sidecar(self, sidecar: str | Path) -> None:
        """Follow this sidecar too (a running catalogue row's ``live_path``), when it exists."""
        self._extra.add(Path(sidecar))

    def _candidates(self) -> set[Path]:
        found = set(self._extra)
        if self.runs_dir is not None:
            try:
                found.update(p for p in self.runs_dir.glob("*.h5.live"))
            except OSError:
                pass
        return found

    def _open(self, sidecar: Path) -> None:
        try:
            tail = LiveTail(sidecar)
        except FileNotFoundError:
            self._extra.discard(sidecar)
            return
        except (LiveFormatError, OSError) as exc:
            self._refused[sidecar] = str(exc)
            return
        run_path = sidecar.with_name(sidecar.name[: -len(".live")])
        self._keys += 1
        self.runs[sidecar] = LiveRun(f"r{self._keys}", run_path, tail)

    def poll(self, now: float | None = None) -> list[dict[str, Any]]:
        """One update per run that changed since the last call (``{"key", "points"?,
        "events"?, "state"}``; a run new to the board comes whole, as in :meth:`snapshot`,
        with ``"new": True``; one that left it as ``{"key", "gone": True}``)."""
        now = time.monotonic() if now is None else now
        with self._lock:
            return self._poll(now)

    def _poll(self, now: float) -> list[dict[str, Any]]:
        updates: list[dict[str, Any]] = []
        for sidecar in sorted(self._candidates()):
            if sidecar not in self.runs and sidecar not in self._refused and len(self.runs) < MAX_RUNS:
                self._open(sidecar)
                if sidecar in self.runs:
                    run = self.runs[sidecar]
                    run.poll(now)
                    updates.append({**run.snapshot(now), "new": True})
        for sidecar, run in list(self.runs.items()):
            if run.status != "running" and now - (run.ended_wall or now) > KEEP_ENDED_S:
                del self.runs[sidecar]
                self._extra.discard(sidecar)
                updates.append({"key": run.key, "gone": True})
                continue
            if any(u.get("key") == run.key for u in updates):
                continue
            update = run.poll(now)
            if update is not None:
                updates.append({"key": run.key, **update})
        return updates

    def set_info(self, sidecar: Path, info: dict[str, Any], now: float | None = None) -> dict[str, Any] | None:
        """Catalogue facts about a followed run (rig, sample, load, id, the end's reason);
        the run's new state when they changed something, else None."""
        now = time.monotonic() if now is None else now
        with self._lock:
            run = self.runs.get(sidecar)
            if run is None or all(run.info.get(k) == v for k, v in info.items()):
                return None
            run.info.update(info)
            return {"key": run.key, "state": run.state(now)}

    def followed(self) -> dict[Path, tuple[Path, str]]:
        """sidecar -> (run file, status) of every run on the board."""
        with self._lock:
            return {side: (run.run_path, run.status) for side, run in self.runs.items()}

    def snapshot(self, now: float | None = None) -> list[dict[str, Any]]:
        now = time.monotonic() if now is None else now
        with self._lock:
            return [run.snapshot(now) for run in self.runs.values()]

    def close(self) -> None:
        with self._lock:
            for run in self.runs.values():
                if run.status == "running":
                    run.tail.close()
