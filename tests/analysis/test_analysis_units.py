"""Unit tests of the diagnose building blocks: holdout split, residual tests, API."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.analysis.hidden import generate
from tsa_bench.analysis import Candidate, DiagnoseResult, Gain, diagnose, load_model
from tsa_bench.analysis.inputs import run_inputs, split
from tsa_bench.analysis.modelspec import candidate_effects, enabled_effects
from tsa_bench.analysis.residual_tests import ljung_box, xcorr
from tsa_bench.store import read_run


@pytest.fixture(scope="module")
def clean_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("units") / "clean.h5"
    generate(path, (), seed=5, short=True)
    return read_run(path)


def test_baseline_model_has_the_thesis_effects_only():
    model = load_model(None)
    on = set(enabled_effects(model))
    assert on == {"string_compliance", "radius_growth", "thermal_contraction", "resistance_length", "sensor_noise",
                  "quantisation"}
    assert set(candidate_effects(model)) == {
        "missed_steps", "thermal_dynamics", "load_dependence", "twist_hysteresis", "length_creep",
        "resistance_hysteresis", "resistance_transient_decay", "resistance_creep", "resistance_temperature"}


@pytest.mark.parametrize("spec", [None, "after:500", "fraction:0.25"])
def test_holdout_is_a_suffix_never_interleaved(clean_run, spec):
    inp = [run_inputs(clean_run, 500.0)]
    split(inp, spec)
    h = inp[0].heldout
    assert h.any() and not h.all()
    first = np.argmax(h)
    assert h[first:].all() and not h[:first].any()
    if spec is None:   # default: cut at a segment boundary
        assert inp[0].segment[first] != inp[0].segment[first - 1]


def test_holdout_whole_runs(clean_run):
    inp = [run_inputs(clean_run, 500.0), run_inputs(clean_run, 500.0)]
    split(inp, None)
    assert not inp[0].heldout.any() and inp[1].heldout.all()
    split(inp, "run:0")
    assert inp[0].heldout.all() and not inp[1].heldout.any()
    with pytest.raises(ValueError):
        split(inp, "bogus:1")


def test_ljung_box_white_and_structured():
    rng = np.random.default_rng(0)
    ps = [ljung_box(rng.normal(size=2000))[1] for _ in range(100)]
    assert 0.0 <= np.mean(np.array(ps) < 0.05) <= 0.12
    walk = np.cumsum(rng.normal(size=2000))
    assert ljung_box(walk)[1] < 1e-6


def test_xcorr_bound_accounts_for_autocorrelation():
    rng = np.random.default_rng(1)
    flagged_naive = flagged = 0
    for _ in range(100):
        a = np.cumsum(rng.normal(size=1000))   # two independent smooth series
        b = np.cumsum(rng.normal(size=1000))
        r, bound = xcorr(a, b)
        flagged += abs(r) > bound
        flagged_naive += abs(r) > 1.96 / np.sqrt(1000)
    assert flagged_naive > 50          # the plain bound over-flags
    assert flagged <= 15               # Bartlett's bound does not (nominal 5 %)


def test_result_api_and_json(clean_run):
    result = diagnose([clean_run], load_model(None))
    assert isinstance(result, DiagnoseResult)
    assert result.cause is None and result.causes == []
    assert all(isinstance(c, Candidate) for c in result.candidates)
    assert {c.name for c in result.candidates} >= {"time", "cycle_count", "motor_angle", "direction",
                                                   "time_since_stop", "heater_power", "twist_hysteresis"}
    assert [g.output for g in result.gain] == ["length", "resistance"] and all(isinstance(g, Gain) for g in result.gain)
    js = json.loads(json.dumps(result.to_json()))
    for key in ("cause", "causes", "candidates", "gain", "residual_tests"):
        assert key in js
    assert set(js["residual_tests"]) == {"before", "after"}
    assert {"ljung_box_p", "structured", "xcorr"} <= set(js["residual_tests"]["before"]["length"])
    for key in ("t", "heldout", "length_measured", "length_before", "length_after", "resistance_measured",
                "resistance_before", "resistance_after"):
        assert len(result.series[key]) == len(clean_run)
    assert "before" in result.calibrated and "after" in result.calibrated


def test_residual_tests_flag_structure_before_not_after(tmp_path):
    info = generate(tmp_path / "r.h5", ("twist_hysteresis",), seed=8)
    result = diagnose([read_run(info["path"])], load_model(None))
    assert result.cause == "twist_hysteresis"
    assert result.residual_tests["before"]["length"]["structured"]
    assert "cause_signal" in result.series
    assert result.residual_tests["after"]["length"]["rms"] < 0.5 * result.residual_tests["before"]["length"]["rms"]
