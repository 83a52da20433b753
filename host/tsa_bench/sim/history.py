"""Run the plant directly on an input history, without the device or protocol stack.

Units: time in s, twist in motor turns, heater voltage in V, load in g; outputs in mm,
ohm, degC and turns.

Contract: :func:`simulate` samples a fresh plant (built from a ``plant`` config
mapping) or the given :class:`~tsa_bench.sim.plant.TsaPlant` (continuing from its
state) once per element of ``t_s`` (nondecreasing), exactly as the simulated device
does, and returns equal-length float arrays.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tsa_bench.sim.plant import TsaPlant, plant_from_config


def simulate(plant_cfg_or_plant: Mapping[str, Any] | TsaPlant, t_s: np.ndarray, turns: np.ndarray,
             heater_voltage_V: np.ndarray | float, load_g: np.ndarray | float,
             motor_moving: np.ndarray | None = None, seed: int | None = None) -> dict[str, np.ndarray]:
    """Sample the plant on the history; return ``length_mm``, ``resistance_ohm``,
    ``temperature_C``, ``turns_actual`` (and ``t_s``).

    ``heater_voltage_V`` and ``load_g`` may be scalars. ``motor_moving`` defaults to
    "the commanded twist changed since the previous sample". ``seed`` overrides the
    config's seed (ignored when a plant is given).
    """
    plant = plant_cfg_or_plant if isinstance(plant_cfg_or_plant, TsaPlant) else plant_from_config(
        plant_cfg_or_plant, seed=seed)
    t = np.asarray(t_s, dtype=float)
    n = len(t)
    tw = np.broadcast_to(np.asarray(turns, dtype=float), (n,))
    volts = np.broadcast_to(np.asarray(heater_voltage_V, dtype=float), (n,))
    loads = np.broadcast_to(np.asarray(load_g, dtype=float), (n,))
    if motor_moving is None:
        moving = np.zeros(n, dtype=bool)
        if n > 1:
            moving[1:] = np.diff(tw) != 0
    else:
        moving = np.broadcast_to(np.asarray(motor_moving, dtype=bool), (n,))
    out: dict[str, list[np.ndarray]] = {"length_mm": [], "resistance_ohm": [], "temperature_C": [],
                                        "turns_actual": []}
    # one block per run of constant load (the load changes only through set_load)
    starts = [0] + (np.flatnonzero(loads[1:] != loads[:-1]) + 1).tolist() if n else []
    for a, b in zip(starts, starts[1:] + [n]):
        plant.set_load(float(loads[a]))
        block = plant.sample_block(t[a:b], tw[a:b], volts[a:b], moving[a:b], state=True)
        for key in out:
            out[key].append(block[key])
    cols = {key: np.concatenate(parts) if parts else np.empty(0) for key, parts in out.items()}
    return {"t_s": t.copy(), **cols}
