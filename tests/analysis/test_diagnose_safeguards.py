"""The safeguards of `diagnose` each have a test that fails when the safeguard goes
(scripts/diagnose_mutations.py removes them one at a time and lists the tests that fail):
calibration never sees held-out outputs; a cause that no longer earns its place leaves the
model; a parameter at the edge of its range caps the confidence; the block bootstrap's
interval is wide when the held-out units disagree; the naming gate turns down what does
not improve the held-out data; hold-to-hold offsets are named only when they are random; the
calibration's parameter order does not hang on string hashing (the report is reproducible)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest

from tests.analysis.hidden import generate
from tsa_bench.analysis import diagnose, load_model
from tsa_bench.analysis.calibrate import calibrate
from tsa_bench.analysis.confusion import EDGE_CAP, cap
from tsa_bench.analysis.context import FLOOR, Context
from tsa_bench.analysis.holdout import split
from tsa_bench.analysis.inputs import run_inputs
from tsa_bench.analysis.modelspec import baseline_specs, enabled_effects, get_value, switch
from tsa_bench.analysis.naming import gate
from tsa_bench.analysis.noise import Noise, noise_model
from tsa_bench.analysis.scoring import Scores, compare
from tsa_bench.analysis.search import Chosen, eliminate
from tsa_bench.analysis.settling import variance_component
from tsa_bench.store import read_run


@pytest.fixture(scope="module")
def model():
    return load_model(None)


@pytest.fixture(scope="module")
def decay_run(tmp_path_factory):
    info = generate(tmp_path_factory.mktemp("safe") / "decay.h5", ("resistance_transient_decay",), seed=2, short=True)
    return read_run(info["path"])


def test_calibration_never_sees_the_held_out_outputs(tmp_path, model, decay_run):
    """Shifting the held-out outputs changes the held-out error, not one bit of the calibration."""
    base = diagnose([decay_run], model, max_causes=0)
    held = np.asarray(base.series["heldout"], bool)
    assert 0.15 < held.mean() < 0.45
    moved = tmp_path / "moved.h5"
    shutil.copy(decay_run.path, moved)
    with h5py.File(moved, "r+") as f:
        for col, by in (("length", 1.0), ("resistance", 0.05)):
            f["samples"][col][...] = f["samples"][col][:] + np.where(held, by, 0.0)
    other = diagnose([read_run(moved)], model, max_causes=0)
    assert other.calibrated["before"] == base.calibrated["before"]
    assert other.gain[0].heldout_rmse_before > base.gain[0].heldout_rmse_before + 0.5


def _context(run, model):
    inputs = [run_inputs(run, float(model["initial_load_g"]))]
    hold = split(inputs, None)
    outputs = ("length", "resistance")
    return Context(inputs, outputs, {o: noise_model(inputs, o) for o in outputs}, hold, 0)


def test_a_cause_that_does_not_earn_its_place_leaves_the_model(model, decay_run):
    """Backward elimination: a sensor drift added to a model of a run that has none explains nothing
    held out once the true cause is in; it is demoted and the model returned no longer has it."""
    ctx = _context(decay_run, model)
    centre = {s.key: get_value(model, s.key) for s in baseline_specs(model)}
    fit0 = calibrate(ctx.problem, model, baseline_specs(model), centre=centre, max_nfev=40)
    cfg = switch(switch(model, "resistance_transient_decay", True), "resistance_offset_drift", True,
                 {"ohm_per_hour": 1e-4})
    start = {**fit0.values, "resistance_transient_decay.b1_ohm": -1.7e-3, "resistance_transient_decay.b2_ohm": -0.027}
    both = calibrate(ctx.problem, cfg, baseline_specs(cfg), start=start, centre=centre, max_nfev=40)
    chosen = [Chosen("resistance_transient_decay", {}, 1.0, 1.0, 1), Chosen("resistance_offset_drift", {}, 1.0, 1.0, 2)]
    fit, scores, kept, demoted = eliminate(ctx, both, ctx.scores(both.cfg), chosen, fit0, ctx.scores(fit0.cfg), centre,
                                           lambda m: None)
    assert demoted is not None and demoted["form"] == "resistance_offset_drift", demoted
    assert [c.form for c in kept] == ["resistance_transient_decay"]
    on = enabled_effects(fit.cfg)
    assert "resistance_offset_drift" not in on and "resistance_transient_decay" in on
    assert kept[0].own is not None and kept[0].own.significant(FLOOR)


def test_a_form_parameter_at_the_edge_of_its_range_caps_the_confidence():
    bound = [{"key": "resistance_creep_time.time_constant_s", "value": 1e6, "bound": 1e6, "side": "upper"}]
    conf, caveats = cap(0.99, "resistance_creep", [], bound)
    assert conf == EDGE_CAP and "edge of its plausible range" in caveats[0]
    assert cap(0.99, "resistance_creep", [], [])[0] == 0.99
    alt = [{"effect": "resistance_sensor_drift", "form": "gain drift with time"}]
    conf, caveats = cap(0.99, "resistance_creep", alt, [])
    assert conf == 0.5 and "reference resistor" in caveats[0]


_SPEC_ORDER = """
from tsa_bench.analysis import load_model
from tsa_bench.analysis.modelspec import baseline_specs, switch
cfg = load_model(None)
for name in ("resistance_transient_decay", "twist_hysteresis", "load_dependence", "length_creep",
             "resistance_hysteresis", "missed_steps"):
    cfg = switch(cfg, name, True)
print(" ".join(s.key for s in baseline_specs(cfg)))
"""


def test_the_calibrated_parameters_keep_one_order_whatever_the_string_hashing():
    """The report is reproducible bit for bit only if the calibration's parameter vector has one
    order: it must not follow the iteration order of a set of effect names (PYTHONHASHSEED)."""
    orders = set()
    for hash_seed in ("1", "2", "3", "4", "5", "6"):
        env = {**os.environ, "PYTHONHASHSEED": hash_seed}
        proc = subprocess.run([sys.executable, "-c", _SPEC_ORDER], env=env, capture_output=True, text=True, check=True)
        orders.add(proc.stdout.strip())
    assert len(orders) == 1, orders
    heads = list(dict.fromkeys(k.split(".")[0] for k in orders.pop().split() if not k.startswith("geometry.")))
    added = ("resistance_transient_decay", "twist_hysteresis", "load_dependence", "length_creep",
             "resistance_hysteresis", "missed_steps")
    assert set(added) <= set(heads)
    cfg = load_model(None)
    for name in added:
        cfg = switch(cfg, name, True)
    assert [h for h in heads if h in added] == [e for e in enabled_effects(cfg) if e in added]   # the library's order


def _units(diff: np.ndarray) -> tuple[Scores, Scores]:
    cnt = np.full((len(diff), 2), 100.0)
    a = Scores(np.column_stack([np.full(len(diff), 500.0), np.full(len(diff), 100.0)]), cnt, ("length", "resistance"),
               [])
    b = Scores(a.sse - np.column_stack([diff, np.zeros(len(diff))]), cnt, a.outputs, [])
    return a, b


def test_the_bootstrap_interval_is_wide_when_the_held_out_units_disagree():
    """Units that improve by +3 and worsen by -2.5 noise variances per sample in turn: a mean of
    0.25 per sample, but an interval that reaches 0 (a point estimate would call it a gain)."""
    diff = np.tile([300.0, -250.0], 12)
    a, b = _units(diff)
    c = compare(a, b, FLOOR, 1000, 0)
    assert c.improvement["length"] == pytest.approx(0.25)
    lo, hi = c.ci95["length"]
    assert lo < 0 < hi and hi - lo > 1.0
    assert not c.significant(0.0)
    steady = compare(*_units(np.full(24, 25.0)), FLOOR, 1000, 0)
    assert steady.significant(FLOOR) and steady.ci95["length"] == pytest.approx((0.25, 0.25))


def test_the_gate_turns_down_an_improvement_the_held_out_data_do_not_support():
    a, b = _units(np.tile([300.0, -250.0], 12))
    c = compare(a, b, FLOOR, 1000, 0)
    ok, why = gate(c, own_train=5.0, own=None, outputs=("length", "resistance"))
    assert not ok and "not significant" in why
    good = compare(*_units(np.full(24, 80.0)), FLOOR, 1000, 0)
    assert gate(good, own_train=5.0, own=None, outputs=("length", "resistance")) == (True, "passes")
    assert not gate(good, own_train=0.01, own=None, outputs=("length", "resistance"))[0]


def _holds(rng, offsets_of, n_holds=40, per=300, bases=None, whole=True):
    """A residual of ``n_holds`` holds with offsets ``offsets_of(twist, index)`` and white noise."""
    twist = rng.uniform(0, 40, n_holds)
    twist = np.repeat(np.round(twist) if whole else twist, per)
    groups = np.repeat(np.arange(n_holds), per)
    res = offsets_of(twist[::per], np.arange(n_holds))[groups] + rng.normal(0, 1.0, len(groups))
    t = np.arange(len(groups)) * 0.1
    train = np.repeat(np.arange(n_holds) % 3 != 0, per)
    noise = Noise(sigma=1.0, step=0.0, rms=1.0, n=len(groups))
    return variance_component("resistance", res, train, ~train, groups, twist, np.full(len(t), 500.0), t, noise,
                              bases=bases(twist) if bases else None, level=200.0 - twist)


def test_random_hold_offsets_are_a_named_variance_component_and_a_misfit_is_not():
    rng = np.random.default_rng(4)
    draws = rng.normal(0, 3.0, 40)
    comp = _holds(rng, lambda tw, k: draws[k])
    assert comp.named and 2.0 < comp.tau < 4.5 and comp.p < 1e-6 and comp.ci95[0] < comp.tau < comp.ci95[1]
    # a deterministic, periodic function of the hold's state: as large, but it repeats with the state
    wave = _holds(np.random.default_rng(5), lambda tw, k: 3.0 * np.sin(2 * np.pi * tw / 9.0))
    assert not wave.named and wave.follows, wave.to_json()
    small = _holds(np.random.default_rng(6), lambda tw, k: 0.1 * draws[k])
    assert not small.named


def test_hold_offsets_that_drift_from_hold_to_hold_or_follow_a_signal_are_not_settling():
    """Offsets that change slowly with the hold's order (a drift seen hold by hold) and offsets
    that follow the motor angle (an eccentric shaft stands still in each hold) are misfits."""
    slow = _holds(np.random.default_rng(7), lambda tw, k: 3.0 * np.sin(2 * np.pi * k / 30.0))
    assert not slow.named and "hold order" in slow.follows, slow.to_json()

    def angle(twist):
        a = 2 * np.pi * twist
        return {"motor_angle": np.column_stack([np.sin(a), np.cos(a)])}
    ecc = _holds(np.random.default_rng(8), lambda tw, k: 3.0 * np.sin(2 * np.pi * tw), bases=angle, whole=False)
    assert not ecc.named and "motor_angle" in ecc.follows, ecc.to_json()


def test_a_residual_that_follows_an_input_is_not_called_settling(tmp_path, model):
    """A hidden resistance hysteresis leaves hold offsets that look random hold by hold, but the
    residual follows the twist direction sample by sample: not a variance component."""
    info = generate(tmp_path / "rh.h5", ("resistance_hysteresis",), seed=2, short=True)
    result = diagnose([read_run(info["path"])], model, max_causes=0)
    assert "resistance_settling" not in result.causes, (result.summary, result.components)
    comp = next(c for c in result.components if c["output"] == "resistance")
    assert not comp["named"] and any("follows" in f for f in comp["offsets_follow"]), comp
