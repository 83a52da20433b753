"""Mechanical effects: load dependence, twist hysteresis, string compliance, radius
growth (geometry stage) and length creep (length stage).

Units: twist in turns, length in mm, force in N, load in g, time in s.

Contract: see :mod:`tsa_bench.sim.effects.base`. The geometry stage sets the twist the
kinematics sees (``turns_eff``), the string length ``L`` (``string_length_mm``) and
whether the radius grows; the plant then computes the TSA length ``X`` with
:func:`tsa_length_mm`; the length stage corrects ``length_mm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_effect
from tsa_bench.sim.kinematics import contracted_length_mm

_SQRT3 = math.sqrt(3.0)
_TWO_PI = 2.0 * math.pi


def tsa_length_mm(string_length_mm: float, turns: float, radius_mm: float, untwisted_length_mm: float,
                  radius_growth: bool) -> float:
    """TSA length X for string length L at ``turns`` (thesis eqs. 4.4-4.5), clamped at L/sqrt(3).

    With radius growth, ``r = r0 sqrt(L0 / X)`` (the closed-form cubic of
    :mod:`tsa_bench.sim.kinematics`); without it, ``X = sqrt(L^2 - (theta r0)^2)``.
    """
    theta_r = _TWO_PI * turns * radius_mm
    if radius_growth:
        return contracted_length_mm(string_length_mm, theta_r * theta_r * untwisted_length_mm)
    x2 = string_length_mm * string_length_mm - theta_r * theta_r
    floor = string_length_mm / _SQRT3
    return max(math.sqrt(x2), floor) if x2 > 0.0 else floor


@register_effect
class LoadDependence(Effect):
    """Load scales the hysteresis terms; stiffness falls as contraction rises.

    ``hysteresis_scale = (m / m_ref)^hysteresis_exponent`` multiplies the twist play and
    the resistance hysteresis (not creep or transient decay); ``K_eff = K (1 - s c)``
    (floored at 0.2 K; multiplies any factor an earlier geometry effect set) with ``c = (L - X) / X`` the contraction of the previous sample
    and ``s`` the softening. Source: thesis section 2.3, Fig. 2.4(d) (stiffness
    decreased as contraction increased; mild hysteresis), section 2.4.2 (hysteresis
    under all loads); Palli et al. (stiffness vs rotations).
    """

    name = "load_dependence"
    stage = "geometry"
    source = "thesis 2.3 Fig. 2.4(d); 2.4.2 Fig. 2.5(b)-(c)"

    @dataclass(frozen=True)
    class Params:
        reference_load_g: float = param(450.0, "g", "load at which hysteresis_scale = 1", minimum=1e-9)
        hysteresis_exponent: float = param(1.0, "1", "hysteresis_scale = (load / reference_load)^exponent",
                                           minimum=0.0)
        stiffness_softening: float = param(0.3, "1", "s in K_eff = K (1 - s * contraction)", minimum=0.0)

    def apply(self, state: PlantState) -> None:
        p = self.params
        ratio = state.load_g / p.reference_load_g
        state.hysteresis_scale = ratio ** p.hysteresis_exponent if ratio > 0.0 else 0.0
        state.stiffness_factor *= max(0.2, 1.0 - p.stiffness_softening * state.contraction)


@register_effect
class TwistHysteresis(Effect):
    """Play (backlash/friction) operator on twist: length lags the twist direction.

    ``turns_eff = max(v - r, min(v + r, turns_eff_prev))`` with ``v`` the actual twist and
    ``r = play_turns * hysteresis_scale`` (thesis eq. 3.10 play operator applied to
    twist): while twisting the strings contract as if ``r`` turns less twisted, while
    untwisting as if ``r`` turns more. Source: thesis 2.4.2 (hysteresis between motor
    rotations and contraction, friction between strings and plies), Fig. 2.5(b)-(c).
    """

    name = "twist_hysteresis"
    stage = "geometry"
    source = "thesis 2.4.2 Fig. 2.5; play operator eq. 3.10"

    @dataclass(frozen=True)
    class Params:
        play_turns: float = param(0.3, "turn", "half width r of the twist play at the reference load", minimum=0.0)

    def reset(self) -> None:
        self._w: float | None = None

    def apply(self, state: PlantState) -> None:
        v = state.turns
        r = self.params.play_turns * state.hysteresis_scale
        w = v if self._w is None else self._w
        lo, hi = v - r, v + r
        w = lo if w < lo else hi if w > hi else w
        self._w = w
        state.turns_eff = w


@register_effect
class StringCompliance(Effect):
    """Compliant strings stretch under the hanging load: ``L = L0 (1 + F / K)``.

    ``F = m g``; ``K`` the normalised stiffness (times ``stiffness_factor`` from
    load_dependence). Off: inextensible strings, ``L = L0``. Source: thesis eq. 2.1,
    section 2.3: K = 24.61 N (3-ply SCP), 31.88 N (4-ply SCP); UHMWPE ~3000 N.
    """

    name = "string_compliance"
    stage = "geometry"
    source = "thesis eq. 2.1, section 2.3"

    @dataclass(frozen=True)
    class Params:
        stiffness_N: float = param(31.88, "N", "normalised stiffness K (3-ply 24.61, 4-ply 31.88, UHMWPE ~3000)",
                                   minimum=1e-9)

    def apply(self, state: PlantState) -> None:
        k = self.params.stiffness_N * state.stiffness_factor
        state.string_length_mm *= 1.0 + state.load_N / k


@register_effect
class RadiusGrowth(Effect):
    """The TSA radius grows as it contracts: ``r = r0 sqrt(L0 / X)``.

    Gives the cubic ``X^3 - L^2 X + theta^2 r0^2 L0 = 0`` (closed form in
    :mod:`tsa_bench.sim.kinematics`). Off: constant radius, ``X = sqrt(L^2 - (theta
    r0)^2)``. Both clamp at the fully twisted length ``L / sqrt(3)``. Source: thesis
    eqs. 4.4-4.5.
    """

    name = "radius_growth"
    stage = "geometry"
    source = "thesis eqs. 4.4-4.5"

    def apply(self, state: PlantState) -> None:
        state.radius_growth = True


@register_effect
class LengthCreep(Effect):
    """Viscoelastic length creep under load, fading after ~10 min: ``X *= 1 + x``.

    ``x(k) = e^{-T/tau} x(k-1) + (1 - e^{-T/tau}) * strain_per_N * F`` (the creep
    operator of thesis eq. 3.13 driven by the load). A new load creeps again. Source:
    thesis 2.5.2 (mild length creep within the first ten minutes, then negligible),
    2.3 (60 s per load to reach steady state).
    """

    name = "length_creep"
    stage = "length"
    source = "thesis 2.5.2 Fig. 2.8(d); creep operator eq. 3.13"

    @dataclass(frozen=True)
    class Params:
        strain_per_N: float = param(0.001, "1/N", "final creep strain per newton of load", minimum=0.0)
        time_constant_s: float = param(180.0, "s", "creep time constant (~95 % after 3 tau = 9 min)",
                                       minimum=1e-9)

    def reset(self) -> None:
        self._x = 0.0

    def apply(self, state: PlantState) -> None:
        p = self.params
        dt = state.dt_s
        if dt > 0.0:
            target = p.strain_per_N * state.load_N
            self._x += (target - self._x) * (1.0 - math.exp(-dt / p.time_constant_s))
        state.length_mm *= 1.0 + self._x
