"""Simulated analogue-to-digital conversion: ADS1115 (length) and CS5513 (resistance).

Units: length in mm, resistance in ohm, heater voltage in mV; outputs in raw counts.

Contract: the inverse of the bench calibrations. Length -> ``round(position.counts(L))``
clipped silently to the int16 rails (a real ADS1115 saturates without complaint).
Resistance -> ``round(resistance.counts(R))`` (``(R - offset_ohm) / (gain ohm_per_count)``) in the converter's signed range
(``-2^(bits-1) .. 2^(bits-1) - 1``); beyond it the count is clipped and
``AdcFlags.RESISTANCE_OVERRANGE`` is set (the CS5513 OF bit). While the heater is on
(> 0 mV) the 50 mA sense current is switched off: the count is 0 and
``AdcFlags.RESISTANCE_NOT_MEASURED`` is set. Noise is the plant's business
(:class:`tsa_bench.sim.effects.SensorNoise`); conversion here is deterministic.
"""

from __future__ import annotations

import math

from tsa_bench.benchdata import PositionCalibration, ResistanceCalibration
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
        self._count_per_ohm = 1.0 / (resistance.gain * resistance.ohm_per_count)
        self._offset_ohm = resistance.offset_ohm
        self._r_max = resistance.max_counts
        self._r_min = -resistance.max_counts - 1

    def position_raw(self, length_mm: float) -> int:
        """ADS1115 counts of the position sensor, clipped to int16."""
        counts = round((length_mm - self._offset_mm) * self._count_per_mm)
        return INT16_MAX if counts > INT16_MAX else INT16_MIN if counts < INT16_MIN else counts

    def resistance_raw(self, resistance_ohm: float) -> tuple[int, int]:
        """CS5513 counts and the flags they raise (overrange only)."""
        counts = round((resistance_ohm - self._offset_ohm) * self._count_per_ohm)
        if counts > self._r_max:
            return self._r_max, _OVERRANGE
        if counts < self._r_min:
            return self._r_min, _OVERRANGE
        return counts, 0

    def convert(self, length_mm: float, resistance_ohm: float, heater_mV: int) -> tuple[int, int, int]:
        """One SAMPLE's ``(position_raw, resistance_raw, adc_flags)`` (position_raw and
        resistance_raw inline: this runs once per sample)."""
        p = round((length_mm - self._offset_mm) * self._count_per_mm)
        position_raw = INT16_MAX if p > INT16_MAX else INT16_MIN if p < INT16_MIN else p
        if heater_mV > 0:
            return position_raw, 0, _NOT_MEASURED
        counts = round((resistance_ohm - self._offset_ohm) * self._count_per_ohm)
        if counts > self._r_max:
            return position_raw, self._r_max, _OVERRANGE
        if counts < self._r_min:
            return position_raw, self._r_min, _OVERRANGE
        return position_raw, counts, 0


#: CS5513 conversion period (s): 612 clocks of its slowest (32 kHz) on-chip oscillator,
#: the firmware's drivers/cs5513.h MAX_CONVERSION_US and the simavr harness default.
CS5513_CONVERSION_S = 612 / 32000
#: Words after the sense current comes on that still average the time it was off (sinc4).
CS5513_SETTLE_S = 4 * CS5513_CONVERSION_S
#: The firmware's analog settling wait before arming a conversion (config.h RESISTANCE_SETTLE_US).
SENSE_SETTLE_S = 0.002
#: A word not ready this long before the next grid slot is given up (device_sample.cpp).
RESISTANCE_MARGIN_S = 0.0005


class ResistanceTiming:
    """When the firmware's sample gets a CS5513 word (times in s of device time).

    Contract: mirrors firmware/core/device_sample.cpp and drivers/cs5513.*. The 50 mA
    sense current comes on at the first sample with the heater off (:meth:`measured`)
    and goes off with the heater (:meth:`sense_off`). Words finish every
    ``CS5513_CONVERSION_S`` on a grid anchored where the current first came on (the
    converter then runs for good); the part keeps only the latest word, and a word is
    read once. A sample starting at ``t`` arms at ``max(t, on + SENSE_SETTLE_S)``: a
    word waiting then is used if the current has been on ``CS5513_SETTLE_S`` plus one
    conversion, else discarded; otherwise the first word finished after arming and no
    earlier than ``on + CS5513_SETTLE_S`` is used if it is ready
    ``RESISTANCE_MARGIN_S`` before the next slot. Else the sample says
    resistance_not_measured and keeps its slot.
    """

    def __init__(self) -> None:
        self._anchor_s: float | None = None
        self._on_s: float | None = None
        self._read_s = -math.inf          # finish time of the last word read out

    def sense_off(self) -> None:
        self._on_s = None

    def _latest_word(self, t_s: float) -> float:
        assert self._anchor_s is not None
        k = math.floor((t_s - self._anchor_s) / CS5513_CONVERSION_S + 1e-9)
        return self._anchor_s + k * CS5513_CONVERSION_S if k >= 1 else -math.inf

    def measured(self, t_s: float, period_s: float) -> bool:
        """Whether the sample starting at ``t_s`` (heater off) gets its resistance."""
        on_s = self._on_s
        if on_s is None:
            on_s = self._on_s = t_s
            if self._anchor_s is None:
                self._anchor_s = t_s
        if period_s <= 0:
            return True
        valid_s = on_s + CS5513_SETTLE_S
        armed_s = on_s + SENSE_SETTLE_S
        if t_s >= armed_s:
            armed_s = t_s
        deadline_s = t_s + period_s - RESISTANCE_MARGIN_S
        # self._latest_word(armed_s) inline (this runs once per sample)
        k = math.floor((armed_s - self._anchor_s) / CS5513_CONVERSION_S + 1e-9)
        waiting = self._anchor_s + k * CS5513_CONVERSION_S if k >= 1 else -math.inf
        if waiting > self._read_s:
            self._read_s = waiting
            if armed_s >= valid_s + CS5513_CONVERSION_S - 1e-9:
                return True
        k = math.ceil((max(valid_s - 1e-9, armed_s + 1e-9) - self._anchor_s) / CS5513_CONVERSION_S)
        word_s = self._anchor_s + k * CS5513_CONVERSION_S
        if word_s <= deadline_s:
            self._read_s = word_s
            return True
        self._read_s = max(self._read_s, min(self._latest_word(deadline_s), self._latest_word(valid_s - 1e-9)))
        return False

    def word_since_last(self, t_s: float) -> bool:
        """Continuous sampling: whether the sample at ``t_s`` (heater off) carries a CS5513
        word, the one finished since the previous sample's, if the filter had settled by
        then (the sense current comes on at the first such sample; words run on at the
        CS5513's own rate, one in several samples)."""
        if self._on_s is None:
            self._on_s = t_s
            if self._anchor_s is None:
                self._anchor_s = t_s
        word = self._latest_word(t_s)
        if word <= self._read_s:
            return False
        self._read_s = word
        return word >= self._on_s + CS5513_SETTLE_S - 1e-9
