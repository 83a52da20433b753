"""Sensor drift: the length and resistance readings drift with time, by an offset or a gain.

Units: length in mm, resistance in ohm, time in s (rates per hour).

Contract: see :mod:`tsa_bench.sim.effects.base`. Each effect changes only the reading of
its sensor (the plant's state is what it was), growing linearly with the time since the
plant's first sample ``t0``: an **offset drift** adds ``rate (t - t0) / 3600`` (an
amplifier's zero creeping with its temperature), a **gain drift** multiplies the reading by
``1 + rate (t - t0) / 3600`` (a sense current or reference voltage that drifts: the
error grows with the reading). All four are off unless a bench file switches them on
(``default_enabled`` False) and do nothing at a rate of 0; they run after the sensor noise
and quantisation, so a
plant that never names them draws the same random numbers as before they existed (the
bench's own ADC conversion, :mod:`tsa_bench.sim.sensors`, quantises the reading last).
They are what ``diagnose`` calls ``length_sensor_drift`` and ``resistance_sensor_drift``
(two forms each): an artefact of the measurement that a physical effect growing with
time (resistance creep with time) can mimic on a single run.
"""

from __future__ import annotations

from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_effect


class _Drift(Effect):
    """Shared logic: the time since the plant's first sample."""

    stage = "sensor"
    default_enabled = False

    def reset(self) -> None:
        self._t0: float | None = None

    def hours(self, state: PlantState) -> float:
        if self._t0 is None:
            self._t0 = state.t_s
        return (state.t_s - self._t0) / 3600.0


@register_effect
class LengthOffsetDrift(_Drift):
    """The length reading's zero drifts: ``X_read = X + rate (t - t0)``.

    Source: SPS-L225-HALS datasheet (zero drift with temperature); a linear drift over a
    run is the first term of any slow drift.
    """

    name = "length_offset_drift"
    source = "sensor datasheets (zero drift); drift of the bench's length channel"

    @dataclass(frozen=True)
    class Params:
        mm_per_hour: float = param(0.0, "mm/h", "drift rate of the length reading's zero")

    def apply(self, state: PlantState) -> None:
        if self.params.mm_per_hour:
            state.length_mm += self.params.mm_per_hour * self.hours(state)


@register_effect
class LengthGainDrift(_Drift):
    """The length reading's gain drifts: ``X_read = X (1 + rate (t - t0))``.

    Source: ratiometric sensor with a drifting supply or reference (SPS-L225-HALS into an
    ADS1115 with its own reference, thesis 2.2).
    """

    name = "length_gain_drift"
    source = "thesis 2.2 (ratiometric length channel); reference drift"

    @dataclass(frozen=True)
    class Params:
        per_hour: float = param(0.0, "1/h", "relative drift rate of the length reading's gain")

    def apply(self, state: PlantState) -> None:
        if self.params.per_hour:
            state.length_mm *= 1.0 + self.params.per_hour * self.hours(state)


@register_effect
class ResistanceOffsetDrift(_Drift):
    """The resistance reading's zero drifts: ``R_read = R + rate (t - t0)``.

    Source: CS5513 offset drift, thermal EMFs in the leads (thesis 2.2 four-wire setup).
    """

    name = "resistance_offset_drift"
    source = "thesis 2.2 (CS5513, four-wire leads); offset drift"

    @dataclass(frozen=True)
    class Params:
        ohm_per_hour: float = param(0.0, "ohm/h", "drift rate of the resistance reading's zero")

    def apply(self, state: PlantState) -> None:
        if self.params.ohm_per_hour:
            state.resistance_ohm += self.params.ohm_per_hour * self.hours(state)


@register_effect
class ResistanceGainDrift(_Drift):
    """The resistance reading's gain drifts: ``R_read = R (1 + rate (t - t0))``.

    Source: the 50 mA sense current or the 2.5 V reference drifting (thesis 2.2: AD8276
    current source, CS5513 reference): every reading scales with it.
    """

    name = "resistance_gain_drift"
    source = "thesis 2.2 (AD8276 sense current, CS5513 reference); gain drift"

    @dataclass(frozen=True)
    class Params:
        per_hour: float = param(0.0, "1/h", "relative drift rate of the resistance reading's gain")

    def apply(self, state: PlantState) -> None:
        if self.params.per_hour:
            state.resistance_ohm *= 1.0 + self.params.per_hour * self.hours(state)
