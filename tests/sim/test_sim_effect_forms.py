"""Alternative forms of plant effects: off unless named, each doing what its doc says."""

from __future__ import annotations

import numpy as np
import pytest

from tsa_bench.bench import load_bench
from tsa_bench.sim import EFFECTS, simulate
from tsa_bench.sim.effects import FORMS, canonical_order, describe_forms
from tsa_bench.sim.plant import plant_from_config


def base(**forms) -> dict:
    """The shipped plant with only the quasi-static effects on, plus ``forms``."""
    plant = dict(load_bench(None).plant)
    effects = {n: {"enabled": n in ("string_compliance", "radius_growth", "resistance_length")} for n in EFFECTS}
    effects.update(forms)
    plant["effects"] = effects
    return plant


def ramp(hold_s: float = 60.0, top: float = 50.0, rate: float = 5.0, dt: float = 0.1):
    up = np.arange(0.0, top, rate * dt)
    turns = np.r_[up, np.full(int(hold_s / dt), top), up[::-1], np.zeros(int(hold_s / dt))]
    t = np.arange(len(turns)) * dt
    moving = np.r_[False, np.diff(turns) != 0]
    return t, turns, moving


def test_forms_are_registered_documented_and_off_by_default():
    assert set(FORMS) == {"missed_steps_pullout", "missed_steps_saturating", "length_creep_twist",
                          "resistance_transient_stretched", "resistance_transient_two_exp", "resistance_creep_time"}
    for d in describe_forms():
        assert d["form_of"] in EFFECTS and d["form"] and d["source"] and d["doc"]
        assert all(p["units"] and p["doc"] for p in d["params"])
    names = {e.name for e in plant_from_config(load_bench(None).plant).effects}
    assert names == set(EFFECTS)          # the shipped bench runs no form
    assert canonical_order(["missed_steps_pullout", "missed_steps"]) == ["missed_steps", "missed_steps_pullout"]


def test_unknown_form_key_is_refused_with_its_name():
    with pytest.raises(ValueError, match="bogus"):
        plant_from_config(base(missed_steps_pullout={"bogus": 1.0}))


def test_pullout_slips_more_when_fast():
    t, turns, moving = ramp(rate=1.0)
    slow = simulate(base(missed_steps_pullout={"pullout_torque_Nm": 0.004, "corner_speed_turns_per_s": 1.0}),
                    t, turns, 0.0, 500.0, moving)
    t2, turns2, moving2 = ramp(rate=5.0)
    fast = simulate(base(missed_steps_pullout={"pullout_torque_Nm": 0.004, "corner_speed_turns_per_s": 1.0}),
                    t2, turns2, 0.0, 500.0, moving2)
    lost_slow = 50.0 - slow["turns_actual"].max()
    lost_fast = 50.0 - fast["turns_actual"].max()
    assert 0 <= lost_slow < lost_fast and lost_fast > 1.0
    # twist lost stays lost: back at 0 commanded turns the motor sits below zero
    assert fast["turns_actual"][-1] == pytest.approx(-lost_fast, abs=1e-6)


def test_saturating_keeps_a_fraction_above_the_threshold():
    t, turns, moving = ramp()
    out = simulate(base(missed_steps_saturating={"threshold_turns": 30.0, "slip_fraction": 0.4}),
                   t, turns, 0.0, 500.0, moving)
    assert out["turns_actual"].max() == pytest.approx(30.0 + 0.6 * 20.0, abs=1e-6)


def test_twist_creep_keeps_moving_during_a_hold():
    t, turns, moving = ramp(hold_s=120.0)
    on = simulate(base(length_creep_twist={"creep_fraction": 0.2, "time_constant_s": 20.0}), t, turns, 0.0, 500.0,
                  moving, seed=0)
    off = simulate(base(), t, turns, 0.0, 500.0, moving, seed=0)
    hold = (turns == 50.0)
    first, last = np.flatnonzero(hold)[[0, -1]]
    lag0 = abs(on["length_mm"][first] - off["length_mm"][first])
    assert lag0 > 1.0                                                            # lags at the stop
    assert abs(on["length_mm"][last] - off["length_mm"][last]) < 0.01 * lag0    # caught up after 6 tau


@pytest.mark.parametrize("form,params,law", [
    ("resistance_transient_stretched", {"amp_ohm": 0.02, "time_constant_s": 10.0, "beta": 0.5},
     lambda s: 0.02 * np.exp(-np.sqrt(s / 10.0))),
    ("resistance_transient_two_exp", {"a1_ohm": 0.01, "tau1_s": 2.0, "a2_ohm": 0.005, "tau2_s": 40.0},
     lambda s: 0.01 * np.exp(-s / 2.0) + 0.005 * np.exp(-s / 40.0)),
])
def test_transient_forms_follow_their_law_after_each_stop(form, params, law):
    t, turns, moving = ramp()
    on = simulate(base(**{form: params}), t, turns, 0.0, 500.0, moving, seed=0)
    off = simulate(base(), t, turns, 0.0, 500.0, moving, seed=0)
    d = on["resistance_ohm"] - off["resistance_ohm"]
    assert np.all(d[moving] == 0.0)
    stop = np.flatnonzero(moving[:-1] & ~moving[1:])[0] + 1
    since = t[stop:stop + 300] - t[stop]
    assert np.allclose(d[stop:stop + 300], law(since), atol=1e-9)


def test_time_creep_grows_with_time_not_travel():
    t = np.arange(0.0, 3600.0, 1.0)
    still = simulate(base(resistance_creep_time={"ohm_per_hour": 0.02, "time_constant_s": 1e6}), t, 10.0, 0.0,
                     500.0, np.zeros(len(t), bool), seed=0)
    ref = simulate(base(), t, 10.0, 0.0, 500.0, np.zeros(len(t), bool), seed=0)
    rise = still["resistance_ohm"][-1] - ref["resistance_ohm"][-1]
    assert rise == pytest.approx(0.02 / 3600 * 1e6 * (1 - np.exp(-3599 / 1e6)), rel=1e-6)
