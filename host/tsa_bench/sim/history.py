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
    out_l = np.empty(n)
    out_r = np.empty(n)
    out_t = np.empty(n)
    out_a = np.empty(n)
    state = plant.state
    sample = plant.sample
    current_load = None
    for i, (ti, ni, vi, li, mi) in enumerate(zip(t.tolist(), tw.tolist(), volts.tolist(), loads.tolist(),
                                                moving.tolist())):
        if li != current_load:
            plant.set_load(li)
            current_load = li
        reading = sample(ti, ni, vi, mi)
        out_l[i] = reading.length_mm
        out_r[i] = reading.resistance_ohm
        out_t[i] = state.temperature_C
        out_a[i] = state.turns
    return {"t_s": t.copy(), "length_mm": out_l, "resistance_ohm": out_r, "temperature_C": out_t,
            "turns_actual": out_a}
