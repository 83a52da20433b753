"""Quasi-static kinematics of a compliant twisted string actuator (TSA).

Units: lengths and radii in mm, twist in motor turns, load in grams (hanging mass),
forces in N.

Contract: the strings first stretch under the hanging load with the normalised
stiffness ``K`` of thesis eq. 2.1, ``L = L0 (1 + F / K)`` with ``F = m g``. Twisting
then shortens them following the TSA model of eq. 4.4 with the radius growth of
eq. 4.5, ``X = sqrt(L^2 - (theta r)^2)``, ``r = r0 sqrt(L0 / X)``, ``theta = 2 pi
turns``. Substituting ``r`` gives the cubic ``X^3 - L^2 X + theta^2 r0^2 L0 = 0``,
whose largest root is the physical length; it is evaluated in closed form
(trigonometric solution), so no iteration and no NaN. A root exists only while
``X >= L / sqrt(3)`` (the fully twisted length); beyond that twist the length stays
clamped there. Twist direction does not matter (the model is even in ``turns``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

GRAVITY_M_PER_S2 = 9.80665
#: N per gram of hanging mass.
NEWTON_PER_GRAM = GRAVITY_M_PER_S2 * 1e-3
_SQRT3 = math.sqrt(3.0)
_TWO_PI = 2.0 * math.pi


def stretched_length_mm(untwisted_length_mm: float, stiffness_N: float, load_g: float) -> float:
    """Untwisted length under a hanging load: ``L0 (1 + m g / K)`` (mm)."""
    return untwisted_length_mm * (1.0 + load_g * NEWTON_PER_GRAM / stiffness_N)


def contracted_length_mm(stretched_mm: float, twist_coefficient_mm3: float) -> float:
    """Largest root of ``X^3 - L^2 X + c = 0`` for ``L = stretched_mm``, ``c >= 0`` (mm).

    ``c = theta^2 r0^2 L0``. Returns ``L`` for ``c = 0`` and clamps to ``L / sqrt(3)``
    when ``c`` exceeds ``2 L^3 / (3 sqrt(3))`` (no real root above ``L / sqrt(3)``).
    """
    length = stretched_mm
    if twist_coefficient_mm3 <= 0.0 or length <= 0.0:
        return length
    arg = -1.5 * _SQRT3 * twist_coefficient_mm3 / (length * length * length)
    if arg <= -1.0:
        return length / _SQRT3
    return (2.0 / _SQRT3) * length * math.cos(math.acos(arg) / 3.0)


def full_twist_turns(stretched_mm: float, untwisted_length_mm: float, radius_mm: float) -> float:
    """Turns at which the strings become fully twisted (length ``L / sqrt(3)``)."""
    if radius_mm <= 0.0:
        return math.inf
    c_max = 2.0 * stretched_mm ** 3 / (3.0 * _SQRT3)
    return math.sqrt(c_max / (radius_mm * radius_mm * untwisted_length_mm)) / _TWO_PI


@dataclass(frozen=True)
class TsaGeometry:
    """One TSA: ``untwisted_length_mm`` (L0, unloaded), ``radius_mm`` (r0), ``stiffness_N`` (K)."""

    untwisted_length_mm: float
    radius_mm: float
    stiffness_N: float

    def __post_init__(self) -> None:
        if not self.untwisted_length_mm > 0:
            raise ValueError(f"untwisted_length_mm must be > 0, got {self.untwisted_length_mm}")
        if not self.radius_mm >= 0:
            raise ValueError(f"radius_mm must be >= 0, got {self.radius_mm}")
        if not self.stiffness_N > 0:
            raise ValueError(f"stiffness_N must be > 0, got {self.stiffness_N}")

    @property
    def twist_coefficient_mm3_per_turn2(self) -> float:
        """``c / turns^2 = (2 pi)^2 r0^2 L0`` (mm^3 per turn^2)."""
        return _TWO_PI * _TWO_PI * self.radius_mm * self.radius_mm * self.untwisted_length_mm

    def stretched_length_mm(self, load_g: float) -> float:
        return stretched_length_mm(self.untwisted_length_mm, self.stiffness_N, load_g)

    def length_mm(self, turns: float, load_g: float) -> float:
        """Quasi-static TSA length at ``turns`` of twist under ``load_g`` (mm)."""
        c = self.twist_coefficient_mm3_per_turn2 * turns * turns
        return contracted_length_mm(self.stretched_length_mm(load_g), c)

    def full_twist_turns(self, load_g: float) -> float:
        """Twist (turns) beyond which the length stays at its fully twisted value."""
        return full_twist_turns(self.stretched_length_mm(load_g), self.untwisted_length_mm, self.radius_mm)
