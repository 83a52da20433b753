#!/usr/bin/env python3
"""Computation budget of length tracking: estimator time per sample, and latency from sample to command.

Three figures:

* estimator time per sample: OnlineLengthEstimator.update (the self-sensing inverse,
  60 play operators, creep and transient states) over a 12,000-sample Scheme 2 run
  (configs/models/scheme2-self-sensing.json), median and 99th percentile; target <= 1 ms;
* host time per control update (estimate + controller decision) inside a track_length
  run on the simulated bench (runner/tracking.py), median and max;
* latency from the sample that decided a correction to its MOVE_TO leaving the host
  (host wall time), and in device time from that sample to the first sample with the
  motor turning (the DWELLs already queued run out first: at most two sampling periods).

    python scripts/bench/control_latency.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT))


def estimator_us() -> np.ndarray:
    from tsa_bench.control.estimator import OnlineLengthEstimator
    from tsa_bench.models.fitting import from_saved
    from tsa_bench.models.saved import load_model_file
    from tsa_bench.reproduce.runs import history, simulate_history

    rng = np.random.default_rng(0)
    steps = [("hold", 5.0)]
    for _ in range(60):
        steps += [("move", float(rng.uniform(10, 50))), ("hold", 18.0)]
    h = history(steps, dt_s=0.1, load_g=250.0)
    sim = simulate_history(h, "sim-scheme2-4ply", seed=1, settle_s=60.0)
    est = OnlineLengthEstimator(from_saved(load_model_file(ROOT / "configs/models/scheme2-self-sensing.json")),
                                window_s=10.0, transient_settled_s=120.0)
    out = np.empty(len(h["t"]))
    for i, (t, r, m) in enumerate(zip(h["t"], sim["resistance_ohm"], h["motor_moving"].astype(bool))):
        t0 = time.perf_counter()
        est.update(float(t), float(r), bool(m))
        out[i] = time.perf_counter() - t0
    return out * 1e6


def tracking_run():
    from tests.control.helpers import protocol, run_text
    from tsa_bench.runner import engine

    captured = {}
    original = engine.Tracking.for_plan

    def spy(plan, spt):
        t = original(plan, spt)
        captured["tracking"] = t
        return t

    engine.Tracking.for_plan = staticmethod(spy)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            text = protocol("targets: [{length_mm: 201, hold_s: 20}, {length_mm: 213, hold_s: 20}, "
                            "{length_mm: 205, hold_s: 20}]")
            stop, run = run_text(text, Path(tmp))
    finally:
        engine.Tracking.for_plan = original
    return captured["tracking"], run


def main() -> int:
    us = estimator_us()
    print(f"estimator time per sample: median {np.median(us):.1f} us, p99 {np.percentile(us, 99):.1f} us, "
          f"max {us.max():.1f} us over {len(us)} samples (target <= 1000 us)")
    tracking, run = tracking_run()
    d = np.array(tracking.decide_s) * 1e6
    lat = np.array(tracking.command_latency_s) * 1e3
    print(f"control update (estimate + decision) in a run: median {np.median(d):.1f} us, max {d.max():.1f} us "
          f"over {len(d)} samples")
    print(f"sample -> MOVE_TO sent (host): median {np.median(lat):.2f} ms, max {lat.max():.2f} ms "
          f"over {len(lat)} corrections")
    s = run.samples
    state, moving, t = s["controller_state"], s["motor_moving"].astype(bool), s["t"]
    starts = np.flatnonzero((state[1:] == 2) & (state[:-1] != 2)) + 1
    dev = []
    for k in starts:
        after = np.flatnonzero(moving[k:])
        if len(after):
            dev.append(t[k + after[0]] - t[k])
    dev = np.array(dev)
    period = float(np.median(np.diff(t)))
    print(f"deciding sample -> motor turning (device time): median {np.median(dev):.2f} s, max {dev.max():.2f} s "
          f"(sampling period {period:g} s) over {len(dev)} corrections")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
