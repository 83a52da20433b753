"""Simulating a point's protocol on its plant (shared by the simulate, diagnose and fit runners).

Units: time in s, twist in turns, load in g, length in mm, resistance in ohm.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def simulate_point(protocol: dict[str, Any], plant: dict[str, Any], seed: int, settle_s: float
                   ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """(input history, plant outputs) of ``protocol`` on ``plant`` (noise seeded), after ``settle_s``
    at the first input so a fresh load's creep has faded, as on a bench where the mass hangs first."""
    from tsa_bench.sim.history import simulate
    from tsa_bench.sim.plant import plant_from_config
    from tsa_bench.sweep.protocols import history

    hist = history(protocol)
    p = plant_from_config(plant, seed=seed)
    if settle_s > 0:
        ts = np.arange(0.0, settle_s, 1.0)
        simulate(p, ts, hist["turns"][0], hist["heater_voltage"][0], hist["load_g"][0], np.zeros(len(ts), bool))
    out = simulate(p, hist["t"] + max(settle_s, 0.0), hist["turns"], hist["heater_voltage"], hist["load_g"],
                   hist["motor_moving"].astype(bool))
    out["resistance_ohm"] = np.where(hist["heater_voltage"] > 0, np.nan, out["resistance_ohm"])  # not measured
    return hist, out


def run_data(name: str, hist: dict[str, np.ndarray], out: dict[str, np.ndarray]):
    """An in-memory run (the contract's columns) of a simulated history."""
    from tsa_bench.reproduce.experiments import run_data as make

    return make(name, hist, out)
