"""The simulated device's segment executor: the command FIFO and what runs now.

Units: virtual time in s (float), positions in microsteps, rates in step/s and
step/s^2, heater in mV, sampling period in us.

Contract: accepted queued commands (MOVE_TO, MOVE_BY, DWELL, SET_HEATER, SET_SAMPLING)
wait in a FIFO of ``capacity`` slots; the one executing is not counted. Whenever the
executor is idle the next command starts at once, with EVENT SEGMENT_STARTED; a move
runs a :class:`TrapezoidProfile` in closed form (the step position is the rounded
profile position; steps are never iterated), a DWELL holds for its duration, and
SET_HEATER / SET_SAMPLING take effect immediately (SEGMENT_DONE at the same instant).
Each end emits SEGMENT_DONE, and QUEUE_EMPTY when nothing is left. ``stop`` is the
controlled stop of STOP and the watchdog: FIFO cleared, heater off, the running move
(no SEGMENT_DONE) decelerates at ``a_max`` from its present speed, or finishes as
planned when that comes sooner (as the firmware's StepPlanner.stop); nothing new starts
before the motor is at rest (``stopping``), and ``stop`` returns where that is.
``halt`` stops the motor at once where it is (no deceleration);
``clear_queue`` drops waiting commands but lets the executing one finish. The heater
runs at ``heater_mV``, the voltage the PWM applies (``heater_applied``, the firmware's
duty rounding) for the last SET_HEATER.
``projected_steps`` is the position after everything accepted has run, for validating
MOVE_BY. Events go to the ``emit_event(t_s, kind, segment, value)`` callback, where
``value`` is the step position at that instant. Validation is the caller's job.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import NamedTuple, Union

from tsa_bench.motion.trapezoid import TrapezoidProfile
from tsa_bench.protocol import catalogue as msg
from tsa_bench.sim.heater import applied_mV

QueuedCommand = Union[msg.MoveTo, msg.MoveBy, msg.Dwell, msg.SetHeater, msg.SetSampling]
#: Segment index reported before any segment ran.
NO_SEGMENT = 0xFFFF
EmitEvent = Callable[[float, int, int, int], None]

_STARTED = int(msg.EventKind.SEGMENT_STARTED)
_DONE = int(msg.EventKind.SEGMENT_DONE)
_EMPTY = int(msg.EventKind.QUEUE_EMPTY)


class _Move(NamedTuple):
    start_s: float
    start_steps: int
    target_steps: int
    profile: "TrapezoidProfile | _Deceleration"


class _Deceleration(NamedTuple):
    """Constant deceleration from ``v0`` (unit/s, signed) to rest at ``accel`` (unit/s^2)."""

    v0: float
    accel: float

    @property
    def duration(self) -> float:
        return abs(self.v0) / self.accel

    def position(self, t: float) -> float:
        t = min(max(t, 0.0), self.duration)
        sign = 1.0 if self.v0 > 0 else -1.0
        return sign * (abs(self.v0) * t - 0.5 * self.accel * t * t)


class SegmentExecutor:
    """FIFO + current segment + heater + sampling period (see module docstring)."""

    def __init__(self, capacity: int, emit_event: EmitEvent,
                 on_sampling: Callable[[int, float], None]) -> None:
        self.capacity = capacity
        self._emit = emit_event
        self._on_sampling = on_sampling
        self._queue: deque[QueuedCommand] = deque()
        self.position_steps = 0        # at rest, or where the running move started
        self.projected_steps = 0
        self.heater_mV = 0
        self.heater_switch_ons = 0       # SET_HEATER > 0 executed so far (the sense current goes off)
        self.segment = NO_SEGMENT
        self.end_s = math.inf          # when the executing segment (or a stop) ends
        self._move: _Move | None = None
        self._executing = False
        self.stopping = False          # a controlled stop is still decelerating

    # -- state ------------------------------------------------------------
    @property
    def queued(self) -> int:
        return len(self._queue)

    @property
    def queue_free(self) -> int:
        return self.capacity - len(self._queue)

    @property
    def executing(self) -> bool:
        """A move or dwell is in progress."""
        return self._executing

    def position_at(self, t_s: float) -> tuple[int, bool]:
        """``(step_position, motor_moving)`` at ``t_s`` (not before the last event)."""
        move = self._move
        if move is None:
            return self.position_steps, False
        if t_s >= self.end_s:
            return move.target_steps, False
        return move.start_steps + round(move.profile.position(t_s - move.start_s)), True

    def velocity_at(self, t_s: float) -> float:
        """Signed speed (step/s) of the motor at ``t_s``."""
        move = self._move
        if move is None or t_s >= self.end_s:
            return 0.0
        profile = move.profile
        if isinstance(profile, _Deceleration):
            return math.copysign(max(0.0, abs(profile.v0) - profile.accel * (t_s - move.start_s)), profile.v0)
        return profile.velocity(t_s - move.start_s)

    # -- commands ---------------------------------------------------------
    def push(self, command: QueuedCommand, now_s: float) -> None:
        """Queue an accepted command; start it now if idle. The caller checked capacity."""
        self._queue.append(command)
        kind = type(command)
        if kind is msg.MoveTo:
            self.projected_steps = command.target_steps
        elif kind is msg.MoveBy:
            self.projected_steps += command.delta_steps
        if not self._executing and not self.stopping:
            self._start_next(now_s)

    def finish(self) -> float:
        """End the executing segment (or the stop) at ``end_s`` and start what follows;
        return that time."""
        t = self.end_s
        if self._move is not None:
            self.position_steps = self._move.target_steps
            self._move = None
        self.end_s = math.inf
        if self.stopping:
            self.stopping = False        # at rest: no SEGMENT_DONE for the stopped move
            if self._queue:
                self._start_next(t)
            return t
        self._executing = False
        self._emit(t, _DONE, self.segment, self.position_steps)
        self._start_next(t)
        return t

    def stop(self, now_s: float, a_max: float) -> int:
        """Controlled stop (see the module contract); return the rest position."""
        self._queue.clear()
        self.heater_mV = 0
        move = self._move
        if move is not None and now_s < self.end_s:
            here, _ = self.position_at(now_s)
            v = self.velocity_at(now_s)
            left = abs(move.target_steps - here)
            d = int(v * v / (2.0 * a_max))
            if self._executing and d < left:
                decel = _Deceleration(v, a_max)
                target = here + (d if v > 0 else -d)
                self._move = _Move(now_s, here, target, decel)
                self.end_s = now_s + decel.duration
            self.stopping = True
        elif move is not None:
            self.position_steps = move.target_steps
            self._move = None
            self.end_s = math.inf
        self._executing = False
        rest = self._move.target_steps if self._move is not None else self.position_steps
        self.projected_steps = rest
        return rest

    def halt(self, now_s: float) -> int:
        """Stop the motor where it is, clear the FIFO, heater off; return the position."""
        self.position_steps, _ = self.position_at(now_s)
        self._move = None
        self._executing = False
        self.stopping = False
        self.end_s = math.inf
        self._queue.clear()
        self.heater_mV = 0
        self.projected_steps = self.position_steps
        return self.position_steps

    def set_position(self, steps: int) -> None:
        """SET_POSITION: the motor is at rest and now at ``steps``."""
        self.position_steps = self.projected_steps = steps

    def clear_queue(self) -> None:
        """Drop waiting commands; the executing segment finishes."""
        self._queue.clear()
        self.projected_steps = self._move.target_steps if self._move is not None else self.position_steps

    @property
    def move_waiting(self) -> bool:
        """A move executes or waits in the queue (SET_POSITION is refused then)."""
        moving = self._executing and self._move is not None
        return moving or any(type(c) in (msg.MoveTo, msg.MoveBy) for c in self._queue)

    # -- execution --------------------------------------------------------
    def _start_next(self, t_s: float) -> None:
        while self._queue:
            command = self._queue.popleft()
            self.segment = command.segment
            self._emit(t_s, _STARTED, self.segment, self.position_steps)
            if self._begin(command, t_s):
                return
            self._emit(t_s, _DONE, self.segment, self.position_steps)
        self._emit(t_s, _EMPTY, self.segment, self.position_steps)

    def _begin(self, command: QueuedCommand, t_s: float) -> bool:
        """Apply ``command`` at ``t_s``; True if it lasts (ends later at ``end_s``)."""
        kind = type(command)
        if kind is msg.MoveTo or kind is msg.MoveBy:
            start = self.position_steps
            target = command.target_steps if kind is msg.MoveTo else start + command.delta_steps
            if target == start:
                return False
            profile = TrapezoidProfile(target - start, command.rate_steps_per_s, command.accel_steps_per_s2)
            self._move = _Move(t_s, start, target, profile)
            self.end_s = t_s + profile.duration
        elif kind is msg.Dwell:
            if command.duration_us == 0:
                return False
            self.end_s = t_s + command.duration_us * 1e-6
        elif kind is msg.SetHeater:
            applied = applied_mV(command.voltage_mV)
            if applied > 0:
                self.heater_switch_ons += 1
            self.heater_mV = applied
            return False
        elif kind is msg.SetSampling:
            self._on_sampling(command.period_us, t_s)
            return False
        else:  # pragma: no cover - the device only pushes queued commands
            raise TypeError(f"not a queued command: {command!r}")
        self._executing = True
        return True
