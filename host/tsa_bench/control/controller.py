"""The step controller of ``track_length``: twist corrections judged on the resistance estimate.

Units: length in mm, twist in turns, time in s of device time.

Contract (:class:`StepController`, one per ``track_length`` segment): it sees every
sample of its segment (:meth:`observe`: time, the length estimate from resistance or
NaN, whether resistance was measured, whether the motor turns, the twist) and decides
once per sample. It never sees the position sensor. States (:data:`STATES`, the
``controller_state`` column):

* ``settling``: after a stop (and at the start) the estimate is judged only once
  ``settle_s`` have passed since the stop, when the transient decay has faded enough.
* ``moving``: a correction is queued or running; nothing is judged until it is done.
* ``on_target``: |target - estimate| <= ``tolerance_mm``; the target's ``hold_s``
  counts from the first time it is reached. A new correction only when the error grows
  beyond 1.5 x ``tolerance_mm`` (a band against chattering on noise).
* ``no_resistance``: resistance not measured (heater on): hold; on its return, settle again.
* ``saturated``: the correction would pass a twist limit: hold at the limit.

A correction moves by ``gain x error / slope`` turns (at most ``max_step_turns``,
within the twist limits), ``slope`` being dL/dturn: ``initial_mm_per_turn`` at first,
then updated from the estimates before and after each correction of at least half a
turn (halfway towards the measured secant, when it has the same sign and is within a
factor 10). Each target ends ``hold_s`` after it was reached, or ``timeout_s`` after it
began without being reached (``on_timeout``: ``continue`` records it, ``fail`` ends the
run). The run ends failed as soon as an estimate the controller judges (``settle_s``
after a stop) lies outside the model's validity range widened by
:data:`VALIDITY_MARGIN` of its width on each side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from tsa_bench.plan.actions import TrackLength

#: controller_state codes (u1) and their names; 0 = no track_length running
STATES: dict[int, str] = {0: "idle", 1: "settling", 2: "moving", 3: "on_target", 4: "no_resistance",
                          5: "saturated"}
IDLE, SETTLING, MOVING, ON_TARGET, NO_RESISTANCE, SATURATED = range(6)
#: Retrigger band: an on-target controller corrects again beyond this x tolerance_mm.
RETRIGGER = 1.5
#: Fraction of the validity range's width by which the estimate may leave it before the run stops.
VALIDITY_MARGIN = 0.1
#: Smallest correction worth a move (turns).
MIN_STEP_TURNS = 0.02


@dataclass
class TargetOutcome:
    length_mm: float
    hold_s: float
    t_start_s: float
    reached: bool = False
    time_to_reach_s: float | None = None
    final_estimate_mm: float | None = None
    corrections: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {"length_mm": self.length_mm, "hold_s": self.hold_s, "reached": self.reached,
                "time_to_reach_s": self.time_to_reach_s, "final_estimate_mm": self.final_estimate_mm,
                "corrections": self.corrections}


@dataclass
class StepController:
    """See the module contract. ``twist_limits_turns`` = (lowest, highest) twist allowed."""

    action: TrackLength
    twist_limits_turns: tuple[float | None, float | None]
    state: int = SETTLING
    command: tuple[str, float] | None = None    # ("move", turns) waiting to be sent
    done: bool = False
    failure: str | None = None
    slope_mm_per_turn: float = 0.0
    outcomes: list[TargetOutcome] = field(default_factory=list)
    _index: int = 0
    _settle_from: float = 0.0
    _reached_at: float | None = None
    _turns_cmd: float = math.nan
    _estimate: float = math.nan
    _before: tuple[float, float] | None = None   # (estimate, twist) before the last correction
    _t: float = 0.0
    started: bool = False

    def __post_init__(self) -> None:
        self.slope_mm_per_turn = self.action.initial_mm_per_turn

    @property
    def target_mm(self) -> float:
        return self.action.targets[self._index][0] if not self.done else math.nan

    def start(self, t_s: float, turns: float) -> None:
        """The segment's first sample: time and twist it starts from."""
        self.started = True
        self._t = self._settle_from = t_s
        self._turns_cmd = turns
        self.outcomes.append(TargetOutcome(*self.action.targets[0], t_s))

    def move_done(self, t_s: float) -> None:
        """The queued correction has been executed by the device."""
        if self.state == MOVING:
            self.state = SETTLING
            self._settle_from = t_s

    def observe(self, t_s: float, estimate_mm: float, resistance_measured: bool, moving: bool,
                turns: float) -> None:
        """One sample of this segment: update and decide (may set :attr:`command`, :attr:`done`,
        :attr:`failure`)."""
        if self.done or self.failure:
            return
        self._t = t_s
        a = self.action
        if math.isfinite(estimate_mm):
            self._estimate = estimate_mm
        if self.state == MOVING or moving:
            return
        self._check_target_end(t_s)
        if self.done or self.failure:
            return
        if not resistance_measured:
            self.state = NO_RESISTANCE
            return
        if self.state == NO_RESISTANCE:
            self.state, self._settle_from = SETTLING, t_s
        if t_s - self._settle_from < a.settle_s or not math.isfinite(estimate_mm):
            return
        lo, hi = a.valid_length_mm
        margin = VALIDITY_MARGIN * (hi - lo)
        if not lo - margin <= estimate_mm <= hi + margin:
            self.failure = (f"length estimate {estimate_mm:.2f} mm left the model's validity range "
                            f"{lo:g}..{hi:g} mm (with {margin:.2g} mm margin); tracking stopped")
            return
        if self._before is not None:
            self._learn_slope(estimate_mm)
        error = self.target_mm - estimate_mm
        band = a.tolerance_mm * (RETRIGGER if self.state == ON_TARGET else 1.0)
        if abs(error) <= band:
            if self.state != ON_TARGET:
                self.state = ON_TARGET
                out = self.outcomes[-1]
                if self._reached_at is None:
                    self._reached_at = t_s
                    out.reached, out.time_to_reach_s = True, t_s - out.t_start_s
        else:
            self._correct(error, turns)

    def _check_target_end(self, t_s: float) -> None:
        a, out = self.action, self.outcomes[-1]
        if self._reached_at is not None and t_s - self._reached_at >= out.hold_s:
            self._next_target(t_s)
        elif self._reached_at is None and t_s - out.t_start_s >= a.timeout_s:
            if a.on_timeout == "fail":
                self.failure = (f"target {out.length_mm:g} mm not reached within {a.timeout_s:g} s "
                                f"(estimate {self._estimate:.2f} mm)")
                return
            self._next_target(t_s)

    def _next_target(self, t_s: float) -> None:
        self.outcomes[-1].final_estimate_mm = self._estimate
        self._index += 1
        self._reached_at = None
        if self._index >= len(self.action.targets):
            self.done = True
            return
        self.outcomes.append(TargetOutcome(*self.action.targets[self._index], t_s))
        if self.state == ON_TARGET:
            self.state = SETTLING  # judged again at once against the new target (settled already)

    def _learn_slope(self, estimate_mm: float) -> None:
        e0, n0 = self._before  # type: ignore[misc]
        self._before = None
        dn = self._turns_cmd - n0
        if abs(dn) < 0.5:
            return
        secant = (estimate_mm - e0) / dn
        g = self.slope_mm_per_turn
        if secant * g > 0 and abs(g) / 10 <= abs(secant) <= abs(g) * 10:
            self.slope_mm_per_turn = 0.5 * (g + secant)

    def _correct(self, error_mm: float, turns: float) -> None:
        a = self.action
        step = a.gain * error_mm / self.slope_mm_per_turn
        step = max(-a.max_step_turns, min(a.max_step_turns, step))
        base = self._turns_cmd if math.isfinite(self._turns_cmd) else turns
        lo, hi = self.twist_limits_turns
        target = base + step
        if hi is not None:
            target = min(target, hi)
        if lo is not None:
            target = max(target, lo)
        if abs(target - base) < MIN_STEP_TURNS:
            self.state = SATURATED if target != base + step else self.state
            return
        self._before = (self._estimate, base)
        self._turns_cmd = target
        self.command = ("move", target)
        self.state = MOVING
        self.outcomes[-1].corrections += 1

    def outcome(self) -> dict[str, Any]:
        """What the controller did, added to its segment's parameters in the run file."""
        return {"targets_reached": sum(o.reached for o in self.outcomes), "targets": [o.as_dict() for o in self.outcomes],
                "final_mm_per_turn": self.slope_mm_per_turn}
