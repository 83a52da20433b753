"""Coupling effects found missing when the plant was calibrated to the thesis's records.

Units: twist in turns, temperature in degC (K for differences), strain dimensionless.

Contract: see :mod:`tsa_bench.sim.effects.base`. All are off unless a bench file switches
them on (``default_enabled`` False) and no-ops at their default parameters.

* ``twist_stiffening`` (geometry stage, before ``string_compliance``): inserting twist
  stiffens the coiled SCP strings, ``K_eff = K (1 + kappa |turns|)``, so the load
  stretches them less the more they are twisted. It gives the linear term of the
  twisting polynomials (Table 3.1, p1) and its growth with the load: the recovered
  stretch is ``L0 F / K * kappa |T|`` to first order, proportional to the load.
* ``thermal_softening`` (geometry stage, before ``string_compliance``): warm strings are
  softer, ``K_eff = K / (1 + sigma (T - T_amb))``: under a load the heated TSA first
  lengthens, as the thesis's 150 g heating polynomials do (p1 > 0), before it contracts.
* ``thermal_actuation`` (geometry stage): hysteretic, saturating thermal contraction,
  ``L *= 1 - s_max tanh(k (T_p - T_amb) / s_max)`` with ``T_p`` the temperature passed
  through a play operator of half width ``hysteresis_K`` (the contraction lags the
  temperature both ways: nylon SCP actuators are hysteretic in temperature). It
  replaces ``thermal_contraction`` in a preset that switches that one off; with
  ``hysteresis_K`` 0 it is a smooth version of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_effect


@register_effect
class TwistStiffening(Effect):
    """Twist stiffens the coiled strings: ``K_eff = K (1 + kappa |turns|)``.

    Source: calibration to thesis Table 3.1 (twisting p1 grows with the load: -0.10,
    -0.24, -0.29 mm/turn for 3-ply at 100/150/200 g), which a load-independent geometry
    cannot give; SCP coils change their spring rate with inserted twist (thesis 1.5.1, 2.1).
    """

    name = "twist_stiffening"
    stage = "geometry"
    default_enabled = False
    source = "calibration to thesis Table 3.1 (p1 vs load)"

    @dataclass(frozen=True)
    class Params:
        per_turn: float = param(0.0, "1/turn", "kappa: relative stiffness gain per turn of twist", minimum=0.0)

    def apply(self, state: PlantState) -> None:
        k = self.params.per_turn
        if k:
            state.stiffness_factor *= 1.0 + k * abs(state.turns)


@register_effect
class ThermalSoftening(Effect):
    """Warm strings are softer: ``K_eff = K / (1 + sigma (T - T_amb))``, so the load stretches them more.

    Source: calibration to thesis Table 3.1 (heating): for 3-ply and 4-ply at 150 g the
    length first rises with the voltage (p1 = +0.32 and +0.673 cm/V) before the thermal
    contraction takes over; nylon's modulus falls as it warms towards its glass transition.
    """

    name = "thermal_softening"
    stage = "geometry"
    default_enabled = False
    source = "calibration to thesis Table 3.1 (heating p1 > 0)"

    @dataclass(frozen=True)
    class Params:
        per_K: float = param(0.0, "1/K", "sigma: relative compliance gain per kelvin above ambient", minimum=0.0)

    def apply(self, state: PlantState) -> None:
        s = self.params.per_K
        dt = state.temperature_C - state.ambient_C
        if s and dt > 0.0:
            state.stiffness_factor /= 1.0 + s * dt


@register_effect
class ThermalActuation(Effect):
    """Hysteretic, saturating thermal contraction of the string length (module docstring).

    Source: thesis 2.4.3 and Fig. 2.6 (contraction against voltage, up and down), 3.1.4
    ('the thermally-induced actuation showed more significant hysteresis than the
    twisting-induced actuation'; Table 3.1 heating polynomials need a cubic term).
    """

    name = "thermal_actuation"
    stage = "geometry"
    default_enabled = False
    source = "thesis 2.4.3, 3.1.4, Table 3.1 (heating)"

    @dataclass(frozen=True)
    class Params:
        strain_per_K: float = param(0.0, "1/K", "initial contraction per kelvin above ambient (0: off)", minimum=0.0)
        max_strain: float = param(0.15, "1", "saturation of the thermal contraction", minimum=1e-6)
        hysteresis_K: float = param(0.0, "K", "half width of the temperature play (contraction lags both ways)",
                                    minimum=0.0)

    def reset(self) -> None:
        self._tp: float | None = None

    def apply(self, state: PlantState) -> None:
        p = self.params
        if not p.strain_per_K:
            return
        t = state.temperature_C
        tp = t if self._tp is None else min(t + p.hysteresis_K, max(t - p.hysteresis_K, self._tp))
        self._tp = tp
        dt = tp - state.ambient_C
        if dt > 0.0:
            s = p.max_strain * math.tanh(p.strain_per_K * dt / p.max_strain)
            state.string_length_mm *= 1.0 - s
