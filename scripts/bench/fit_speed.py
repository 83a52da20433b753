"""Identification times of the thesis's models (issue 7 figures).

Usage: PYTHONPATH=host python3 scripts/bench/fit_speed.py [--repeats N]

Prints (best of N):
* Preisach M = 20 identification on 10,000 samples (target < 0.5 s): a simulated
  4-ply twist sweep (turns -> length), 10 Hz, cut to 10,000 samples;
* strain-resistance identification on the two training runs (6 s and 32 s step
  durations, 2 staircases each; target < 20 s), and the self-sensing envelopes on top.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from tsa_bench.models.fitting import series
from tsa_bench.models.preisach import PreisachModel
from tsa_bench.models.self_sensing import SelfSensingModel
from tsa_bench.models.strain_resistance import StrainResistanceModel
from tsa_bench.reproduce.procedures import step_duration_runs
from tsa_bench.reproduce.runs import history, simulate_history, twist_sweep_steps


def best_of(n: int, fn) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(n):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    h = history(twist_sweep_steps(81.0, cycles=7), dt_s=0.1, load_g=250.0)
    sim = simulate_history(h, "sim-4ply")
    u, y = h["turns"][:10_000], sim["length_mm"][:10_000]
    assert len(u) == 10_000, len(u)
    dt, model = best_of(args.repeats, lambda: PreisachModel.fit(u, y, levels=20))
    err = np.mean(np.abs(model.predict(u) - y))
    print(f"Preisach M=20 identification, 10,000 samples: {dt:.3f} s (target < 0.5 s); E_aver {err:.4f} mm")
    runs = step_duration_runs(Path(tempfile.mkdtemp(prefix="fit-speed-")), cycles=2)
    train = [series(runs[6.0]), series(runs[32.0])]
    n = sum(len(r.t_s) for r in train)
    dt, sr = best_of(args.repeats, lambda: StrainResistanceModel.identify(train))
    print(f"strain-resistance identification, 6 s + 32 s runs ({n} samples): {dt:.3f} s (target < 20 s)")
    dt, _ = best_of(args.repeats, lambda: SelfSensingModel.identify(sr, train))
    print(f"self-sensing envelope identification on the same runs: {dt:.3f} s")


if __name__ == "__main__":
    main()
