"""The online estimator follows the offline self-sensing model sample by sample."""

from __future__ import annotations

import math

import numpy as np

from tsa_bench.control.estimator import OnlineLengthEstimator
from tsa_bench.models.fitting import from_saved
from tsa_bench.models.saved import load_model_file
from tsa_bench.models.steps import series_from_arrays
from tsa_bench.models.transient import hold_curves
from tsa_bench.reproduce.runs import history, simulate_history
from tests.control.helpers import MODEL


def _scheme2_run(seed: int = 4):
    steps = [("hold", 5.0)]
    for turns in (20, 28, 24, 35, 33, 45, 30, 31, 18):
        steps += [("move", float(turns)), ("hold", 15.0)]
    h = history(steps, dt_s=0.1, load_g=250.0)
    sim = simulate_history(h, "sim-scheme2-4ply", seed=seed, settle_s=60.0)
    return series_from_arrays("scheme2", h["t"], sim["length_mm"], sim["resistance_ohm"], h["motor_moving"])


def test_online_estimate_equals_the_offline_model_at_every_hold_end():
    model = from_saved(load_model_file(MODEL))
    run = _scheme2_run()
    offline, finals = model.estimate(run)
    est = OnlineLengthEstimator(model)
    online = np.array([est.update(t, r, m) for t, r, m in zip(run.t_s, run.resistance_ohm, run.motor_moving)])
    ends = [c.stop - 1 for c in hold_curves(run.t_s, run.motor_moving)]
    assert len(ends) == 9
    np.testing.assert_allclose(online[ends], finals, rtol=0, atol=1e-9)
    assert np.all(np.isnan(online[run.motor_moving]))          # nothing while the motor turns
    # and it tracks the true length at the hold ends (the shipped model's accuracy)
    assert np.max(np.abs(online[ends] - run.length_mm[ends])) < 1.0


def test_no_resistance_gives_no_estimate_and_a_window_follows_a_change():
    model = from_saved(load_model_file(MODEL))
    run = _scheme2_run()
    est = OnlineLengthEstimator(model, window_s=5.0)
    for t, r, m in zip(run.t_s[:300], run.resistance_ohm[:300], run.motor_moving[:300]):
        est.update(t, r, m)
    assert not run.motor_moving[299]
    t = float(run.t_s[299])
    assert not math.isnan(est.update(t + 0.1, math.nan, False))   # the hold's estimate stands
    before = est.last_mm
    # a resistance step of +0.02 ohm (about 0.9 mm): a 5 s window has followed it after 5 s
    r0 = float(np.nanmean(run.resistance_ohm[290:300]))
    for k in range(1, 60):
        est.update(t + 0.1 + 0.1 * k, r0 + 0.02, False)
    assert est.last_mm - before > 0.5
    # heater on from the start of a new hold: no estimate until resistance is measured again
    assert math.isnan(est.update(t + 7.0, math.nan, True))
    assert math.isnan(est.update(t + 7.1, math.nan, False))
