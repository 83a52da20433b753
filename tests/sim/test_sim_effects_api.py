"""The effect library: registry, documentation, config handling, order, seeds, simulate()."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tsa_bench.bench import load_bench
from tsa_bench.sim import EFFECTS, simulate
from tsa_bench.sim.effects import STAGES, canonical_order, describe_effects, register_effect
from tsa_bench.sim.plant import plant_from_config

BENCH_DIR = Path(__file__).resolve().parents[2] / "configs" / "bench"
REQUIRED = {"string_compliance", "radius_growth", "twist_hysteresis", "thermal_dynamics", "thermal_contraction",
            "resistance_length", "resistance_hysteresis", "resistance_transient_decay", "resistance_creep",
            "length_creep", "resistance_temperature", "load_dependence", "missed_steps", "sensor_noise",
            "quantisation"}


def test_every_required_effect_is_registered_and_documented():
    assert REQUIRED <= set(EFFECTS)
    described = describe_effects()
    assert [d["name"] for d in described] == canonical_order()
    stages = [STAGES.index(d["stage"]) for d in described]
    assert stages == sorted(stages)
    for d in described:
        assert d["doc"] and d["source"], d["name"]
        cls = EFFECTS[d["name"]]
        assert "Source" in cls.__doc__ or "source" in cls.__doc__.lower(), d["name"]
        for p in d["params"]:
            assert p["units"] and p["doc"], (d["name"], p["name"])


def _calibrated_sim_parameters() -> set[tuple[str, str]]:
    """(effect, parameter) of sim.yaml that configs/thesis/calibration.yaml fits (declared, not drifted)."""
    from tsa_bench.reproduce.plan import load_plan
    from tsa_bench.reproduce.records import load_records

    paths = load_plan(load_records()).fitted_parameters().get("sim", [])
    return {tuple(p.split(".")[1:]) for p in paths if p.startswith("effects.")}


def test_shipped_sim_yaml_lists_every_effect_with_its_defaults():
    """Every effect on, every parameter at its documented default, except the parameters the
    calibration plan fits for sim.yaml (configs/thesis/calibration.yaml), which must differ only there."""
    effects = load_bench(None).plant["effects"]
    calibrated = _calibrated_sim_parameters()
    assert set(effects) == set(EFFECTS)
    for name, cfg in effects.items():
        assert cfg["enabled"] is True, name
        params = {f.name: f.default for f in dataclasses.fields(EFFECTS[name].Params)}
        assert set(cfg) - {"enabled"} == set(params), name
        for key, default in params.items():
            if (name, key) not in calibrated:
                assert cfg[key] == pytest.approx(default), (name, key)
    text = (BENCH_DIR / "sim.yaml").read_text()
    for name, cfg in effects.items():  # every parameter line carries a unit comment
        for key in set(cfg) - {"enabled"}:
            line = next(ln for ln in text.splitlines() if ln.strip().startswith(f"{key}:")
                        and text.index(ln) > text.index(f"{name}:"))
            assert "#" in line, (name, key)


def test_defaults_when_omitted_equal_the_shipped_file():
    """Omitted effects and parameters behave as sim.yaml's, once its calibrated parameters are reset."""
    t = np.arange(0, 60, 0.1)
    turns = np.clip(t * 2, 0, 40)
    a = simulate({}, t, turns, 0.0, 500.0, seed=3)
    shipped = {n: dict(c) for n, c in load_bench(None).plant["effects"].items()}
    for name, key in _calibrated_sim_parameters():
        shipped[name][key] = getattr(EFFECTS[name].Params(), key)
    b = simulate({"effects": shipped}, t, turns, 0.0, 500.0, seed=3)
    assert np.array_equal(a["length_mm"], b["length_mm"]) and np.array_equal(a["resistance_ohm"], b["resistance_ohm"])


def test_unknown_effect_or_parameter_names_them():
    with pytest.raises(ValueError, match="warp_drive"):
        plant_from_config({"effects": {"warp_drive": {"enabled": True}}})
    with pytest.raises(ValueError, match="b3_ohm"):
        plant_from_config({"effects": {"resistance_transient_decay": {"b3_ohm": 1.0}}})
    with pytest.raises(ValueError, match="stiffness_N"):
        plant_from_config({"stiffness_N": 31.88})  # moved into string_compliance
    with pytest.raises(ValueError, match="must be >= 0"):
        plant_from_config({"effects": {"sensor_noise": {"length_noise_mm": -1}}})


def test_config_order_does_not_matter():
    shipped = load_bench(None).plant
    reordered = dict(shipped)
    reordered["effects"] = dict(reversed(list(shipped["effects"].items())))
    p, q = plant_from_config(shipped), plant_from_config(reordered)
    assert [e.name for e in p.effects] == [e.name for e in q.effects] == canonical_order()
    t = np.arange(0, 30, 0.1)
    turns = np.clip(t * 3, 0, 50)
    a, b = simulate(p, t, turns, 0.0, 450.0), simulate(q, t, turns, 0.0, 450.0)
    assert np.array_equal(a["resistance_ohm"], b["resistance_ohm"])


def test_seeds_reproducible_and_noise_switchable():
    t = np.arange(0, 20, 0.1)
    turns = np.full(len(t), 20.0)
    cfg = load_bench(None).plant
    a, b, c = (simulate(cfg, t, turns, 0.0, 500.0, seed=s) for s in (5, 5, 6))
    assert np.array_equal(a["length_mm"], b["length_mm"]) and not np.array_equal(a["length_mm"], c["length_mm"])
    quiet = dict(cfg)
    quiet["effects"] = {**cfg["effects"], "sensor_noise": {"enabled": False}}
    d, e = (simulate(quiet, t, turns, 0.0, 500.0, seed=s) for s in (5, 6))
    assert np.array_equal(d["length_mm"], e["length_mm"])


def test_simulate_outputs_and_moving_default():
    t = np.arange(0, 10, 0.1)
    turns = np.clip(t * 5, 0, 20)
    out = simulate(load_bench(None).plant, t, turns, np.zeros(len(t)), np.full(len(t), 500.0), seed=0)
    for key in ("length_mm", "resistance_ohm", "temperature_C", "turns_actual"):
        assert out[key].shape == t.shape and np.all(np.isfinite(out[key])), key
    assert np.array_equal(out["turns_actual"], turns)


def test_register_effect_refuses_duplicates_and_bad_stages():
    cls = EFFECTS["sensor_noise"]
    with pytest.raises(ValueError, match="already registered"):
        register_effect(cls)

    class Bad(cls):
        name, stage = "bad_stage_effect", "kinematics"

    with pytest.raises(ValueError, match="stage"):
        register_effect(Bad)
    assert "bad_stage_effect" not in EFFECTS


@pytest.mark.parametrize("name", ["sim.yaml", "sim-scheme1.yaml", "sim-scheme2-4ply.yaml", "sim-3ply.yaml",
                                  "sim-4ply.yaml"])
def test_presets_load_and_share_the_rig(name):
    bench = load_bench(BENCH_DIR / name)
    shipped = load_bench(None)
    assert bench.backend == "sim" and bench.limits == shipped.limits and bench.position == shipped.position
    plant = plant_from_config(bench.plant)
    assert {e.name for e in plant.effects} == set(EFFECTS)  # presets keep every effect on
