"""Compiled plan segments: one primitive bench action each.

Units: twist in motor turns (absolute, 0 = untwisted start of the run), rates in
turns/s, accelerations in turns/s^2, durations/periods in s, voltages in V, masses in g.
Every action is final: relative moves have already been resolved to absolute targets.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, TypeAlias


@dataclass(frozen=True)
class Move:
    """Move the motor to the absolute ``target_turns`` with a trapezoidal profile."""

    target_turns: float
    rate_turns_per_s: float
    accel_turns_per_s2: float
    kind: ClassVar[str] = "move"

    def params(self) -> dict[str, Any]:
        return {
            "target_turns": self.target_turns,
            "rate_turns_per_s": self.rate_turns_per_s,
            "accel_turns_per_s2": self.accel_turns_per_s2,
        }


@dataclass(frozen=True)
class Hold:
    """Keep every output as it is for ``duration_s`` seconds (> 0) while sampling."""

    duration_s: float
    kind: ClassVar[str] = "hold"

    def params(self) -> dict[str, Any]:
        return {"duration_s": self.duration_s}


@dataclass(frozen=True)
class Settle:
    """Hold until the TSA has settled: end once, over the last ``window_s`` seconds, the
    fitted slopes satisfy |dR/dt| <= ``max_dR_dt_ohm_per_s`` and |dL/dt| <=
    ``max_dL_dt_mm_per_s`` (a threshold of None is not judged), but not before
    ``min_duration_s`` and never after ``max_duration_s`` (s)."""

    max_duration_s: float
    window_s: float
    min_duration_s: float
    max_dR_dt_ohm_per_s: float | None
    max_dL_dt_mm_per_s: float | None
    kind: ClassVar[str] = "settle"

    def params(self) -> dict[str, Any]:
        return {
            "max_duration_s": self.max_duration_s,
            "window_s": self.window_s,
            "min_duration_s": self.min_duration_s,
            "max_dR_dt_ohm_per_s": self.max_dR_dt_ohm_per_s,
            "max_dL_dt_mm_per_s": self.max_dL_dt_mm_per_s,
        }


@dataclass(frozen=True)
class SetHeater:
    """Set the Joule-heating voltage across the strings to ``voltage_V`` (>= 0)."""

    voltage_V: float
    kind: ClassVar[str] = "heater"

    def params(self) -> dict[str, Any]:
        return {"voltage_V": self.voltage_V}


@dataclass(frozen=True)
class HeaterLevel(SetHeater):
    """A heater change that belongs to a combined step (``step``, e.g. ``twist_heat``): the level
    set just before sub-move ``sub_move`` (1-based, of ``sub_moves``) to ``target_turns``, or,
    with ``sub_move`` 0 and ``target_turns`` None, the level once the last sub-move is done.
    Runs as any :class:`SetHeater` (kind ``heater``); its parameters say where it belongs."""

    step: str = "twist_heat"
    sub_move: int = 0
    sub_moves: int = 1
    target_turns: float | None = None

    def params(self) -> dict[str, Any]:
        return {"voltage_V": self.voltage_V, "step": self.step, "sub_move": self.sub_move,
                "sub_moves": self.sub_moves, "sub_move_target_turns": self.target_turns}


@dataclass(frozen=True)
class SetSampling:
    """Change the acquisition period to ``period_s`` seconds."""

    period_s: float
    kind: ClassVar[str] = "sampling"

    def params(self) -> dict[str, Any]:
        return {"period_s": self.period_s}


@dataclass(frozen=True)
class Prompt:
    """Pause for the operator; ``load_g`` is the new hanging mass if the prompt changes it."""

    text: str
    load_g: float | None = None
    kind: ClassVar[str] = "prompt"

    def params(self) -> dict[str, Any]:
        return {"text": self.text, "load_g": self.load_g}


@dataclass(frozen=True)
class TrackLength:
    """Closed-loop length tracking from resistance alone (:mod:`tsa_bench.control`): reach each
    ``(length_mm, hold_s)`` of ``targets`` in turn and keep it for ``hold_s`` seconds, judged by the
    self-sensing model at ``model_path``; moves of at most ``max_step_turns`` at
    ``rate_turns_per_s`` / ``accel_turns_per_s2``. ``valid_length_mm`` is the model's validity
    range, ``model_bench`` the bench its training runs were recorded on (None: not recorded)."""

    model_path: str
    targets: tuple[tuple[float, float], ...]
    tolerance_mm: float
    gain: float
    initial_mm_per_turn: float
    settle_s: float
    window_s: float
    max_step_turns: float
    rate_turns_per_s: float
    accel_turns_per_s2: float
    timeout_s: float
    on_timeout: str
    valid_length_mm: tuple[float, float]
    model_bench: str | None
    kind: ClassVar[str] = "track_length"

    def params(self) -> dict[str, Any]:
        return {
            "controller": "self-sensing step controller",
            "model_path": self.model_path,
            "targets_mm": [t for t, _ in self.targets],
            "hold_s": [h for _, h in self.targets],
            "tolerance_mm": self.tolerance_mm,
            "gain": self.gain,
            "initial_mm_per_turn": self.initial_mm_per_turn,
            "settle_s": self.settle_s,
            "window_s": self.window_s,
            "max_step_turns": self.max_step_turns,
            "rate_turns_per_s": self.rate_turns_per_s,
            "accel_turns_per_s2": self.accel_turns_per_s2,
            "timeout_s": self.timeout_s,
            "on_timeout": self.on_timeout,
            "valid_length_mm": list(self.valid_length_mm),
        }

    @property
    def longest_s(self) -> float:
        """Upper bound of its duration (s): every target's timeout and hold."""
        return sum(self.timeout_s + h for _, h in self.targets)


Action: TypeAlias = Move | Hold | Settle | SetHeater | HeaterLevel | SetSampling | Prompt | TrackLength

#: All segment kinds, in a stable display order.
KINDS: tuple[str, ...] = ("move", "hold", "settle", "heater", "sampling", "prompt", "track_length")


@dataclass(frozen=True)
class Segment:
    """One executable step of a compiled plan.

    ``index`` counts from 0 in execution order; ``cycle`` is the 0-based iteration of
    the innermost enclosing ``repeat`` (``None`` outside repeats); ``source`` is
    ``"file.yaml:LINE"`` of the YAML step the segment came from.
    """

    index: int
    action: Action
    cycle: int | None
    source: str

    @property
    def kind(self) -> str:
        """``"move" | "hold" | "settle" | "heater" | "sampling" | "prompt"``."""
        return self.action.kind

    def params(self) -> dict[str, Any]:
        """JSON-serialisable action parameters with unit-suffixed keys."""
        return self.action.params()
