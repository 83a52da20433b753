"""Device SAMPLE rows -> the run file's sample columns, in physical units.

Contract: :func:`sample_block` takes rows ``(t_us, step_position, position_raw,
resistance_raw, adc_flags, heater_mV, motor_moving, segment, counter, load_g)`` as
received (device time in us since boot, raw counts) and returns a
:class:`~tsa_bench.rundocs.SampleBlock` with every column of
:data:`~tsa_bench.rundocs.SAMPLE_COLUMNS`: time in s from ``t0_us``, twist in
turns, length in mm and resistance in ohm through the bench calibration (NaN where the
device flags the reading invalid or not measured), heater voltage in V, load in N
(NaN when undeclared). The runner and the rig commands (jog) use the same conversion.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import chain

import numpy as np

from tsa_bench.benchdata import BenchConfig
from tsa_bench.protocol import msg
from tsa_bench.rundocs import SAMPLE_COLUMNS, SampleBlock
from tsa_bench.units import G_N_PER_G


def row(s: msg.Sample, segment: int, load_g: float) -> tuple:
    """One received SAMPLE as a row for :func:`sample_block`."""
    return (s.t_us, s.step_position, s.position_raw, s.resistance_raw, s.adc_flags, s.heater_mV, s.motor_moving,
            segment, s.counter, load_g)


def length_mm(bench: BenchConfig, position_raw: float, adc_flags: int) -> float:
    """One sample's length (mm), NaN when the position reading failed."""
    if adc_flags & msg.AdcFlags.POSITION_INVALID:
        return float("nan")
    return float(bench.position.length_mm(position_raw))


def resistance_ohm(bench: BenchConfig, resistance_raw: float, adc_flags: int) -> float:
    """One sample's resistance (ohm), NaN when it was not measured (heater on, sense current off)."""
    if adc_flags & msg.AdcFlags.RESISTANCE_NOT_MEASURED:
        return float("nan")
    return float(bench.resistance.resistance_ohm(resistance_raw))


def sample_block(rows: Sequence[tuple], bench: BenchConfig, steps_per_turn: int, t0_us: int) -> SampleBlock:
    """Rows (see the module contract) -> one block of physical columns."""
    n = len(rows)
    width = len(rows[0]) if n else 10
    if len(set(map(len, rows))) > 1:
        raise ValueError(f"sample rows of different lengths (the first has {width} fields)")
    # the same float64 values as np.array(rows), in half its time on a run's blocks
    a = np.fromiter(chain.from_iterable(rows), dtype=np.float64, count=n * width).reshape(n, width)
    flags = a[:, 4].astype(np.uint8)
    resistance = bench.resistance.resistance_ohm(a[:, 3])
    resistance[(flags & msg.AdcFlags.RESISTANCE_NOT_MEASURED) != 0] = np.nan
    length = bench.position.length_mm(a[:, 2])
    length[(flags & msg.AdcFlags.POSITION_INVALID) != 0] = np.nan
    cols = {
        "t": (a[:, 0] - t0_us) / 1e6,
        "turns": a[:, 1] / steps_per_turn,
        "length": length,
        "resistance": resistance,
        "heater_voltage": a[:, 5] / 1000.0,
        "load": a[:, 9] * G_N_PER_G,
        "segment": a[:, 7],
        "motor_moving": a[:, 6],
        "counter": a[:, 8],
        "step_position": a[:, 1],
        "position_raw": a[:, 2],
        "resistance_raw": a[:, 3],
        "adc_flags": flags,
    }
    return SampleBlock({k: np.asarray(v).astype(SAMPLE_COLUMNS[k][0]) for k, v in cols.items()})


def segments_outside_plan(block: SampleBlock, n_segments: int) -> str | None:
    """The runner's check before a block is stored: every sample's ``segment`` is a segment
    of the plan (0 .. ``n_segments`` - 1) or -1 (outside the plan: set-up, tear-down).
    Samples that break it are stored with -1 (their data kept, the index never a wrong
    one) and the returned text says what was found (None: all fine)."""
    seg = block.columns["segment"]
    outside = (seg < -1) | (seg >= n_segments)
    if not outside.any():
        return None
    found = np.unique(seg[outside])
    seg[outside] = -1
    return (f"{int(outside.sum())} sample(s) named segment(s) {', '.join(map(str, found[:5].tolist()))} outside the "
            f"plan's {n_segments} segments (stored as -1, outside the plan)")
