"""Hidden-effect data generator for the diagnose tests (the project's own plant).

Builds one rich diagnostic protocol (twist staircases up and down with 60-120 s holds,
fast cycles, load changes, heater steps) as a 10 Hz input history, simulates it with a
"truth" plant = the thesis-level baseline (configs/bench/sim-baseline.yaml) plus one or
two drawn effects with parameters drawn in physical ranges (seeded), sensor noise on,
and writes a contract run file (docs/run-format.md) with plain h5py. The protocol is
the same whatever effect is drawn, so nothing in the file reveals it.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from tests.analysis.runfiles import write_contract_run
from tsa_bench.analysis import load_model
from tsa_bench.analysis.modelspec import switch
from tsa_bench.sim.history import simulate

G0 = 9.80665
DT = 0.1
#: Effects the generator can hide (resistance_temperature only shows with thermal_dynamics).
HIDEABLE = ("resistance_transient_decay", "resistance_creep", "length_creep", "load_dependence",
            "twist_hysteresis", "thermal_dynamics", "missed_steps", "resistance_hysteresis")


def protocol_steps(short: bool = False) -> list[tuple]:
    """Steps: ("move", turns, rate) | ("hold", s) | ("load", g) | ("heater", V, s); cycles tagged."""
    h = 0.5 if short else 1.0
    nc = 5 if short else 10
    s: list[tuple] = [("hold", 20)]

    def stairs(targets, hold, rate=3.0):
        for x in targets:
            s.append(("move", x, rate))
            s.append(("hold", hold * h))

    def cycles(lo, hi, n):
        for _ in range(n):
            s.append(("move", hi, 5.0, "cycle"))
            s.append(("hold", 0.5, "cycle"))
            s.append(("move", lo, 5.0, "cycle"))
            s.append(("hold", 0.5, "cycle"))

    # --- first ~70 %: training part by default
    stairs([10, 20, 30, 40], 60)
    stairs([30, 20, 10], 60)
    cycles(10, 35, nc)
    s.append(("hold", 90 * h))
    s.append(("load", 300))
    s.append(("hold", 90 * h))
    stairs([25, 40, 25, 10], 60)
    stairs([20], 30)
    s.append(("heater", 6.0, 20))
    s.append(("hold", 120 * h))
    s.append(("heater", 8.0, 15))
    s.append(("hold", 120 * h))
    s.append(("load", 500))
    s.append(("hold", 60 * h))
    cycles(10, 35, nc)
    stairs([10], 60)
    # --- last ~30 %: held out by default
    stairs([20, 30, 40], 60)
    stairs([25, 10], 60)
    cycles(10, 35, nc)
    stairs([20], 60)
    s.append(("heater", 7.0, 20))
    s.append(("hold", 120 * h))
    s.append(("load", 300))
    s.append(("hold", 90 * h))
    stairs([35, 15], 60)
    return s


def history(steps: list[tuple], load0_g: float = 500.0) -> dict:
    """10 Hz input history + segment table of the steps."""
    t, turns, volts, loads, moving, seg = [], [], [], [], [], []
    segments = []
    now, pos, load, cyc_count = 0.0, 0.0, load0_g, -1
    for k, step in enumerate(steps):
        kind = step[0]
        is_cycle = len(step) > 2 and step[-1] == "cycle"
        if is_cycle and kind == "move" and step[1] > pos:
            cyc_count += 1
        t0 = now
        if kind == "move":
            target, rate = float(step[1]), float(step[2])
            n = max(1, int(math.ceil(abs(target - pos) / rate / DT)))
            path = pos + (target - pos) * np.arange(1, n + 1) / n
            for x in path:
                t.append(now); turns.append(x); volts.append(0.0); loads.append(load); moving.append(1); seg.append(k)
                now += DT
            pos = target
            kname = "move"
        elif kind == "load":
            load = float(step[1])
            kname = "prompt"
        else:
            v = float(step[1]) if kind == "heater" else 0.0
            dur = float(step[2] if kind == "heater" else step[1])
            for _ in range(max(1, int(round(dur / DT)))):
                t.append(now); turns.append(pos); volts.append(v); loads.append(load); moving.append(0); seg.append(k)
                now += DT
            kname = "heater" if kind == "heater" else "hold"
        segments.append((k, kname, t0, now, 1, cyc_count if is_cycle else -1, f"hidden.py:{k}",
                         json.dumps({"step": list(map(str, step))})))
    return {"t": np.array(t), "turns": np.array(turns), "heater_voltage": np.array(volts),
            "load_g": np.array(loads), "motor_moving": np.array(moving, np.uint8), "segment": np.array(seg, np.int32),
            "segments": segments}


def draw_params(name: str, rng: np.random.Generator, hist: dict, base_cfg: dict) -> dict:
    """Parameters of a hidden effect drawn in physical ranges."""
    u = lambda a, b: float(rng.uniform(a, b))  # noqa: E731
    if name == "resistance_transient_decay":
        return {"b1_ohm": -1.71e-3 * u(0.5, 2), "b2_ohm": -2.68e-2 * u(0.5, 2)}
    if name == "resistance_creep":
        return {"ohm_per_turn": 1e-5 * u(0.7, 3)}
    if name == "length_creep":
        return {"strain_per_N": 1e-3 * u(0.5, 2), "time_constant_s": 180 * u(0.5, 2)}
    if name == "load_dependence":
        return {"stiffness_softening": u(0.15, 0.6)}
    if name == "twist_hysteresis":
        return {"play_turns": u(0.15, 0.6)}
    if name == "thermal_dynamics":
        return {"thermal_resistance_K_per_W": 5 * u(0.7, 1.4), "heat_capacity_J_per_K": 0.3 * u(0.5, 2),
                "cooling_time_constant_s": 30 * u(0.5, 2)}
    if name == "resistance_temperature":
        return {"alpha_per_K": 5e-4 * u(0.6, 3)}
    if name == "resistance_hysteresis":
        return {"ohm_per_mm": 0.015 * u(0.7, 2), "alpha_mm": u(0.6, 2)}
    if name == "missed_steps":
        # weak holding torque: the stepper slips near the top of the staircases
        from tsa_bench.sim.kinematics import NEWTON_PER_GRAM
        L0, r0 = base_cfg["untwisted_length_mm"], base_cfg["radius_mm"]
        k = base_cfg["effects"]["string_compliance"]["stiffness_N"]
        from tsa_bench.sim.effects.mechanics import tsa_length_mm
        tau = []
        for th, m in zip(hist["turns"][::10], hist["load_g"][::10]):
            f = m * NEWTON_PER_GRAM
            big_l = L0 * (1 + f / k)
            x = tsa_length_mm(big_l, th, r0, L0, True)
            tau.append(f * 2 * math.pi * abs(th) * r0 * r0 * L0 / x / x * 1e-3)
        return {"holding_torque_Nm": float(np.max(tau)) * u(0.6, 0.85)}
    raise KeyError(name)


def truth_config(effects: tuple[str, ...], seed: int, hist: dict) -> tuple[dict, dict]:
    base = load_model(None)
    rng = np.random.default_rng(10_000 + seed)
    cfg, drawn = base, {}
    for name in effects:
        p = draw_params(name, rng, hist, base)
        drawn[name] = p
        cfg = switch(cfg, name, True, p)
    return cfg, drawn


def write_run(path: Path, hist: dict, length: np.ndarray, resistance: np.ndarray, bench_text: str = "") -> Path:
    """A contract run file (docs/run-format.md) written with plain h5py."""
    n = len(hist["t"])
    cols = {
        "t": (hist["t"], "s"), "turns": (hist["turns"], "turn"), "length": (length, "mm"),
        "resistance": (resistance, "ohm"), "heater_voltage": (hist["heater_voltage"], "V"),
        "load": (hist["load_g"] * G0 / 1000.0, "N"), "segment": (hist["segment"], "1"),
        "motor_moving": (hist["motor_moving"], "1"), "counter": (np.arange(n, dtype=np.uint32), "1"),
    }
    return write_contract_run(path, cols, hist["segments"], {
        "created": "2024-01-01T00:00:00+00:00", "backend": "import", "firmware": "0.0.0", "exit_status": "success",
        "reason": "all segments done"}, {"config/bench": bench_text})


def generate(path: Path, effects: tuple[str, ...] = (), seed: int = 0, short: bool = False,
             noise_seed: int | None = None) -> dict:
    """Simulate the protocol on baseline + ``effects`` (drawn params, noise on); write ``path``.

    ``seed`` draws the actuator (the hidden effects' parameters); ``noise_seed``
    (default ``seed + 1``) the sensor noise, so two runs of one actuator share ``seed``.
    Returns ``{"path", "drawn", "n"}``.
    """
    hist = history(protocol_steps(short))
    cfg, drawn = truth_config(tuple(effects), seed, hist)
    out = simulate(cfg, hist["t"], hist["turns"], hist["heater_voltage"], hist["load_g"],
                   hist["motor_moving"].astype(bool), seed=seed + 1 if noise_seed is None else noise_seed)
    res = out["resistance_ohm"].copy()
    res[hist["heater_voltage"] > 0] = np.nan          # not measured while heating
    write_run(path, hist, out["length_mm"], res)
    return {"path": path, "drawn": drawn, "n": len(hist["t"])}
