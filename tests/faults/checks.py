"""Checks of a run file against what the device really sent (the relay's record)."""

from __future__ import annotations

import h5py
import numpy as np

from tsa_bench.protocol import msg


def check_rows_against_device(path, device_samples: dict[int, msg.Sample]) -> dict[str, int]:
    """Every stored row is a sample the device sent, unchanged, once, in counter order;
    ``samples_lost`` is exactly the sum of the counter gaps; every stored segment index
    is a segment of the plan (or -1, outside it) and the one the device named (see
    :func:`check_segments`). Returns counts."""
    with h5py.File(path, "r") as f:
        s = {k: f["samples"][k][()] for k in ("t", "counter", "step_position", "position_raw", "resistance_raw",
                                             "adc_flags", "heater_voltage", "motor_moving", "segment")}
        lost = int(f.attrs["samples_lost"])
        n_segments = int(f.attrs["n_segments"])
    counter = s["counter"].astype(np.int64)
    assert np.all(np.diff(counter) > 0), "counters not strictly increasing: a duplicated or reordered row"
    wrong = 0
    t0_us = None
    for i, c in enumerate(counter):
        d = device_samples.get(int(c))
        assert d is not None, f"row {i}: counter {c} was never sent by the device"
        t0_us = d.t_us - round(s["t"][i] * 1e6) if t0_us is None else t0_us
        row = (round(s["t"][i] * 1e6) + t0_us, int(s["step_position"][i]), int(s["position_raw"][i]),
               int(s["resistance_raw"][i]), int(s["adc_flags"][i]), round(s["heater_voltage"][i] * 1000),
               int(s["motor_moving"][i]))
        sent = (d.t_us, d.step_position, d.position_raw, d.resistance_raw, d.adc_flags, d.heater_mV, d.motor_moving)
        wrong += abs(row[0] - sent[0]) > 1 or row[1:] != sent[1:]
    gaps = int((np.diff(counter) - 1).sum()) if len(counter) > 1 else 0
    assert wrong == 0, f"{wrong} stored rows differ from what the device sent"
    check_segments(s["segment"], np.array([device_samples[int(c)].segment for c in counter]), n_segments)
    assert lost == gaps, f"samples_lost {lost} != counter gaps {gaps}"
    return {"rows": len(counter), "gaps": gaps, "sent": len(device_samples)}


def check_segments(stored: np.ndarray, wire: np.ndarray, n_segments: int) -> None:
    """Stored segment indices against the device's (``wire``, modulo 65535, 0xFFFF none):
    each is a segment of the plan or -1, congruent to what the device said (-1 where it
    said none), and they never go back (the device runs its segments in order)."""
    from tsa_bench.runner.commands import NO_SEGMENT, WIRE_SEGMENTS

    stored = stored.astype(np.int64)
    outside = (stored < -1) | (stored >= n_segments)
    assert not outside.any(), f"{int(outside.sum())} rows with a segment outside the plan's {n_segments}: " \
                              f"{np.unique(stored[outside])[:5]}"
    got = np.where(stored == -1, -1, stored % WIRE_SEGMENTS)
    bad = got != np.where(wire == NO_SEGMENT, -1, wire)
    assert not bad.any(), f"{int(bad.sum())} rows stored another segment than the device named, first at row " \
                          f"{int(np.argmax(bad))}: stored {stored[bad][:5]}, device {wire[bad][:5]}"
    in_plan = stored[stored >= 0]
    assert np.all(np.diff(in_plan) >= 0), "stored segment indices go back"
