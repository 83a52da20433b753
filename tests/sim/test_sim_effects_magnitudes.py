"""Thesis magnitudes from the plant presets (configs/bench/sim-*.yaml), every effect on.

The staircase tests switch noise and quantisation off so tolerances reflect the model,
not the sensor; the strain tests run the reproduction's experiments as calibrated (noise on). Contraction follows thesis eq. 2.2, ``(x_l - x) / x`` with ``x_l`` the loaded,
untwisted, cold length; the thermal part is ``(x_twisted - x_heated) / x_heated``.
Tolerances: the records' own (configs/thesis/: +-2 percentage points on the 2.4 strains,
centimetre-level ranges as read from the thesis figures); the strains are computed with the
experiments `tsa-bench reproduce` and the calibration use (tsa_bench.reproduce.experiments).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest

from tsa_bench.bench import load_bench
from tsa_bench.sim import simulate

BENCH_DIR = Path(__file__).resolve().parents[2] / "configs" / "bench"
DT = 0.1


@functools.lru_cache(maxsize=None)
def _plant(name: str, quiet: bool = True) -> dict:
    plant = dict(load_bench(BENCH_DIR / name).plant)
    effects = {n: dict(v) for n, v in plant["effects"].items()}
    if quiet:
        for n in ("sensor_noise", "quantisation"):
            effects[n] = {**effects.get(n, {}), "enabled": False}
    plant["effects"] = effects
    return plant


def preset(name: str, quiet: bool = True) -> dict:
    return _plant(name, quiet)


def staircase(levels, hold_s, start=0.0, rate=3.33):
    turns, moving, ends = [start], [False], []
    cur = start
    for lv in levels:
        n = max(1, int(np.ceil(abs(lv - cur) / rate / DT)))
        turns += list(np.linspace(cur, lv, n + 1)[1:])
        moving += [True] * n
        nh = int(round(hold_s / DT))
        turns += [lv] * nh
        moving += [False] * nh
        ends.append(len(turns) - 1)
        cur = lv
    return np.arange(len(turns)) * DT, np.array(turns), np.array(moving), np.array(ends)


def quasi_static(name: str, load_g: float, levels=(20, 30, 40, 55, 40, 30, 20), hold_s=150.0):
    """Settled (after the ~2 min transient) length and resistance at each twist level."""
    t, tw, mv, ends = staircase(levels, hold_s)
    out = simulate(preset(name), t, tw, 0.0, load_g, mv)
    return out["length_mm"][ends], out["resistance_ohm"][ends]


@pytest.mark.parametrize("load", [450, 550])
def test_scheme1_28_to_21_cm_over_20_to_55_turns(load):
    x, r = quasi_static("sim-scheme1.yaml", load)
    assert 270 <= x[0] <= 290 and 200 <= x[3] <= 220
    assert (x[0] - x[3]) / x[3] > 0.25 and x[0] - x[3] > 60  # "over 25 %", "over 6 cm"
    assert np.all(np.diff(x[:4]) < 0) and np.all(np.diff(r[1:4]) < 0)  # R higher at greater length
    assert 20 < r[3] < r[0] < 30  # Table 3.2's Scheme 1 polynomials put 21-28 cm at about 21-29 ohm


def test_scheme1_heavier_load_longer_and_higher_resistance():
    """While twisting (the first half of the staircase). On the way back the calibrated preset's
    twist play, which grows with the load, can put the 550 g TSA a fraction of a millimetre
    below the 450 g one (configs/thesis/calibration.yaml gives the reason)."""
    x450, r450 = quasi_static("sim-scheme1.yaml", 450)
    x550, r550 = quasi_static("sim-scheme1.yaml", 550)
    assert np.all(x550[:4] > x450[:4]) and np.all(r550[:4] > r450[:4])


@pytest.mark.parametrize("load", [250, 350])
def test_scheme2_range_2_to_3_cm_and_r_near_table_3_2(load):
    x, r = quasi_static("sim-scheme2-4ply.yaml", load)
    assert 20 <= x[0] - x[3] <= 30
    assert np.all((7.0 < r) & (r < 9.0))  # Table 3.2's Scheme 2 polynomials: about 8-9 ohm at 21-23 cm
    assert np.all(np.diff(r[:4]) < 0)


def test_scheme2_less_hysteretic_than_scheme1():
    def relative_loop(name, load):
        x, r = quasi_static(name, load, hold_s=6.0)
        width = max(abs(r[1] - r[5]), abs(r[2] - r[4]), abs(r[0] - r[6]))
        return width / np.ptp(r)
    assert relative_loop("sim-scheme2-4ply.yaml", 250) < 0.5 * relative_loop("sim-scheme1.yaml", 450)


@pytest.fixture(scope="module")
def lab():
    """The thesis experiments as the calibration and `tsa-bench reproduce` run them."""
    from tsa_bench.reproduce.experiments import Lab

    return Lab()


def test_3ply_200g_passive_and_active_strain(lab):
    from tsa_bench.reproduce.quantities import strain

    c = {"ply": 3, "load_g": 200}
    assert strain(lab, {"kind": "passive"}, c) == pytest.approx(13.49, abs=2.0)  # thesis 2.4.3, +-2 points
    assert strain(lab, {"kind": "active"}, c) == pytest.approx(27.01, abs=2.0)


def test_4ply_250g_81_turns_then_heating_contracts_further(lab):
    from tsa_bench.reproduce.quantities import strain

    c = {"ply": 4, "load_g": 250}
    heat = lab.heat(4, 250.0)
    assert heat.out["turns_actual"].max() == 81  # no missed steps at 81 turns
    thermal = strain(lab, {"kind": "thermal"}, c)
    # thesis 2.4.3: 14.1 %; the calibrated preset gives about 11 %, because the 4-ply records pull
    # against each other (configs/thesis/calibration.yaml, reasons of ch2.strain.4ply_250g_thermal)
    assert 9.0 < thermal < 15.0
    assert 18.0 < strain(lab, {"kind": "passive"}, {"ply": 4}) < 30.0  # 4-ply passive average 25.46 %


def test_lifetime_like_cycling_resistance_creeps_length_creep_fades():
    """596 cycles 15 -> 25 -> 15 turns in 2-turn steps with 1 s pauses, 550 g, all effects and noise."""
    levels = [17, 19, 21, 23, 25, 23, 21, 19, 17, 15] * 596
    t, tw, mv, ends = staircase(levels, 1.0, start=15.0)
    out = simulate(preset("sim.yaml", quiet=False), t, tw, 0.0, 550.0, mv, seed=2)
    assert t[-1] > 2.5 * 3600
    at15 = ends[9::10]
    r15, x15, t15 = out["resistance_ohm"][at15], out["length_mm"][at15], t[at15]

    def window(values, t0, t1):
        return np.median(values[(t15 >= t0) & (t15 < t1)])
    end = t15[-1]
    assert window(r15, end - 600, end) - window(r15, 0, 600) > 0.05  # creep visible over the test
    first = window(x15, 540, 660) - window(x15, 0, 60)
    later = window(x15, end - 120, end) - window(x15, 540, 660)
    assert first > 0.5 and abs(later) < 0.2 * first  # mild creep in the first ~10 min, then negligible
