"""Alternative forms of resistance effects: transient decay as a stretched exponential or
a sum of two exponentials (the library's ``resistance_transient_decay`` is the thesis's
ln^2 law), and resistance creep with time (the library's ``resistance_creep`` grows with
twist travel).

Units: resistance in ohm, time in s.

Contract: see :mod:`tsa_bench.sim.effects.base` (``register_form``); off unless a plant
config names them. The transients add nothing while the motor turns and start at each
stop (``state.t_since_stop_s``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_form


@register_form
class ResistanceTransientStretched(Effect):
    """After each stop R is up by ``A exp(-((t - t0) / tau)^beta)`` (stretched exponential).

    Source: thesis 2.5.2 Fig. 2.8(b) (spike at the stop, decay over minutes); relaxation
    of disordered contacts is commonly stretched-exponential (Kohlrausch); the thesis
    tried a decaying exponential (3.2.2) before choosing eq. 3.9.
    """

    name = "resistance_transient_stretched"
    stage = "resistance"
    form_of = "resistance_transient_decay"
    form = "stretched exponential"
    source = "thesis 2.5.2 Fig. 2.8(b), 3.2.2; Kohlrausch relaxation"

    @dataclass(frozen=True)
    class Params:
        amp_ohm: float = param(0.02, "ohm", "A, resistance step at the stop")
        time_constant_s: float = param(10.0, "s", "tau", minimum=1e-9)
        beta: float = param(0.6, "1", "stretching exponent (1: plain exponential)", minimum=1e-3)

    def apply(self, state: PlantState) -> None:
        since = state.t_since_stop_s
        if not state.motor_moving and since < math.inf:
            p = self.params
            state.resistance_ohm += p.amp_ohm * math.exp(-((since / p.time_constant_s) ** p.beta))


@register_form
class ResistanceTransientTwoExp(Effect):
    """After each stop R is up by ``a1 exp(-(t - t0) / tau1) + a2 exp(-(t - t0) / tau2)``.

    Source: thesis 2.5.2 Fig. 2.8(b) (fast, then slow decay after each stop), 3.2.2.
    """

    name = "resistance_transient_two_exp"
    stage = "resistance"
    form_of = "resistance_transient_decay"
    form = "sum of exponentials"
    source = "thesis 2.5.2 Fig. 2.8(b), 3.2.2"

    @dataclass(frozen=True)
    class Params:
        a1_ohm: float = param(0.012, "ohm", "amplitude of the fast decay")
        tau1_s: float = param(2.0, "s", "fast time constant", minimum=1e-9)
        a2_ohm: float = param(0.008, "ohm", "amplitude of the slow decay")
        tau2_s: float = param(40.0, "s", "slow time constant", minimum=1e-9)

    def apply(self, state: PlantState) -> None:
        since = state.t_since_stop_s
        if not state.motor_moving and since < math.inf:
            p = self.params
            state.resistance_ohm += p.a1_ohm * math.exp(-since / p.tau1_s) + p.a2_ohm * math.exp(-since / p.tau2_s)


@register_form
class ResistanceCreepTime(Effect):
    """R creeps with time under tension: ``R += rate tau (1 - exp(-t / tau))``.

    ``t`` counts from the plant's first sample; ``rate`` is the initial creep rate and
    ``tau`` how slowly it saturates (large: a steady drift). Source: thesis 2.5.2
    Fig. 2.8(d) (resistance creep over > 2.5 h); creep operator, eq. 3.13.
    """

    name = "resistance_creep_time"
    stage = "resistance"
    form_of = "resistance_creep"
    form = "with time"
    source = "thesis 2.5.2 Fig. 2.8(d); creep operator eq. 3.13"

    @dataclass(frozen=True)
    class Params:
        ohm_per_hour: float = param(0.02, "ohm/h", "initial creep rate")
        time_constant_s: float = param(3600.0, "s", "saturation time constant", minimum=1e-9)

    def reset(self) -> None:
        self._t0: float | None = None

    def apply(self, state: PlantState) -> None:
        if self._t0 is None:
            self._t0 = state.t_s
        p = self.params
        tau = p.time_constant_s
        state.resistance_ohm += p.ohm_per_hour / 3600.0 * tau * (1.0 - math.exp(-(state.t_s - self._t0) / tau))
