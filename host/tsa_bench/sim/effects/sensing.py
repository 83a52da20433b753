"""Sensor effects: additive noise and quantisation of the length and resistance readings.

Units: length in mm, resistance in ohm.
"""

from __future__ import annotations

from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_effect


@register_effect
class SensorNoise(Effect):
    """Additive white Gaussian noise on both channels (standard deviations; 0 disables).

    Source: thesis 2.2 (SPS-L225-HALS position sensor, CS5513 resistance ADC).
    """

    name = "sensor_noise"
    stage = "sensor"
    source = "thesis 2.2"

    @dataclass(frozen=True)
    class Params:
        length_noise_mm: float = param(0.05, "mm", "std of the position reading", minimum=0.0)
        resistance_noise_ohm: float = param(0.001, "ohm", "std of the resistance reading", minimum=0.0)

    def reset(self) -> None:
        self._gauss = self.rng.gauss

    def apply(self, state: PlantState) -> None:
        p = self.params
        if p.length_noise_mm:
            state.length_mm += self._gauss(0.0, p.length_noise_mm)
        if p.resistance_noise_ohm:
            state.resistance_ohm += self._gauss(0.0, p.resistance_noise_ohm)


@register_effect
class Quantisation(Effect):
    """Round each reading to its sensor's resolution (0 disables a channel).

    Source: thesis 2.2: position sensor resolution 0.14 mm; 0.240 uOhm resistance
    resolution (CS5513). The bench ADC conversion (tsa_bench.sim.sensors) follows.
    """

    name = "quantisation"
    stage = "sensor"
    source = "thesis 2.2"

    @dataclass(frozen=True)
    class Params:
        length_resolution_mm: float = param(0.14, "mm", "position sensor resolution", minimum=0.0)
        resistance_resolution_ohm: float = param(2.4e-7, "ohm", "resistance measurement resolution", minimum=0.0)

    def apply(self, state: PlantState) -> None:
        p = self.params
        q = p.length_resolution_mm
        if q:
            state.length_mm = round(state.length_mm / q) * q
        q = p.resistance_resolution_ohm
        if q:
            state.resistance_ohm = round(state.resistance_ohm / q) * q
