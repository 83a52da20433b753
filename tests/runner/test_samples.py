"""Device sample rows -> physical columns (runner/samples.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tsa_bench.bench import load_bench
from tsa_bench.protocol import msg
from tsa_bench.runner.samples import sample_block
from tsa_bench.units import G_N_PER_G


def test_columns_from_rows_in_physical_units():
    bench = load_bench(None)
    nm = int(msg.AdcFlags.RESISTANCE_NOT_MEASURED)
    rows = [(1_100_000, 3200, 1000, 5000, 0, 0, 1, 0, 7, 550.0),
            (1_200_000, 6400, -32768, 0, nm, 2500, 0, 1, 8, math.nan)]
    block = sample_block(rows, bench, 3200, 1_000_000)
    c = block.columns
    assert c["t"].tolist() == [0.1, 0.2]
    assert c["turns"].tolist() == [1.0, 2.0]
    assert c["length"].tolist() == [float(bench.position.length_mm(1000.0)), float(bench.position.length_mm(-32768.0))]
    assert c["resistance"][0] == float(bench.resistance.resistance_ohm(5000.0)) and np.isnan(c["resistance"][1])
    assert c["heater_voltage"].tolist() == [0.0, 2.5]
    assert c["load"][0] == 550.0 * G_N_PER_G and np.isnan(c["load"][1])
    assert c["counter"].tolist() == [7, 8] and c["adc_flags"].tolist() == [0, nm]
    assert c["segment"].tolist() == [0, 1] and c["motor_moving"].tolist() == [1, 0]


def test_rows_of_different_lengths_are_refused():
    with pytest.raises(ValueError, match="different lengths"):
        sample_block([(1, 2, 3, 4, 0, 0, 0, 0, 1, 5.0), (1, 2, 3)], load_bench(None), 3200, 0)
