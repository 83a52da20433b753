"""Trapezoidal (or triangular) velocity profile for one point-to-point move.

Contract: a move of ``distance`` (any unit, e.g. steps or turns; sign gives the
direction) starts and ends at rest, accelerates at ``accel`` (unit/s^2) up to at most
``rate`` (unit/s), cruises, and decelerates symmetrically. When the distance is too
short to reach ``rate`` the profile is triangular. ``position(t)`` is exact (closed
form), so a simulated device never has to integrate individual steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property


@dataclass(frozen=True)
class TrapezoidProfile:
    """Closed-form trapezoidal move. ``rate`` and ``accel`` must be > 0. The derived
    quantities (peak rate, ramp and cruise times) are computed once, on first use."""

    distance: float
    rate: float
    accel: float

    def __post_init__(self) -> None:
        if not (self.rate > 0 and self.accel > 0):
            raise ValueError(f"rate and accel must be > 0, got rate={self.rate}, accel={self.accel}")
        # Every derived quantity at once, by the properties' own functions, into the instance
        # (where cached_property keeps them): a simulated run makes thousands of profiles, and
        # cached_property's first reads (each under a lock) cost more than the arithmetic.
        d = self.__dict__
        for name in _DERIVED:
            d[name] = _DERIVED[name](self)

    @cached_property
    def _abs(self) -> float:
        return abs(self.distance)

    @cached_property
    def peak_rate(self) -> float:
        """Highest speed reached (unit/s): ``rate`` or less for a triangular move."""
        return min(self.rate, math.sqrt(self._abs * self.accel))

    @cached_property
    def accel_time(self) -> float:
        """Duration of the acceleration ramp (s); the deceleration ramp is as long."""
        return self.peak_rate / self.accel

    @cached_property
    def cruise_time(self) -> float:
        """Duration at constant speed (s); zero for a triangular move."""
        v = self.peak_rate
        ramp_distance = v * v / self.accel  # both ramps together
        return max(0.0, (self._abs - ramp_distance) / v) if v > 0 else 0.0

    @cached_property
    def duration(self) -> float:
        """Total move time (s)."""
        return 2.0 * self.accel_time + self.cruise_time

    def position(self, t: float) -> float:
        """Signed distance travelled after ``t`` seconds (clamped to [0, duration])."""
        if self._abs == 0.0 or t <= 0.0:
            return 0.0
        sign = 1.0 if self.distance > 0 else -1.0
        ta, tc, a, v = self.accel_time, self.cruise_time, self.accel, self.peak_rate
        if t < ta:
            s = 0.5 * a * t * t
        elif t < ta + tc:
            s = 0.5 * a * ta * ta + v * (t - ta)
        elif t < 2 * ta + tc:
            td = 2 * ta + tc - t
            s = self._abs - 0.5 * a * td * td
        else:
            s = self._abs
        return sign * min(s, self._abs)

    def velocity(self, t: float) -> float:
        """Signed speed (unit/s) at time ``t`` after the start."""
        if self._abs == 0.0 or t <= 0.0 or t >= self.duration:
            return 0.0
        sign = 1.0 if self.distance > 0 else -1.0
        ta, tc, a = self.accel_time, self.cruise_time, self.accel
        if t < ta:
            return sign * a * t
        if t < ta + tc:
            return sign * self.peak_rate
        return sign * a * (2 * ta + tc - t)


#: the cached properties in dependency order (each reads only those before it)
_DERIVED = {name: getattr(TrapezoidProfile, name).func
            for name in ("_abs", "peak_rate", "accel_time", "cruise_time", "duration")}
