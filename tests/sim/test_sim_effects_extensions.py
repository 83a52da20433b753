"""The plant extensions the calibration added: off unless switched on, and each doing what its docstring says."""

from __future__ import annotations

import numpy as np
import pytest

from tsa_bench.sim import simulate
from tsa_bench.sim.effects import EFFECTS
from tsa_bench.sim.plant import plant_from_config

NEW = ("twist_stiffening", "thermal_actuation", "length_settling", "resistance_settling")
QUIET = {"sensor_noise": {"enabled": False}, "quantisation": {"enabled": False}}


def _cfg(**effects) -> dict:
    return {"untwisted_length_mm": 230.0, "radius_mm": 0.35, "effects": {**QUIET, **effects}}


def test_new_effects_are_off_unless_a_bench_file_switches_them_on():
    plant = plant_from_config({})
    names = {e.name for e in plant.effects}
    for name in NEW:
        assert not EFFECTS[name].default_enabled and name not in names
    on = plant_from_config({"effects": {n: {"enabled": True} for n in NEW}})
    assert set(NEW) <= {e.name for e in on.effects}


def _settled(cfg: dict, turns: float, load_g: float) -> float:
    t = np.arange(0, 40, 0.1)
    tw = np.minimum(t * 5, turns)
    return float(simulate(cfg, t, tw, 0.0, load_g, seed=1)["length_mm"][-1])


def test_twist_stiffening_recovers_stretch_in_proportion_to_the_load():
    base = {"string_compliance": {"stiffness_N": 4.0}, "length_creep": {"enabled": False}}
    stiff = {**base, "twist_stiffening": {"enabled": True, "per_turn": 0.002}}
    gains = []
    for load in (100.0, 200.0):
        plain = _settled(_cfg(**base), 30.0, load) - _settled(_cfg(**base), 0.0, load)
        with_k = _settled(_cfg(**stiff), 30.0, load) - _settled(_cfg(**stiff), 0.0, load)
        assert with_k < plain  # the twisted strings stretch less: more contraction
        gains.append(plain - with_k)
    assert gains[1] > 1.6 * gains[0]  # about proportional to the load (the stretch it recovers)
    assert _settled(_cfg(**stiff), 0.0, 150.0) == pytest.approx(_settled(_cfg(**base), 0.0, 150.0))


def _heat_cycle(cfg: dict, turns: float = 40.0) -> tuple[np.ndarray, np.ndarray]:
    """Length at the end of each 1 V step up to 8 V and back down (twisted ``turns``)."""
    volts = list(range(0, 9)) + list(range(7, -1, -1))
    t = np.arange(0, 60 * len(volts) + 20, 0.5)
    v = np.zeros(len(t))
    for i, vv in enumerate(volts):
        v[(t >= 20 + 60 * i) & (t < 20 + 60 * (i + 1))] = vv
    out = simulate(cfg, t, np.minimum(t * 5, turns), v, 200.0, seed=0)
    ends = [np.flatnonzero(t < 20 + 60 * (i + 1))[-1] for i in range(len(volts))]
    return np.array(volts), out["length_mm"][ends]


def test_thermal_actuation_saturates_and_lags_both_ways():
    thermal = {"thermal_contraction": {"strain_per_K": 0.0}, "length_creep": {"enabled": False},
               "thermal_dynamics": {"cooling_time_constant_s": 1.0}}  # settles within each step
    smooth = _cfg(**thermal, thermal_actuation={"enabled": True, "strain_per_K": 0.004, "max_strain": 0.1})
    hyst = _cfg(**thermal, thermal_actuation={"enabled": True, "strain_per_K": 0.004, "max_strain": 0.1,
                                              "hysteresis_K": 10.0})
    _, x0 = _heat_cycle(smooth, turns=0.0)  # untwisted: the TSA length is the string length
    assert 0.09 < (x0[0] - x0[8]) / x0[0] < 0.1 + 1e-9  # saturates below max_strain
    v, x = _heat_cycle(smooth)
    up, down = x[:9], x[8:][::-1]
    assert np.allclose(up, down, atol=0.05)  # no hysteresis without hysteresis_K
    _, xh = _heat_cycle(hyst)
    gap = xh[8:][::-1][2:7] - xh[:9][2:7]  # cooling branch minus heating branch at the same voltage
    assert np.all(gap < -0.5)  # cooling stays more contracted: the contraction lags the temperature


def test_settling_offsets_hold_within_a_hold_and_change_at_stops():
    cfg = _cfg(length_settling={"enabled": True, "hold_sd_mm": 0.5},
               resistance_settling={"enabled": True, "hold_sd_ohm": 0.02, "run_sd_ohm": 0.05},
               resistance_transient_decay={"enabled": False}, length_creep={"enabled": False})
    quiet = _cfg(resistance_transient_decay={"enabled": False}, length_creep={"enabled": False})
    t = np.arange(0, 60, 0.1)
    tw = np.where(t < 20, 10.0, np.where(t < 20.5, 10.0 + (t - 20) * 4, np.where(t < 40, 12.0, 12.0)))
    tw[(t >= 40) & (t < 40.5)] = 12.0 + (t[(t >= 40) & (t < 40.5)] - 40) * 4
    tw[t >= 40.5] = 14.0
    moving = np.r_[False, np.diff(tw) != 0]
    a = simulate(cfg, t, tw, 0.0, 200.0, moving, seed=3)
    b = simulate(quiet, t, tw, 0.0, 200.0, moving, seed=3)
    dl, dr = a["length_mm"] - b["length_mm"], a["resistance_ohm"] - b["resistance_ohm"]
    hold2, hold3 = (t > 25) & (t < 39), (t > 45)
    assert np.ptp(dl[hold2]) < 1e-6 and np.ptp(dl[hold3]) < 1e-6  # constant within a hold
    assert abs(dl[hold2][0] - dl[hold3][0]) > 1e-3                 # redrawn at the stop
    c = simulate(cfg, t, tw, 0.0, 200.0, moving, seed=4)
    assert abs((c["resistance_ohm"] - b["resistance_ohm"])[5] - dr[5]) > 1e-4  # per-run offset differs by seed
    off = _cfg(length_settling={"enabled": True}, resistance_settling={"enabled": True},
               resistance_transient_decay={"enabled": False}, length_creep={"enabled": False})
    z = simulate(off, t, tw, 0.0, 200.0, moving, seed=3)
    assert np.array_equal(z["length_mm"], b["length_mm"]) and np.array_equal(z["resistance_ohm"], b["resistance_ohm"])
