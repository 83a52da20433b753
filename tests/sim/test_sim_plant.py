"""Plant physics: compliant TSA kinematics with radius growth, resistance, effects.

Most tests use the shipped plant with only the quasi-static effects on
(string_compliance, radius_growth, resistance_length); the dynamic effects have their
own tests in test_sim_effects_*.py."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from tsa_bench.bench import load_bench
from tsa_bench.sim import EFFECTS, SensorNoise, TsaGeometry, TsaPlant, contracted_length_mm, plant_from_config
from tsa_bench.sim.effects import Effect
from tsa_bench.sim.kinematics import NEWTON_PER_GRAM

QUASI_STATIC = ("string_compliance", "radius_growth", "resistance_length")


def only(*names: str, base=None) -> dict:
    """The shipped plant config with only ``names`` enabled."""
    cfg = dict(load_bench(None).plant if base is None else base)
    effects = {n: dict(v) for n, v in cfg.get("effects", {}).items()}
    for n in EFFECTS:
        effects.setdefault(n, {})["enabled"] = n in names
    cfg["effects"] = effects
    return cfg


@pytest.fixture
def plant() -> TsaPlant:
    """The shipped plant, quasi-static effects only (deterministic)."""
    return plant_from_config(only(*QUASI_STATIC))


def length(plant: TsaPlant, turns: float, load_g: float) -> float:
    plant.set_load(load_g)
    return plant.sample(0.0, turns, 0.0, False).length_mm


def test_length_falls_as_twist_rises(plant):
    lengths = [length(plant, t, 500) for t in range(0, 101)]
    assert all(b <= a for a, b in zip(lengths, lengths[1:]))
    full = plant.geometry.full_twist_turns(500)
    strict = [length(plant, t, 500) for t in range(0, int(full) + 1)]
    assert all(b < a for a, b in zip(strict, strict[1:]))


def test_compliance_longer_under_more_load(plant):
    for turns in (0, 20, 40, 55, 81):  # noqa: B007
        assert length(plant, turns, 550) > length(plant, turns, 450) > length(plant, turns, 0)
    # untwisted: exactly L0 (1 + F/K)
    g = plant.geometry
    assert length(plant, 0, 450) == pytest.approx(g.untwisted_length_mm * (1 + 450 * NEWTON_PER_GRAM / g.stiffness_N))


def test_thesis_scheme1_magnitudes():
    """Section 2.5.1: ~28 cm at 20 turns down to ~21 cm at 55 turns under 450-550 g (the Scheme 1
    preset; the default bench now plays the 2.5.2 actuator)."""
    scheme1 = load_bench(Path(__file__).resolve().parents[2] / "configs" / "bench" / "sim-scheme1.yaml").plant
    plant = plant_from_config(only(*QUASI_STATIC, base=scheme1))
    for load in (450, 550):
        assert 270 <= length(plant, 20, load) <= 290
        assert 195 <= length(plant, 55, load) <= 225
        assert (length(plant, 20, load) - length(plant, 55, load)) / length(plant, 20, load) > 0.2


def test_resistance_follows_length():
    """Without the contact term R is a monotonic function of length alone."""
    cfg = only(*QUASI_STATIC)
    cfg["effects"]["resistance_length"]["contact_ohm_per_turn"] = 0.0
    plant = plant_from_config(cfg)
    pairs = []
    for load in (450, 550):
        plant.set_load(load)
        pairs += [plant.sample(0.0, t, 0.0, False) for t in range(0, 82, 3)]
    pairs.sort(key=lambda r: r.length_mm)
    assert all(b.resistance_ohm >= a.resistance_ohm for a, b in zip(pairs, pairs[1:]))
    assert pairs[0].resistance_ohm < pairs[-1].resistance_ohm
    assert all(r.resistance_ohm > 0 for r in pairs)


@pytest.mark.parametrize("turns", [81, 100, -100, 1e4])
def test_over_twist_is_clamped_never_nan(plant, turns):
    plant.set_load(500)
    r = plant.sample(0.0, turns, 0.0, False)
    assert math.isfinite(r.length_mm) and math.isfinite(r.resistance_ohm)
    assert r.length_mm == pytest.approx(plant.geometry.stretched_length_mm(500) / math.sqrt(3))


def test_twist_direction_does_not_matter(plant):
    assert length(plant, -33.3, 500) == length(plant, 33.3, 500)


@given(stretched=st.floats(50, 1000), fraction=st.floats(0, 1))
def test_cubic_root_is_the_largest_physical_root(stretched, fraction):
    c_max = 2 * stretched ** 3 / (3 * math.sqrt(3))
    c = fraction * c_max
    x = contracted_length_mm(stretched, c)
    assert stretched / math.sqrt(3) - 1e-6 <= x <= stretched + 1e-9
    assert abs(x ** 3 - stretched ** 2 * x + c) <= 1e-6 * stretched ** 3


def test_geometry_matches_implicit_equation():
    g = TsaGeometry(248.0, 0.51, 31.88)
    turns, load = 30.0, 500.0
    x = g.length_mm(turns, load)
    r = g.radius_mm * math.sqrt(g.untwisted_length_mm / x)
    assert x == pytest.approx(math.sqrt(g.stretched_length_mm(load) ** 2 - (2 * math.pi * turns * r) ** 2))


def test_geometry_refuses_nonsense():
    with pytest.raises(ValueError, match="stiffness_N"):
        TsaGeometry(248.0, 0.5, 0.0)
    with pytest.raises(ValueError, match="load_g"):
        TsaPlant(248.0, 0.5, 5.0).set_load(-1)


def test_config_errors_name_the_key():
    with pytest.raises(ValueError, match="radius_m"):
        plant_from_config({"radius_m": 1})
    with pytest.raises(ValueError, match="stiffness_N"):
        plant_from_config({"effects": {"string_compliance": {"stiffness_N": "stiff"}}})
    with pytest.raises(ValueError, match="thermal_magic"):
        plant_from_config({"effects": {"thermal_magic": {}}})
    with pytest.raises(ValueError, match="lenght_noise_mm"):
        plant_from_config({"effects": {"sensor_noise": {"lenght_noise_mm": 1}}})
    with pytest.raises(ValueError, match="lenght_noise_mm"):  # even when switched off
        plant_from_config({"effects": {"sensor_noise": {"enabled": False, "lenght_noise_mm": 1}}})
    with pytest.raises(ValueError, match="enabled"):
        plant_from_config({"effects": {"sensor_noise": {"enabled": "yes"}}})
    with pytest.raises(ValueError, match="mapping"):
        plant_from_config({"effects": [{"name": "sensor_noise"}]})


def test_noise_is_seeded_and_zero_mean():
    cfg = only(*QUASI_STATIC, "sensor_noise")
    a, b, c = plant_from_config(cfg, seed=7), plant_from_config(cfg, seed=7), plant_from_config(cfg, seed=8)
    assert any(isinstance(e, SensorNoise) for e in a.effects)
    ra = [a.sample(i * 0.1, 20.0, 0.0, False) for i in range(2000)]
    rb = [b.sample(i * 0.1, 20.0, 0.0, False) for i in range(2000)]
    rc = [c.sample(i * 0.1, 20.0, 0.0, False) for i in range(2000)]
    assert ra == rb and ra != rc
    clean = a.quasi_static(20.0)
    mean = sum(r.length_mm for r in ra) / len(ra)
    assert mean == pytest.approx(clean.length_mm, abs=0.01)
    sd = math.sqrt(sum((r.length_mm - mean) ** 2 for r in ra) / len(ra))
    assert sd == pytest.approx(0.05, rel=0.15)


def test_effects_run_in_canonical_order_with_inputs():
    seen = []

    class Late(Effect):
        name, stage = "test_late", "resistance"

        def apply(self, state):
            seen.append(("late", state.t_s, state.turns_cmd, state.heater_voltage_V, state.motor_moving,
                         state.load_g))
            state.resistance_ohm += 1.0

    class Early(Effect):
        name, stage = "test_early", "geometry"

        def apply(self, state):
            seen.append(("early",))
            state.string_length_mm += 1.0

    base = TsaPlant(248.0, 0.51, 5.0, load_g=300)
    EFFECTS["test_late"], EFFECTS["test_early"] = Late, Early  # temporarily registered
    try:
        p = TsaPlant(248.0, 0.51, 5.0, load_g=300, effects=[Late(), Early()])
    finally:
        del EFFECTS["test_late"], EFFECTS["test_early"]
    r = p.sample(1.5, 10.0, 6.0, True)
    b = base.sample(1.5, 10.0, 6.0, True)
    assert [e.name for e in p.effects] == ["test_early", "test_late"]
    assert seen == [("early",), ("late", 1.5, 10.0, 6.0, True, 300.0)]
    assert r.length_mm == pytest.approx(math.sqrt(249.0 ** 2 - (2 * math.pi * 10 * 0.51) ** 2))
    assert b.length_mm == pytest.approx(math.sqrt(248.0 ** 2 - (2 * math.pi * 10 * 0.51) ** 2))
    assert r.resistance_ohm == pytest.approx(6.0)


def test_sample_is_fast(plant):
    n = 20000
    t0 = time.perf_counter()
    for i in range(n):
        plant.sample(i * 0.1, 40.0, 0.0, False)
    assert (time.perf_counter() - t0) / n < 20e-6
