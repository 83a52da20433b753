"""Safety limits for a bench or a protocol.

Units: twist in motor turns (signed, 0 = untwisted start), heater voltage in volts,
rate in turns/s, acceleration in turns/s^2. ``None`` means unlimited.

Contract: a protocol may only *tighten* the bench limits (lower a maximum, raise the
minimum twist); :meth:`Limits.tightened` refuses anything that would loosen them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

#: Limit fields that are upper bounds; ``min_twist_turns`` is the only lower bound.
UPPER_BOUND_FIELDS: tuple[str, ...] = (
    "max_twist_turns",
    "max_heater_voltage_V",
    "max_rate_turns_per_s",
    "max_accel_turns_per_s2",
)
LOWER_BOUND_FIELDS: tuple[str, ...] = ("min_twist_turns",)


@dataclass(frozen=True)
class Limits:
    """Bench or effective protocol limits; every field ``None`` = unlimited.

    Raises ``ValueError`` on construction for non-finite or non-numeric values, a
    non-positive rate/accel limit, a negative heater limit, or min twist > max twist.
    """

    max_twist_turns: float | None = None
    min_twist_turns: float | None = None
    max_heater_voltage_V: float | None = None
    max_rate_turns_per_s: float | None = None
    max_accel_turns_per_s2: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"{f.name} must be a finite number or None, got {value!r}")
            object.__setattr__(self, f.name, float(value))
        for name in ("max_rate_turns_per_s", "max_accel_turns_per_s2"):
            value = getattr(self, name)
            if value is not None and value <= 0:
                raise ValueError(f"{name} must be > 0, got {value}")
        if self.max_heater_voltage_V is not None and self.max_heater_voltage_V < 0:
            raise ValueError(f"max_heater_voltage_V must be >= 0, got {self.max_heater_voltage_V}")
        lo, hi = self.min_twist_turns, self.max_twist_turns
        if lo is not None and hi is not None and lo > hi:
            raise ValueError(f"min_twist_turns ({lo}) is above max_twist_turns ({hi})")

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """Names of all limit fields, in declaration order."""
        return tuple(f.name for f in fields(cls))

    def as_dict(self) -> dict[str, float | None]:
        """JSON-serialisable ``{field: value}`` mapping."""
        return {name: getattr(self, name) for name in self.field_names()}

    def tightened(self, other: Limits | Mapping[str, float | None]) -> Limits:
        """Return these limits narrowed by ``other`` (a Limits or any subset of fields).

        ``None`` entries in ``other`` leave the field unchanged. Raises ``ValueError``
        naming every field ``other`` would loosen, and for unknown field names.
        """
        proposed = other.as_dict() if isinstance(other, Limits) else dict(other)
        unknown = sorted(set(proposed) - set(self.field_names()))
        if unknown:
            raise ValueError(f"unknown limit field(s) {unknown}; allowed: {list(self.field_names())}")
        problems = [
            msg
            for name, value in proposed.items()
            if value is not None and (msg := loosening_problem(name, getattr(self, name), value))
        ]
        if problems:
            raise ValueError("protocol limits may only tighten the bench limits: " + "; ".join(problems))
        merged = self.as_dict()
        merged.update({k: v for k, v in proposed.items() if v is not None})
        return Limits(**merged)


def loosening_problem(name: str, bench_value: float | None, proposed: float) -> str | None:
    """Explain why ``proposed`` would loosen the bench limit ``name``, or ``None`` if it doesn't."""
    if bench_value is None:
        return None
    if name in LOWER_BOUND_FIELDS and proposed < bench_value:
        return f"{name} {proposed:g} is below the bench limit {bench_value:g}"
    if name in UPPER_BOUND_FIELDS and proposed > bench_value:
        return f"{name} {proposed:g} exceeds the bench limit {bench_value:g}"
    return None
