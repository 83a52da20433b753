"""Resume an aborted, failed or killed run from its first incomplete segment.

Units: twist in turns, rates in turns/s and turns/s^2, voltage in V, period in s, mass in g.

Contract: :func:`resume_point` takes the first run (as read by
:func:`~tsa_bench.store.read_run`) and its plan compiled again from the protocol text
it stored, and returns the :class:`ResumePoint`: the first segment to run and the
state the plan had at its start (the target of the last move before it, the rate and
acceleration of that move - or, when a ``track_length`` came after that move, the twist
the run recorded at the end of it, at the track's rate - the heater voltage, the sampling
period and the declared load). The first segment to run is the first one the run did not complete; a segment
whose samples show the device had moved past it counts as completed (its SEGMENT_DONE
may have been lost, or the run was killed before its record was flushed), and the one
the device was executing is run again from its start. The runner brings the rig to that
state with set-up commands, then runs the plan from there; the new file is linked to
the first by its root attributes :meth:`ResumePoint.attributes`.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.plan import Move, Plan, Prompt, SetHeater, SetSampling, TrackLength


class CannotResume(ValueError):
    """The run cannot be resumed; the message says why."""


@dataclass(frozen=True)
class ResumePoint:
    """Where a resumed run starts and the state the plan had there (module contract)."""

    source: str                   # the first run file
    source_created: str           # its `created` attribute (identifies it)
    first_segment: int
    n_segments: int
    turns: float
    rate_turns_per_s: float
    accel_turns_per_s2: float
    heater_V: float
    sampling_period_s: float
    load_g: float | None
    source_line: str = ""

    def attributes(self) -> dict[str, Any]:
        """Root attributes of the new run file linking it to the first one: its file name,
        absolute path and ``created`` time, and the first segment this file holds."""
        src = Path(self.source)
        return {"resumed_from": src.name, "resumed_from_path": str(src.resolve()),
                "resumed_from_created": self.source_created, "first_segment": self.first_segment}

    def describe(self) -> str:
        load = "undeclared" if self.load_g is None else f"{self.load_g:g} g"
        return (f"resuming {Path(self.source).name} at segment {self.first_segment} of {self.n_segments}"
                + (f" ({self.source_line})" if self.source_line else "")
                + f": twist {self.turns:g} turns, heater {self.heater_V:g} V, sampling {self.sampling_period_s:g} s, "
                  f"load {load}")


def first_incomplete(segments: np.ndarray | None, segment_column: np.ndarray, n_segments: int) -> int:
    """The first plan segment to run again (module contract)."""
    done = np.zeros(n_segments, dtype=bool)
    if segments is not None and len(segments):
        idx = np.asarray(segments["index"], dtype=np.int64)
        completed = np.asarray(segments["completed"], dtype=bool)
        ok = completed & (idx >= 0) & (idx < n_segments)
        done[idx[ok]] = True
    seen = np.asarray(segment_column, dtype=np.int64)
    seen = seen[(seen >= 0) & (seen < n_segments)]
    if len(seen):
        done[: int(seen.max())] = True   # the device executes in order: everything before it is done
    open_ = np.flatnonzero(~done)
    return int(open_[0]) if len(open_) else n_segments


def resume_point(run, plan: Plan, path: str | Path) -> ResumePoint:
    """The :class:`ResumePoint` of ``run`` (a RunData) on ``plan``; CannotResume when
    there is nothing to resume."""
    status = run.exit_status
    if status == "success":
        raise CannotResume(f"{path}: the run ended in success; there is nothing to resume")
    if status not in ("aborted", "failed", "running"):
        raise CannotResume(f"{path}: exit_status {status!r} is not one tsa-bench resumes (aborted, failed, killed)")
    n = len(plan.segments)
    if run.segments is not None and len(run.segments) and int(np.max(run.segments["index"])) >= n:
        raise CannotResume(f"{path}: its segments do not belong to the protocol it stored ({n} segments)")
    k = first_incomplete(run.segments, run.samples["segment"], n)
    if k >= n:
        raise CannotResume(f"{path}: every segment of the protocol was done; there is nothing to resume")
    move: Move | None = None
    tracked: int | None = None     # a track_length after the last move: its twist was decided while running
    heater, period, load = 0.0, plan.sampling_period_s, plan.load_g
    for seg in itertools.islice(plan.segments, k):
        a = seg.action
        if isinstance(a, Move):
            move, tracked = a, None
        elif isinstance(a, TrackLength):
            tracked = seg.index
        elif isinstance(a, SetHeater):
            heater = a.voltage_V
        elif isinstance(a, SetSampling):
            period = a.period_s
        elif isinstance(a, Prompt) and a.load_g is not None:
            load = a.load_g
    if move is None:  # nothing moved yet: back to the start's twist zero, gently
        first_move = next((s.action for s in plan.segments if isinstance(s.action, Move)), None)
        rate = first_move.rate_turns_per_s if first_move else min(1.0, plan.limits.max_rate_turns_per_s or 1.0)
        accel = first_move.accel_turns_per_s2 if first_move else min(1.0, plan.limits.max_accel_turns_per_s2 or 1.0)
        turns = 0.0
    else:
        turns, rate, accel = move.target_turns, move.rate_turns_per_s, move.accel_turns_per_s2
    if tracked is not None:  # the twist the run recorded at the end of that track_length
        seg_col = np.asarray(run.samples["segment"])
        rows = np.flatnonzero(seg_col == tracked)
        if not len(rows):
            raise CannotResume(f"{path}: no samples of the track_length segment {tracked}; its final twist is unknown")
        t_action: TrackLength = plan.segments[tracked].action  # type: ignore[assignment]
        turns = float(np.asarray(run.samples["turns"])[rows[-1]])
        rate, accel = t_action.rate_turns_per_s, t_action.accel_turns_per_s2
    return ResumePoint(str(path), str(run.attrs.get("created", "")), k, n, turns, rate, accel, heater, period,
                       load, plan.segments[k].source)
