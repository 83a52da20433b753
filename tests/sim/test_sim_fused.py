"""The fused plant kernel equals the per-effect chain bit for bit, for every effect and form."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from tsa_bench.sim import fused
from tsa_bench.sim.effects import EFFECTS, FORMS, Effect
from tsa_bench.sim.plant import TsaPlant, plant_from_config

ROOT = Path(__file__).resolve().parents[2]
SIM_BENCHES = sorted(p for p in (ROOT / "configs" / "bench").glob("*.yaml")
                     if yaml.safe_load(p.read_text()).get("backend") == "sim")


def script(n_cycles: int = 6) -> list[tuple]:
    """Moves, holds, heater steps, load changes, an irregular clock, a repeated time and one
    that goes back: ``("load", g)`` or ``("sample", t, turns, volts, moving)``."""
    out: list[tuple] = [("load", 300.0)]
    t, turns = 0.0, 0.0
    rng = np.random.default_rng(7)
    for cycle in range(n_cycles):
        target = (12.0, 40.0, -3.0, 60.0, 25.0, 5.0)[cycle % 6]
        volts = (0.0, 6.0, 0.0, 9.0, 0.0, 3.0)[cycle % 6]
        while turns != target:                       # a move at 4 turns/s
            step = min(0.4, abs(target - turns))
            turns = turns + step if target > turns else turns - step
            t += 0.1
            out.append(("sample", t, turns, 0.0, True))
        for k in range(60 + 30 * (cycle % 2)):       # a hold, the heater on for part of it
            t += 0.1 if k % 7 else 0.1 + float(rng.uniform(0.0, 0.05))
            out.append(("sample", t, turns, volts if 10 < k < 40 else 0.0, False))
        out.append(("sample", t, turns, 0.0, False))          # the same time again
        out.append(("sample", t - 0.05, turns, 0.0, False))   # a time that goes back: dt 0
        if cycle == 2:
            out.append(("load", 550.0))
        if cycle == 4:
            out.append(("load", 0.0))
    return out


def every_effect_on(**overrides: dict) -> dict:
    """The shipped plant with every effect and form on at non-trivial parameters."""
    plant = yaml.safe_load((ROOT / "configs" / "bench" / "sim.yaml").read_text())["plant"]
    effects = {name: dict(cfg or {}) for name, cfg in plant["effects"].items()}
    effects.update({
        "twist_stiffening": {"enabled": True, "per_turn": 0.01},
        "thermal_softening": {"enabled": True, "per_K": 0.004},
        "thermal_actuation": {"enabled": True, "strain_per_K": 0.002, "hysteresis_K": 3.0},
        "length_settling": {"enabled": True, "hold_sd_mm": 0.05, "run_sd_mm": 0.2},
        "missed_steps_pullout": {"pullout_torque_Nm": 0.02, "corner_speed_turns_per_s": 1.0},
        "missed_steps_saturating": {"threshold_turns": 30.0, "slip_fraction": 0.2},
        "length_creep_twist": {"creep_fraction": 0.1},
        "resistance_transient_stretched": {}, "resistance_transient_two_exp": {}, "resistance_creep_time": {},
        "length_offset_drift": {"enabled": True, "mm_per_hour": 0.7},
        "length_gain_drift": {"enabled": True, "per_hour": -0.004},
        "resistance_offset_drift": {"enabled": True, "ohm_per_hour": 0.03},
        "resistance_gain_drift": {"enabled": True, "per_hour": 0.002},
    })
    for name, cfg in overrides.items():
        effects[name] = {**effects.get(name, {}), **cfg}
    plant["effects"] = effects
    return plant


CASES = {p.stem: yaml.safe_load(p.read_text())["plant"] for p in SIM_BENCHES}
CASES["every effect and form"] = every_effect_on()
CASES["slipping motor, many operators"] = every_effect_on(
    missed_steps={"holding_torque_Nm": 0.003}, resistance_hysteresis={"operators": 40},
    sensor_noise={"resistance_noise_ohm": 0.0}, quantisation={"length_resolution_mm": 0.0})
CASES["no growth, no noise, settling without hold draws"] = every_effect_on(
    radius_growth={"enabled": False}, sensor_noise={"enabled": False},
    length_settling={"hold_sd_mm": 0.0}, resistance_settling={"hold_sd_ohm": 0.0},
    missed_steps={"holding_torque_Nm": 0.0005}, missed_steps_pullout={"pullout_torque_Nm": 0.001})
CASES["bare kinematics"] = {"effects": {name: False for name in EFFECTS}}


def memory(plant: TsaPlant) -> list:
    """The plant's state, its own bookkeeping and every effect's memory (rngs by their state)."""
    out: list = [dataclasses.asdict(plant.state), plant._t_prev, plant._moving_prev, plant.load_g]
    for e in plant.effects:
        out.append({k: (v.getstate() if k == "rng" else v) for k, v in vars(e).items()
                    if not callable(v) or k == "rng"})
    return out


def drive(plant: TsaPlant, steps: list[tuple], interrupt: bool = False) -> list:
    got = []
    for i, step in enumerate(steps):
        if step[0] == "load":
            plant.set_load(step[1])
            continue
        got.append(tuple(plant.sample(*step[1:])))
        if interrupt and i % 97 == 0:   # the kernel stops and restarts around these
            got.append(tuple(plant.peek(step[2] + 1.0)))
            got.append(plant.state.temperature_C)
            if i % 3 == 0:
                plant = copy.deepcopy(plant)
        if interrupt and i == 1500:
            plant.reset()
    return got + [memory(plant)]


@pytest.mark.parametrize("name", sorted(CASES))
def test_fused_kernel_is_bit_identical_to_the_effect_chain(name):
    cfg = CASES[name]
    steps = script()
    fast = plant_from_config(cfg, seed=3)
    assert fused.fuse(fast) is not None          # the kernel runs (no fallback)
    fast._warmup = 0                             # ... from the first sample on
    ref = drive(plant_from_config(cfg, seed=3, fused=False), steps)
    assert drive(fast, steps) == ref
    assert drive(plant_from_config(cfg, seed=3), steps, interrupt=True) == \
        drive(plant_from_config(cfg, seed=3, fused=False), steps, interrupt=True)


def test_the_cases_exercise_every_effect_form_and_branch():
    on = {e.name for e in plant_from_config(CASES["every effect and form"], seed=0).effects}
    assert on == set(EFFECTS) | set(FORMS)
    assert {"sim", "sim-3ply", "sim-4ply", "sim-baseline", "sim-scheme1", "sim-scheme2-4ply"} <= set(CASES)
    for case in ("slipping motor, many operators", "no growth, no noise, settling without hold draws"):
        plant = plant_from_config(CASES[case], seed=3)
        drive(plant, script())
        lost = {e.name: e.lost_turns for e in plant.effects if hasattr(e, "lost_turns")}
        assert all(v != 0.0 for v in lost.values()) and len(lost) == 3   # every motor form slipped


def test_sample_block_equals_repeated_samples():
    cfg = CASES["every effect and form"]
    steps = [s for s in script(3) if s[0] == "sample"]
    t, turns, volts, moving = (np.array([s[k] for s in steps]) for k in (1, 2, 3, 4))
    one = plant_from_config(cfg, seed=5)
    one.set_load(450.0)
    rows = [(tuple(one.sample(*s[1:])), one.state.temperature_C, one.state.turns) for s in steps]
    for fused_on in (True, False):
        blk = plant_from_config(cfg, seed=5, fused=fused_on)
        blk.set_load(450.0)
        half = len(t) // 2
        a = blk.sample_block(t[:half], turns[:half], volts[:half], moving[:half], state=True)
        b = blk.sample_block(t[half:], turns[half:], volts[half:], moving[half:], state=True)
        got = {k: np.concatenate([a[k], b[k]]) for k in a}
        assert got["length_mm"].tolist() == [r[0][0] for r in rows]
        assert got["resistance_ohm"].tolist() == [r[0][1] for r in rows]
        assert got["temperature_C"].tolist() == [r[1] for r in rows]
        assert got["turns_actual"].tolist() == [r[2] for r in rows]
    scalar = plant_from_config(cfg, seed=5).sample_block(np.arange(5) * 0.1, 10.0, 0.0, False)
    assert scalar["length_mm"].shape == (5,) and "temperature_C" not in scalar


def test_a_plant_with_a_custom_effect_runs_the_chain():
    class Shift(Effect):
        name = "test_shift"
        stage = "length"

        def apply(self, state):
            state.length_mm += 1.0

    plain = plant_from_config(CASES["bare kinematics"], seed=0)
    EFFECTS["test_shift"] = Shift  # temporarily registered
    try:
        custom = TsaPlant(effects=[Shift()])
    finally:
        del EFFECTS["test_shift"]
    assert [e.name for e in custom.effects] == ["test_shift"]
    assert fused.fuse(custom) is None and custom._start(block=True) is None
    assert custom.sample(0.0, 10.0, 0.0, False).length_mm == plain.sample(0.0, 10.0, 0.0, False).length_mm + 1.0
