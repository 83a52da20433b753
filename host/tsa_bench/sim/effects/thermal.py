"""Thermal effects: Joule heating/cooling of the strings and thermal contraction.

Units: temperature in degC, power in W, voltage in V, time in s, length in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_effect


@register_effect
class ThermalDynamics(Effect):
    """String temperature: fast first-order heating, slow creep-like cooling.

    Heating follows ``C dT/dt = V^2/R0 - (T - T_amb)/R_th`` (time constant ``C R_th``,
    seconds). Cooling towards a lower steady state relaxes with ``cooling_time_constant_s``
    instead: the thesis reports full actuation within a few seconds but complete cooling
    (length recovery) over one minute, attributed to nylon creep, so the slow return is
    lumped into the temperature that drives contraction. Discretised exactly for
    piecewise-constant voltage. Off: the strings stay at ambient. Source: thesis 2.4.3.
    """

    name = "thermal_dynamics"
    stage = "thermal"
    source = "thesis 2.4.3 (heats in seconds, cools over > 1 min)"

    @dataclass(frozen=True)
    class Params:
        thermal_resistance_K_per_W: float = param(5.0, "K/W", "R_th, string to ambient", minimum=1e-9)
        heat_capacity_J_per_K: float = param(0.3, "J/K", "C; heating time constant C R_th", minimum=1e-9)
        cooling_time_constant_s: float = param(30.0, "s", "slow (creep-like) cooling/recovery time constant",
                                               minimum=1e-9)

    def reset(self) -> None:
        self._t: float | None = None

    def apply(self, state: PlantState) -> None:
        p = self.params
        if self._t is None:
            self._t = state.ambient_C
        v = state.heater_voltage_V
        r0 = state.resistance0_ohm
        t_ss = state.ambient_C + (v * v / r0 * p.thermal_resistance_K_per_W if r0 > 0.0 else 0.0)
        dt = state.dt_s
        if dt > 0.0:
            tau = p.heat_capacity_J_per_K * p.thermal_resistance_K_per_W if t_ss > self._t \
                else p.cooling_time_constant_s
            self._t += (t_ss - self._t) * (1.0 - math.exp(-dt / tau))
        state.temperature_C = self._t


@register_effect
class ThermalContraction(Effect):
    """Heated SCP strings contract: ``L *= 1 - min(max_strain, k (T - T_amb))``.

    Source: thesis 2.4.3 and Fig. 2.6: 4-ply pair, 250 g, +14.1 % contraction from
    heating after 81 turns; 3-ply, 200 g: 13.49 % passive -> 27.01 % active.
    """

    name = "thermal_contraction"
    stage = "geometry"
    source = "thesis 2.4.3, Fig. 2.6"

    @dataclass(frozen=True)
    class Params:
        strain_per_K: float = param(0.00193, "1/K", "string contraction per kelvin above ambient", minimum=0.0)
        max_strain: float = param(0.15, "1", "largest thermal contraction of the string length", minimum=0.0)

    def apply(self, state: PlantState) -> None:
        p = self.params
        s = p.strain_per_K * (state.temperature_C - state.ambient_C)
        if s > 0.0:
            state.string_length_mm *= 1.0 - (s if s < p.max_strain else p.max_strain)
