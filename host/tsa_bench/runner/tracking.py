"""``track_length`` inside the run engine: the estimator on every sample, the controller on its segment.

Units: time in s of device time, length in mm, resistance in ohm, twist in turns.

Execution contract (:class:`Tracking`, created by the engine when the plan has a
``track_length`` segment): one :class:`~tsa_bench.control.estimator.OnlineLengthEstimator`
per (model file, window) runs on every sample of the run from its first, so its
hysteresis, creep and transient states are those of the whole history. While a
``track_length`` segment runs, its :class:`~tsa_bench.control.controller.StepController`
sees each of the segment's samples (resistance, motor flag, twist; never the position
sensor) and decides once per sample; the engine sends what it decided: a MOVE_TO of the
correction (at the step's rate and acceleration; the device enforces its limits) or,
while there is nothing to correct, DWELLs of one sampling period, at most
:data:`IN_FLIGHT` commands queued, so a decision reaches the device within two sampling
periods. Every stored sample gets ``length_estimate`` (mm, NaN while moving or without
resistance), ``length_target`` (mm, NaN outside tracking) and ``controller_state``
(:data:`~tsa_bench.control.controller.STATES`). The segment's parameters say which
controller ran and what it did (targets reached, time to reach, corrections). A
controller failure (estimate outside the validity range, ``on_timeout: fail``) ends the
run as failed through the engine's safe stop, like a Ctrl-C ends it aborted.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tsa_bench.control.controller import IDLE, STATES, StepController
from tsa_bench.plan import Plan, Segment, SetSampling, TrackLength
from tsa_bench.protocol import msg
from tsa_bench.runner.commands import WIRE_SEGMENTS
from tsa_bench.rundocs import SampleBlock

if TYPE_CHECKING:
    from tsa_bench.runner.engine import Runner

IN_FLIGHT = 2
#: The decay after a stop is taken as settled from this time on (s; thesis 2.5.2: about two minutes).
TRANSIENT_SETTLED_S = 120.0
#: The first this many seconds of each hold are left out of the estimate (s; estimator.skip_s).
SKIP_S = 0.5
#: Extra sample columns of a plan with track_length: name -> (dtype, units, attributes).
COLUMNS: dict[str, tuple[str, str, dict[str, str]]] = {
    "length_estimate": ("f8", "mm", {"description": "length estimated from resistance by the self-sensing model"}),
    "length_target": ("f8", "mm", {"description": "target length of the running track_length (NaN outside)"}),
    "controller_state": ("u1", "1", {"description": "state of the track_length controller",
                                     "states": ", ".join(f"{k}={v}" for k, v in STATES.items())}),
}


class Tracking:
    """The ``track_length`` segments of one plan (see the module contract)."""

    def __init__(self, plan: Plan, steps_per_turn: int) -> None:
        self.plan, self.spt = plan, steps_per_turn
        self._estimators: dict[tuple[str, float], Any] = {}   # OnlineLengthEstimator / TwistResistanceEstimator
        self._load_error: str | None = None
        self._periods: dict[int, float] = {}
        period = plan.sampling_period_s
        for seg in plan.segments:
            if isinstance(seg.action, SetSampling):
                period = seg.action.period_s
            elif isinstance(seg.action, TrackLength):
                self._periods[seg.index] = period
                self._estimator(seg.action)
        self._records: list[tuple[float, float, int]] = []
        self._last_turns = 0.0
        self.controller: StepController | None = None
        self._index = -1
        self._move_part = 0
        self.decide_s: list[float] = []   # host time of each sample's estimate + decision (s)
        self.command_latency_s: list[float] = []   # host time from a deciding sample to its MOVE_TO sent (s)
        self._decided_wall = 0.0

    @classmethod
    def for_plan(cls, plan: Plan, steps_per_turn: int) -> Tracking | None:
        return cls(plan, steps_per_turn) if any(isinstance(s.action, TrackLength) for s in plan.segments) else None

    def _estimator(self, a: TrackLength) -> Any:
        key = (a.model_path, a.window_s)
        if key not in self._estimators:  # (scipy and the models load only for a plan that tracks)
            from tsa_bench.models import load_strain
            from tsa_bench.control.estimator import OnlineLengthEstimator, TwistResistanceEstimator
            from tsa_bench.models.fitting import from_saved
            from tsa_bench.models.saved import ModelFileError, load_model_file
            from tsa_bench.plan.tracking_step import _format

            try:
                if _format(Path(a.model_path)) == load_strain.FORMAT:
                    self._estimators[key] = TwistResistanceEstimator(load_strain.load(a.model_path), a.window_s,
                                                                     SKIP_S)
                else:
                    self._estimators[key] = OnlineLengthEstimator(
                        from_saved(load_model_file(a.model_path)), window_s=a.window_s, skip_s=SKIP_S,
                        transient_settled_s=TRANSIENT_SETTLED_S)
            except (ModelFileError, load_strain.LoadStrainError) as exc:
                self._load_error = str(exc)
                return None
        return self._estimators[key]

    # -- samples ---------------------------------------------------------------
    def on_sample(self, t_s: float, resistance_ohm: float, moving: bool, turns: float, segment: int) -> None:
        """Every stored sample, in order (exactly one record each, for :meth:`annotate`)."""
        t0 = time.perf_counter()
        self._last_turns = turns
        estimates = {key: (e.update(t_s, resistance_ohm, moving, turns) if hasattr(e, "last_load_N")
                           else e.update(t_s, resistance_ohm, moving)) for key, e in self._estimators.items()}
        c = self.controller
        if c is not None and segment == self._index:
            if not c.started:
                c.start(t_s, turns)
            a = c.action
            est = estimates.get((a.model_path, a.window_s), math.nan)
            had = c.command
            c.observe(t_s, est, math.isfinite(resistance_ohm), moving, turns)
            if c.command is not None and had is None:
                self._decided_wall = time.perf_counter()
            self._records.append((est, c.target_mm, c.state))
            self.decide_s.append(time.perf_counter() - t0)
        else:
            est = next(iter(estimates.values()), math.nan)
            self._records.append((est, math.nan, IDLE))

    def annotate(self, block: SampleBlock) -> None:
        """Add the tracking columns to a block of the samples seen (in order)."""
        n = len(block)
        rec, self._records = self._records[:n], self._records[n:]
        a = np.array(rec, dtype=float).reshape(-1, 3)
        for j, name in enumerate(COLUMNS):
            block.columns[name] = a[:, j].astype(COLUMNS[name][0])

    # -- sending -----------------------------------------------------------------
    def feed(self, runner: Runner, seg: Segment) -> bool:
        """Queue what the segment's controller decided; end the segment once it is done.
        False when nothing more can be sent now (the engine's contract for _feed_settle)."""
        from tsa_bench.runner.engine import RunFailed

        idx = seg.index
        if self._load_error:
            raise RunFailed(f"track_length at {seg.source}: {self._load_error}")
        c = self.controller
        if c is None or self._index != idx:
            a: TrackLength = seg.action  # type: ignore[assignment]
            lo, hi = self.plan.limits.min_twist_turns, self.plan.limits.max_twist_turns
            c = self.controller = StepController(a, (lo, hi))
            self._index = idx   # it starts at the segment's first sample (the device may still be busy before)
            runner._event("tracking", f"segment {idx}: track_length with the self-sensing step controller, "
                                      f"targets {', '.join(f'{t:g}' for t, _ in a.targets)} mm")
        if c.failure:
            runner._settle_outcome[idx] = c.outcome()
            raise RunFailed(f"track_length at {seg.source}: {c.failure}")
        if self._move_part and runner._parts_done[idx] >= self._move_part:
            self._move_part = 0
            c.move_done(runner._t(runner._now_us))
        if c.done:
            runner._settle_outcome[idx] = c.outcome()
            reached = sum(o.reached for o in c.outcomes)
            runner._event("tracking_done", f"segment {idx}: {reached} of {len(c.outcomes)} targets reached")
            runner._next += 1
            self.controller = None
            if runner._parts_done[idx] >= runner._parts[idx]:
                t_end = runner._t(runner._now_us)
                start = runner._t_start[idx]
                runner._finish_segment(idx, t_end if math.isnan(start) else float(start), t_end, True)
            return True
        if runner._parts[idx] - runner._parts_done[idx] >= IN_FLIGHT:
            return False
        wire = idx % WIRE_SEGMENTS
        a = c.action
        if c.command is not None:
            turns = c.command[1]
            command: Any = msg.MoveTo(wire, round(turns * self.spt), max(1, round(a.rate_turns_per_s * self.spt)),
                                      max(1, round(a.accel_turns_per_s2 * self.spt)))
        else:
            command = msg.Dwell(wire, max(1, round(self._periods.get(idx, 0.1) * 1e6)))
        if not _send(runner, seg, command):
            return False
        if c.command is not None:
            c.command = None
            self._move_part = int(runner._parts[idx])
            self.command_latency_s.append(time.perf_counter() - self._decided_wall)
        return True


def _send(runner: Runner, seg: Segment, command: Any) -> bool:
    """Queue one device command of ``seg`` (False: the queue is full, try later)."""
    if not runner._accepted(runner._command(command), seg):
        return False
    runner._parts[seg.index] += 1
    return True


def bench_problems(plan: Plan, bench_name: str) -> list[str]:
    """``"source: why"`` for each track_length whose model was identified on another bench's runs."""
    out = []
    for seg in plan.segments:
        a = seg.action
        if isinstance(a, TrackLength) and a.model_bench is not None and a.model_bench != bench_name:
            out.append(f"{seg.source}: the model {a.model_path} was identified on runs of bench "
                       f"'{a.model_bench}', not on this bench '{bench_name}' (another string); fit one on this bench")
    return sorted(set(out))
