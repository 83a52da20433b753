"""Simulated analogue-to-digital conversion: ADS1115 (length) and CS5513 (resistance).

Units: length in mm, resistance in ohm, heater voltage in mV; outputs in raw counts.

Contract: the inverse of the bench calibrations. Length -> ``round(position.counts(L))``
clipped silently to the int16 rails (a real ADS1115 saturates without complaint).
Resistance -> ``round(R / ohm_per_count)`` in the converter's signed range
(``-2^(bits-1) .. 2^(bits-1) - 1``); beyond it the count is clipped and
``AdcFlags.RESISTANCE_OVERRANGE`` is set (the CS5513 OF bit). While the heater is on
(> 0 mV) the 50 mA sense current is switched off: the count is 0 and
``AdcFlags.RESISTANCE_NOT_MEASURED`` is set. Noise is the plant's business
(:class:`tsa_bench.sim.effects.SensorNoise`); conversion here is deterministic.
"""

from __future__ import annotations

from tsa_bench.bench.config import PositionCalibration, ResistanceCalibration
from tsa_bench.protocol.catalogue import AdcFlags

INT16_MIN, INT16_MAX = -32768, 32767
_OVERRANGE = int(AdcFlags.RESISTANCE_OVERRANGE)
_NOT_MEASURED = int(AdcFlags.RESISTANCE_NOT_MEASURED)


class SimSensors:
    """Length/resistance -> ``(position_raw, resistance_raw, adc_flags)``."""

    def __init__(self, position: PositionCalibration, resistance: ResistanceCalibration) -> None:
        self.position = position
        self.resistance = resistance
        self._offset_mm = position.offset_mm
        self._count_per_mm = 1.0 / position.mm_per_count
        self._count_per_ohm = 1.0 / resistance.ohm_per_count
        self._r_max = resistance.max_counts
        self._r_min = -resistance.max_counts - 1

    def position_raw(self, length_mm: float) -> int:
        """ADS1115 counts of the position sensor, clipped to int16."""
        counts = round((length_mm - self._offset_mm) * self._count_per_mm)
        return INT16_MAX if counts > INT16_MAX else INT16_MIN if counts < INT16_MIN else counts

    def resistance_raw(self, resistance_ohm: float) -> tuple[int, int]:
        """CS5513 counts and the flags they raise (overrange only)."""
        counts = round(resistance_ohm * self._count_per_ohm)
        if counts > self._r_max:
            return self._r_max, _OVERRANGE
        if counts < self._r_min:
            return self._r_min, _OVERRANGE
        return counts, 0

    def convert(self, length_mm: float, resistance_ohm: float, heater_mV: int) -> tuple[int, int, int]:
        """One SAMPLE's ``(position_raw, resistance_raw, adc_flags)``."""
        position_raw = self.position_raw(length_mm)
        if heater_mV > 0:
            return position_raw, 0, _NOT_MEASURED
        resistance_raw, flags = self.resistance_raw(resistance_ohm)
        return position_raw, resistance_raw, flags
