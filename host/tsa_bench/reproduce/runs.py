"""Simulated runs for the thesis's modelling procedures, generated from input histories.

Units: time in s, twist in turns, heater voltage in V, load in g (N in the run file),
length in mm, resistance in ohm.

Contract: a history is a list of steps ``("move", turns)``, ``("hold", s)``,
``("heater", V, s)`` (heater at V for s, motor stopped). :func:`history` samples it at
``dt_s`` (moves at ``rate_turns_per_s``, one sample per ``dt_s``, motor_moving = 1).
:func:`simulate_history` runs a bench preset's plant (``configs/bench/<preset>.yaml``)
on it after a pre-settle of ``settle_s`` at the starting state (so the load's length
creep has faded, as on a bench where the mass hangs before the experiment), and
:func:`write_run` stores the result as a contract run file (docs/run-format.md).
The thesis's step-duration runs (section 2.5.2, 350 g, staircase 15 -> 25 -> 15 turns in
2-turn steps) are :func:`step_duration_steps`; the twist sweeps and heating runs of
section 2.4 are :func:`twist_sweep_steps` and :func:`twist_heat_steps`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import yaml

from tsa_bench.sim.history import simulate
from tsa_bench.sim.kinematics import NEWTON_PER_GRAM
from tsa_bench.sim.plant import plant_from_config
from tsa_bench.shipped import shipped

BENCH_DIR = shipped("bench")
RATE_TURNS_PER_S = 3.33


def preset_plant(preset: str) -> dict[str, Any]:
    """The ``plant`` mapping of ``configs/bench/<preset>.yaml``."""
    return dict(yaml.safe_load((BENCH_DIR / f"{preset}.yaml").read_text(encoding="utf-8"))["plant"])


def step_duration_steps(hold_s: float, cycles: int = 2, lo: int = 15, hi: int = 25, step: int = 2,
                        rest_s: float = 120.0) -> list[tuple]:
    """Thesis 2.5.2: move to ``lo``, rest, then ``cycles`` staircases lo -> hi -> lo of ``hold_s`` holds."""
    s: list[tuple] = [("hold", 5.0), ("move", lo), ("hold", rest_s)]
    up = list(range(lo + step, hi + 1, step))
    targets = up + list(range(hi - step, lo - 1, -step))
    for _ in range(cycles):
        for x in targets:
            s += [("move", x), ("hold", hold_s)]
    return s


def twist_sweep_steps(full_turns: float, step_turns: float = 8.0, hold_s: float = 5.0, cycles: int = 1) -> list[tuple]:
    """Thesis 2.4.2: 0 -> full -> 0 turns in steps held ``hold_s`` (as configs/protocols/twist-sweep-*.yaml)."""
    n = int(round(full_turns / step_turns))
    up = [full_turns * i / n for i in range(1, n + 1)]
    s: list[tuple] = [("hold", 10.0)]
    for _ in range(cycles):
        for x in up + up[-2::-1] + [0.0]:
            s += [("move", x), ("hold", hold_s)]
    return s


def twist_heat_steps(full_turns: float, max_V: float = 8.0, hold_s: float = 90.0) -> list[tuple]:
    """Thesis 2.4.3: twist to ``full_turns``, heater 0 -> max -> 0 V in 1 V steps of ``hold_s``, untwist."""
    volts = list(range(0, int(max_V) + 1)) + list(range(int(max_V) - 1, -1, -1))
    s: list[tuple] = [("hold", 10.0), ("move", full_turns), ("hold", 30.0)]
    s += [("heater", float(v), hold_s) for v in volts]
    s += [("hold", 120.0), ("move", 0.0), ("hold", 10.0)]
    return s


def history(steps: list[tuple], dt_s: float = 0.1, load_g: float = 350.0,
            rate_turns_per_s: float = RATE_TURNS_PER_S) -> dict[str, np.ndarray]:
    """Sample ``steps`` every ``dt_s``: t, turns, heater_voltage, load_g, motor_moving, segment."""
    t, turns, volts, moving, seg = [], [], [], [], []
    now, pos = 0.0, 0.0
    for k, st in enumerate(steps):
        if st[0] == "move":
            target = float(st[1])
            n = max(1, int(math.ceil(abs(target - pos) / rate_turns_per_s / dt_s)))
            for x in pos + (target - pos) * np.arange(1, n + 1) / n:
                t.append(now); turns.append(x); volts.append(0.0); moving.append(1); seg.append(k)
                now += dt_s
            pos = target
        else:
            v = float(st[1]) if st[0] == "heater" else 0.0
            dur = float(st[2] if st[0] == "heater" else st[1])
            for _ in range(max(1, int(round(dur / dt_s)))):
                t.append(now); turns.append(pos); volts.append(v); moving.append(0); seg.append(k)
                now += dt_s
    n = len(t)
    return {"t": np.array(t), "turns": np.array(turns), "heater_voltage": np.array(volts),
            "load_g": np.full(n, float(load_g)), "motor_moving": np.array(moving, np.uint8),
            "segment": np.array(seg, np.int32)}


def simulate_history(hist: dict[str, np.ndarray], preset: str | dict[str, Any] = "sim", seed: int = 0,
                     settle_s: float = 1200.0) -> dict[str, np.ndarray]:
    """Simulate ``hist`` on the preset's plant (noise seeded) after ``settle_s`` at the first input.

    ``preset``: a bench file name (configs/bench/<preset>.yaml) or a ``plant`` mapping itself.
    """
    plant = plant_from_config(preset_plant(preset) if isinstance(preset, str) else preset, seed=seed)
    if settle_s > 0:
        ts = np.arange(0.0, settle_s, 1.0)
        simulate(plant, ts, hist["turns"][0], hist["heater_voltage"][0], hist["load_g"][0],
                 np.zeros(len(ts), bool))
        t_shift = settle_s
    else:
        t_shift = 0.0
    out = simulate(plant, hist["t"] + t_shift, hist["turns"], hist["heater_voltage"], hist["load_g"],
                   hist["motor_moving"].astype(bool))
    out["t_s"] = hist["t"].copy()
    return out


def write_run(path: str | Path, hist: dict[str, np.ndarray], sim: dict[str, np.ndarray],
              description: str = "") -> Path:
    """A contract run file (docs/run-format.md) of one simulated history."""
    path = Path(path)
    n = len(hist["t"])
    cols = {
        "t": (hist["t"], "s"), "turns": (hist["turns"], "turn"), "length": (sim["length_mm"], "mm"),
        "resistance": (sim["resistance_ohm"], "ohm"), "heater_voltage": (hist["heater_voltage"], "V"),
        "load": (hist["load_g"] * NEWTON_PER_GRAM, "N"), "segment": (hist["segment"], "1"),
        "motor_moving": (hist["motor_moving"], "1"), "counter": (np.arange(n, dtype=np.uint32), "1"),
    }
    with h5py.File(path, "w") as f:
        f.attrs.update({"format": "tsa-bench/run", "format_version": "1.0",
                        "created": "2024-01-01T00:00:00+00:00", "backend": "sim-history", "firmware": "0.0.0",
                        "exit_status": "success", "reason": "all segments done",
                        "description": description})
        g = f.create_group("samples")
        for name, (a, unit) in cols.items():
            g.create_dataset(name, data=a).attrs["units"] = unit
        f.create_dataset("config/protocol", data=json.dumps({"generated_by": "tsa_bench.reproduce.runs",
                                                              "description": description}))
    return path
