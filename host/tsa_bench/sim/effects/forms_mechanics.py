"""Alternative form of length creep: creep after twist changes (the library's
``length_creep`` creeps after load changes).

Units: twist in turns, time in s.

Contract: see :mod:`tsa_bench.sim.effects.base` (``register_form``); off unless a plant
config names it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_form


@register_form
class LengthCreepTwist(Effect):
    """After a twist change the strings follow part of it at once and creep the rest.

    The twist the kinematics sees is ``w - g (w - w_f)``, with ``w`` the twist after the
    other geometry effects and ``w_f`` its first-order lag (``time_constant_s``, exact for
    piecewise-constant twist): a fraction ``g`` of every length change arrives with that
    time constant, in both directions. Source: thesis 2.5.2 (mild length creep), 2.4.2
    (friction between strings and plies); viscoelastic creep of nylon (thesis ref. [68]).
    """

    name = "length_creep_twist"
    stage = "geometry"
    form_of = "length_creep"
    form = "after twist changes"
    source = "thesis 2.5.2, 2.4.2; nylon viscoelasticity"

    @dataclass(frozen=True)
    class Params:
        creep_fraction: float = param(0.1, "1", "fraction g of a twist change that arrives by creep", minimum=0.0)
        time_constant_s: float = param(30.0, "s", "creep time constant", minimum=1e-9)

    def reset(self) -> None:
        self._lag: float | None = None

    def apply(self, state: PlantState) -> None:
        p = self.params
        w = state.turns_eff
        if self._lag is None:
            self._lag = w
        elif state.dt_s > 0.0:
            self._lag += (w - self._lag) * (1.0 - math.exp(-state.dt_s / p.time_constant_s))
        state.turns_eff = w - p.creep_fraction * (w - self._lag)
