"""Checks of a run file against what the device really sent (the relay's record)."""

from __future__ import annotations

import h5py
import numpy as np

from tsa_bench.protocol import msg


def check_rows_against_device(path, device_samples: dict[int, msg.Sample]) -> dict[str, int]:
    """Every stored row is a sample the device sent, unchanged, once, in counter order;
    ``samples_lost`` is exactly the sum of the counter gaps. Returns counts."""
    with h5py.File(path, "r") as f:
        s = {k: f["samples"][k][()] for k in ("t", "counter", "step_position", "position_raw", "resistance_raw",
                                             "adc_flags", "heater_voltage", "motor_moving")}
        lost = int(f.attrs["samples_lost"])
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
    assert lost == gaps, f"samples_lost {lost} != counter gaps {gaps}"
    return {"rows": len(counter), "gaps": gaps, "sent": len(device_samples)}
