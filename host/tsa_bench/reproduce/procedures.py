"""The thesis's chapter-3 procedures on simulated runs; returns the rows of their tables.

Units: errors of the self-sensing procedure in % of the measured value (eq. 3.21) and
in ohm / mm; Preisach-vs-polynomial errors (E_aver, sigma, eqs. 3.5-3.6) in mm.

Contract:

* :func:`step_duration_procedure` generates the five step-duration runs of section
  2.5.2 (2.4, 6, 17, 32, 98 s; 350 g; sim.yaml's plant), identifies the strain-resistance
  and self-sensing models on the 6 s and 32 s runs exactly as `tsa-bench fit` does
  (:func:`tsa_bench.models.fitting.fit`) and validates them on all five.
* :func:`preisach_vs_polynomial` generates, per string (3-ply: 100/150/200 g, 72 turns;
  4-ply: 150/200/250 g, 81 turns; presets sim-3ply / sim-4ply) and load, a twist sweep
  (input turns) and a twist-then-heat run (input heater voltage, 0 -> 8 -> 0 V) and
  fits both models to each (M = 20, order 3).
Run files are written to ``work_dir`` and read back through the run-file reader.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tsa_bench.models.fitting import fit
from tsa_bench.reproduce.runs import (history, simulate_history, step_duration_steps, twist_heat_steps,
                                      twist_sweep_steps, write_run)
from tsa_bench.rundata import RunData
from tsa_bench.store.reader import read_run

DURATIONS_S = (2.4, 6.0, 17.0, 32.0, 98.0)
TRAINING_S = (6.0, 32.0)
STRINGS = {"3-ply": ("sim-3ply", 72.0, (100.0, 150.0, 200.0)), "4-ply": ("sim-4ply", 81.0, (150.0, 200.0, 250.0))}


def step_duration_runs(work_dir: Path, cycles: int = 2, seed: int = 0) -> dict[float, RunData]:
    """The five step-duration runs (sampled at 20 Hz for 2.4 s steps, 10 Hz otherwise)."""
    runs = {}
    for i, d in enumerate(DURATIONS_S):
        h = history(step_duration_steps(d, cycles=cycles), dt_s=0.05 if d < 3 else 0.1, load_g=350.0)
        sim = simulate_history(h, "sim", seed=seed + i)
        path = write_run(Path(work_dir) / f"steps-{d:g}s.h5", h, sim, f"step duration {d:g} s, 350 g")
        runs[d] = read_run(path)
    return runs


def step_duration_procedure(work_dir: Path, cycles: int = 2, seed: int = 0) -> dict[str, Any]:
    """Fit both models on the 6 s + 32 s runs, validate on all; rows per model and duration."""
    runs = step_duration_runs(work_dir, cycles, seed)
    train = [runs[d] for d in TRAINING_S]
    others = [runs[d] for d in DURATIONS_S if d not in TRAINING_S]
    out: dict[str, Any] = {}
    for model in ("strain-resistance", "self-sensing"):
        saved = fit(model, train, validate=others)
        rows = []
        for d in DURATIONS_S:
            path = runs[d].path
            kind = "identification" if d in TRAINING_S else "validation"
            m = saved.metrics[kind][path]
            rows.append({"step_s": d, "set": kind, **m})
        out[model] = {"saved": saved, "rows": rows}
    return out


def preisach_vs_polynomial(work_dir: Path, strings: tuple[str, ...] = ("3-ply", "4-ply"), sweep_cycles: int = 1,
                           heat_hold_s: float = 90.0, seed: int = 0) -> list[dict[str, Any]]:
    """Rows: string, load, input mode, E_aver and sigma of both models and their ratio."""
    rows = []
    for s in strings:
        preset, full, loads = STRINGS[s]
        for j, load in enumerate(loads):
            for mode, steps, col in (("twisting", twist_sweep_steps(full, cycles=sweep_cycles), "turns"),
                                     ("heating", twist_heat_steps(full, hold_s=heat_hold_s), "heater_voltage")):
                h = history(steps, dt_s=0.1, load_g=load)
                sim = simulate_history(h, preset, seed=seed + j)
                run = read_run(write_run(Path(work_dir) / f"{s}-{load:g}g-{mode}.h5", h, sim,
                                         f"{s} {load:g} g {mode}"))
                res = {}
                for model in ("preisach", "polynomial"):
                    saved = fit(model, [run], input_col=col, output_col="length")
                    res[model] = saved.metrics["identification"][run.path]
                rows.append({"string": s, "load_g": load, "mode": mode,
                             "preisach_e_aver_mm": res["preisach"]["e_aver"],
                             "preisach_sigma_mm": res["preisach"]["sigma"],
                             "polynomial_e_aver_mm": res["polynomial"]["e_aver"],
                             "polynomial_sigma_mm": res["polynomial"]["sigma"],
                             "ratio": res["polynomial"]["e_aver"] / max(res["preisach"]["e_aver"], 1e-12)})
    return rows
