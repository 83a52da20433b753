"""Simulated ADS1115 / CS5513 conversion against the bench calibrations."""

from __future__ import annotations

import pytest

from tsa_bench.bench import load_bench
from tsa_bench.protocol.catalogue import AdcFlags
from tsa_bench.sim import SimSensors


@pytest.fixture
def sensors() -> SimSensors:
    b = load_bench(None)
    return SimSensors(b.position, b.resistance)


def test_position_round_trips_through_the_calibration(sensors):
    for length_mm in (150.0, 213.37, 280.0, 375.0):
        counts = sensors.position_raw(length_mm)
        assert counts == round(sensors.position.counts(length_mm))
        assert sensors.position.length_mm(counts) == pytest.approx(length_mm, abs=sensors.position.mm_per_count)


def test_position_clips_silently_at_the_rails(sensors):
    assert sensors.convert(1e6, 5.0, 0) == (32767, round(5.0 / sensors.resistance.ohm_per_count), 0)
    assert sensors.convert(-1e6, 5.0, 0)[0] == -32768
    assert sensors.convert(-1e6, 5.0, 0)[2] == 0


def test_resistance_counts_and_overrange(sensors):
    opc = sensors.resistance.ohm_per_count
    assert sensors.convert(250.0, 5.5, 0)[1:] == (round(5.5 / opc), 0)
    top = sensors.resistance.max_counts
    assert sensors.convert(250.0, 60.0, 0)[1:] == (top, int(AdcFlags.RESISTANCE_OVERRANGE))
    assert sensors.convert(250.0, -60.0, 0)[1:] == (-top - 1, int(AdcFlags.RESISTANCE_OVERRANGE))
    assert sensors.convert(250.0, top * opc, 0)[2] == 0


def test_heater_on_means_resistance_not_measured(sensors):
    pos, res, flags = sensors.convert(250.0, 5.5, 1)
    assert pos == sensors.position_raw(250.0)
    assert (res, flags) == (0, int(AdcFlags.RESISTANCE_NOT_MEASURED))
