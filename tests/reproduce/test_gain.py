"""Gain claims with intervals: the twist-heat gain per hold, on and off the training grid, block-bootstrapped.

The runs are generated here (numpy only): the length falls with twist and with heating, and the
heating's depth grows with the twist through a saturating law (not the models' polynomials),
so the coupled form has something to gain that the additive one cannot reach.
"""

from __future__ import annotations

import numpy as np
import pytest

from tsa_bench.reproduce.experiments import run_data
from tsa_bench.reproduce.gain import Hold, gain_with_interval, heating_effect_mm, hold_errors


def _run(name: str, pairs: list[tuple[float, float]], seed: int, hold_n: int = 60):
    rng = np.random.default_rng(seed)
    t, v = np.repeat([p[0] for p in pairs], hold_n), np.repeat([p[1] for p in pairs], hold_n)
    n = len(t)
    length = 300.0 - 0.4 * t - (4.0 + 0.12 * t) * (1.0 - np.exp(-(v / 5.0) ** 2)) + rng.normal(0, 0.3, n)
    hist = {"t": np.arange(n) * 0.5, "turns": t, "heater_voltage": v, "load_g": np.full(n, 250.0),
            "segment": np.repeat(np.arange(len(pairs)), hold_n).astype(np.int32), "motor_moving": np.zeros(n, np.uint8)}
    return run_data(name, hist, {"length_mm": length, "resistance_ohm": np.full(n, 5.0)})


GRID = [(t, v) for t in (0.0, 27.0, 54.0, 81.0) for v in (0.0, 2.0, 4.0, 6.0, 8.0)]


def test_holds_are_split_on_and_off_the_training_grid_and_the_coupled_form_gains():
    train = [_run("grid", GRID, 1)]
    # on grid only where both the twist and the voltage were held together in training
    scored = [_run("mixed", [(27.0, 2.0), (9.0, 1.0), (54.0, 6.0), (40.5, 4.0), (81.0, 8.0), (27.0, 7.0)], 2)]
    tr, held = hold_errors(train, scored)
    assert len(tr) == len(GRID) and all(h.on_grid for h in tr)
    assert [h.on_grid for h in held] == [True, False, True, False, True, False]
    assert [(h.turns, h.voltage_V) for h in held][:2] == [(27.0, 2.0), (9.0, 1.0)]
    assert all(h.n == 20 for h in held)   # the last third of each 60-sample hold
    g = gain_with_interval(held)
    assert g.holds == 6 and g.samples == 120 and g.gain_percent > 20 and g.low_percent < g.gain_percent < g.high_percent
    assert heating_effect_mm(tr) > 5.0


def _holds(gains: list[tuple[float, float]]) -> list[Hold]:
    return [Hold("r", i, float(i), 0.0, 10, a, c, 300.0) for i, (a, c) in enumerate(gains)]


def test_the_interval_is_a_bootstrap_over_holds_and_reproducible():
    even = _holds([(4.0, 1.0)] * 12)              # every hold gains alike: no spread to resample
    g = gain_with_interval(even)
    assert g.gain_percent == pytest.approx(50.0) and g.low_percent == pytest.approx(50.0)
    assert g.high_percent == pytest.approx(50.0) and g.top3_share == pytest.approx(0.25)
    one = _holds([(40.0, 1.0)] + [(1.0, 1.0)] * 11)   # one hold carries the whole gain
    h = gain_with_interval(one)
    assert h.top3_share == pytest.approx(1.0)
    assert h.low_percent < 5.0 < h.gain_percent < h.high_percent   # resamples without that hold gain nothing
    assert gain_with_interval(one) == h
    varied = _holds([(1.0 + 0.7 * i, 1.0 + 0.1 * i) for i in range(12)])
    assert gain_with_interval(varied) == gain_with_interval(varied)      # fixed seed: the same interval every run
    assert gain_with_interval(varied, seed=1).low_percent != gain_with_interval(varied).low_percent
    with pytest.raises(ValueError, match="no holds"):
        gain_with_interval([])
