"""Resistance effects: length/contact, rate-dependent hysteresis, transient decay after
each motor stop, wear creep, temperature coefficient.

Units: resistance in ohm, length in mm, time in s, temperature in degC, twist in turns.

The thesis models the resistance as ``y = y_t + y_h + y_c`` (eq. 3.8): transient decay,
hysteresis and creep; here each is its own effect, added to the quasi-static
``R0 + dR/dX (X - L0)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_effect


@register_effect
class ResistanceLength(Effect):
    """``R += dR/dX (X - L0) - c |turns|``: longer -> higher R; strings pressed together -> lower.

    Source: thesis 2.5.1 (resistance rises with length and load; in Scheme 2 contact
    between the twisted strings raises conductivity), 2.5.2.
    """

    name = "resistance_length"
    stage = "resistance"
    source = "thesis 2.5.1 Fig. 2.7(c)-(f), 2.5.2"

    @dataclass(frozen=True)
    class Params:
        ohm_per_mm: float = param(0.015, "ohm/mm", "dR/dX, resistance rise per mm of TSA length")
        contact_ohm_per_turn: float = param(0.001, "ohm/turn", "resistance drop per turn of twist (contact)")

    def apply(self, state: PlantState) -> None:
        p = self.params
        state.resistance_ohm += (p.ohm_per_mm * (state.length_mm - state.untwisted_length_mm)
                                 - p.contact_ohm_per_turn * abs(state.turns_eff))


@register_effect
class ResistanceHysteresis(Effect):
    """Rate-dependent Prandtl-Ishlinskii hysteresis of R vs length.

    ``y_h = g * hysteresis_scale * mean_n (F_rn[X] - X)`` with play operators ``F_r``
    (eq. 3.10) of thresholds ``r_n = (n/N) alpha ln(beta + lambda |v|^eps)`` (eq. 3.12);
    ``v`` is the length step divided by the step duration (time between motor stops), so
    shorter steps widen the loop (peak-to-peak depends on step duration). Source: thesis
    3.2.2, eqs. 3.10-3.12; Fig. 2.8(a),(c).
    """

    name = "resistance_hysteresis"
    stage = "resistance"
    source = "thesis 3.2.2 eqs. 3.10-3.12, Fig. 2.8(a),(c)"

    @dataclass(frozen=True)
    class Params:
        ohm_per_mm: float = param(0.015, "ohm/mm", "gain g from the play operators' lag to resistance")
        alpha_mm: float = param(1.0, "mm", "alpha: largest threshold scale", minimum=0.0)
        beta: float = param(1.5, "1", "beta (> 1 keeps thresholds positive at rest)", minimum=1.0)
        rate_weight: float = param(1.0, "(s/mm)^eps", "lambda: weight of the rate", minimum=0.0)
        epsilon: float = param(1.0, "1", "eps: exponent of the rate", minimum=0.0)
        operators: float = param(8, "1", "number N of play operators", minimum=1, maximum=1000)

    def reset(self) -> None:
        n = int(self.params.operators)
        self._unit = [(i + 1) / n for i in range(n)]
        self._w: list[float] | None = None
        self._rate = 0.0
        self._was_moving = False
        self._stop_x: float | None = None
        self._stop_t = 0.0

    def apply(self, state: PlantState) -> None:
        p = self.params
        x = state.length_mm
        moving = state.motor_moving
        if self._was_moving and not moving:
            if self._stop_x is not None and state.t_s > self._stop_t:
                self._rate = abs(x - self._stop_x) / (state.t_s - self._stop_t)
            self._stop_x, self._stop_t = x, state.t_s
        elif self._stop_x is None:
            self._stop_x, self._stop_t = x, state.t_s
        self._was_moving = moving
        scale = p.alpha_mm * math.log(p.beta + p.rate_weight * self._rate ** p.epsilon)
        w = self._w
        if w is None:
            w = self._w = [x] * len(self._unit)
        total = 0.0
        for i, u in enumerate(self._unit):
            r = u * scale
            wi = w[i]
            if wi < x - r:
                wi = x - r
            elif wi > x + r:
                wi = x + r
            w[i] = wi
            total += wi - x
        state.resistance_ohm += p.ohm_per_mm * state.hysteresis_scale * total / len(w)


@register_effect
class ResistanceTransientDecay(Effect):
    """After each motor stop R spikes, then decays: ``b1 ln^2(t-t0+e) + b2 ln(t-t0+e)``.

    Shifted so it is zero from ``settle_s`` on (the thesis: steady state after about two
    minutes, length constant meanwhile): ``y_t = f(t - t0) - f(settle_s)`` for
    ``t - t0 < settle_s``, else 0; nothing while the motor turns. Source: thesis eq. 3.9,
    Table 3.3 (b1 = -1.71e-3 ohm, b2 = -2.68e-2 ohm, e = 1e-5 s), 2.5.2 Fig. 2.8(b).
    """

    name = "resistance_transient_decay"
    stage = "resistance"
    source = "thesis eq. 3.9, Table 3.3, Fig. 2.8(b)"

    @dataclass(frozen=True)
    class Params:
        b1_ohm: float = param(-1.71e-3, "ohm", "b1 (coefficient of ln^2)")
        b2_ohm: float = param(-2.68e-2, "ohm", "b2 (coefficient of ln)")
        epsilon_s: float = param(1e-5, "s", "offset avoiding the singularity at t = t0", minimum=1e-12)
        settle_s: float = param(120.0, "s", "time after the stop at which the decay has settled", minimum=1e-9)

    def reset(self) -> None:
        p = self.params
        self._f_settle = self._f(p.settle_s)

    def _f(self, dt: float) -> float:
        p = self.params
        lg = math.log(dt + p.epsilon_s)
        return p.b1_ohm * lg * lg + p.b2_ohm * lg

    def apply(self, state: PlantState) -> None:
        since = state.t_since_stop_s
        if not state.motor_moving and since < self.params.settle_s:
            state.resistance_ohm += self._f(since) - self._f_settle


@register_effect
class ResistanceCreep(Effect):
    """R drifts with wear: ``R += k * cumulative |twist travel|`` (silver coating wears off).

    Source: thesis 2.5.2 Fig. 2.8(d): resistance creep over 596 cycles (15-25 turns,
    550 g, > 2.5 h), attributed to friction wearing the silver coating.
    """

    name = "resistance_creep"
    stage = "resistance"
    source = "thesis 2.5.2 Fig. 2.8(d)"

    @dataclass(frozen=True)
    class Params:
        ohm_per_turn: float = param(1e-5, "ohm/turn", "resistance rise per turn of cumulative twist travel")

    def apply(self, state: PlantState) -> None:
        state.resistance_ohm += self.params.ohm_per_turn * state.travel_turns


@register_effect
class ResistanceTemperature(Effect):
    """``R *= 1 + alpha (T - T_amb)``: temperature coefficient of the silver-coated strings.

    Source: assumption (the thesis notes strings may warm slightly while cycling, 2.5.2,
    and does not measure R while heating); metallic coating, reduced by the composite.
    """

    name = "resistance_temperature"
    stage = "resistance"
    source = "assumption; thesis 2.5.2 (temperature not measured)"

    @dataclass(frozen=True)
    class Params:
        alpha_per_K: float = param(5e-4, "1/K", "temperature coefficient of resistance")

    def apply(self, state: PlantState) -> None:
        state.resistance_ohm *= 1.0 + self.params.alpha_per_K * (state.temperature_C - state.ambient_C)
