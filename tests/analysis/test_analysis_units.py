"""Unit tests of the diagnose building blocks: holdout, noise model, structure tests, the
bootstrap comparison, missing inputs, calibration limits, the result's JSON."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.analysis.foreign.cases import make
from tests.analysis.foreign.plant import run_plant
from tests.analysis.foreign.rig import RIGS
from tests.analysis.foreign.runfile import write
from tests.analysis.foreign.walks import random_walk
from tsa_bench.analysis import VERDICTS, HoldoutError, diagnose, load_model
from tsa_bench.analysis.families import FAMILIES, FAMILY_OF
from tsa_bench.analysis.holdout import excitation_events, split, units
from tsa_bench.analysis.inputs import run_inputs
from tsa_bench.analysis.modelspec import enabled_effects
from tsa_bench.analysis.noise import Noise, lattice_step, noise_model
from tsa_bench.analysis.provenance import sha256_file
from tsa_bench.analysis.scoring import Scores, compare
from tsa_bench.analysis.structure import structure_test
from tsa_bench.store import read_run


@pytest.fixture(scope="module")
def clean_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("units") / "clean.h5"
    make("clean-short-3ply", path, seed=1, minutes=10)
    return read_run(path)


@pytest.fixture(scope="module")
def model():
    return load_model(None)


def test_baseline_model_has_the_thesis_effects_and_every_family_its_forms(model):
    assert set(enabled_effects(model)) == {"string_compliance", "radius_growth", "thermal_contraction",
                                           "resistance_length", "sensor_noise", "quantisation"}
    assert set(FAMILIES) == {"missed_steps", "thermal_dynamics", "load_dependence", "twist_hysteresis", "length_creep",
                             "resistance_hysteresis", "resistance_transient_decay", "resistance_creep",
                             "resistance_temperature", "length_sensor_drift", "resistance_sensor_drift"}
    assert len(FAMILIES["missed_steps"]) == 3 and len(FAMILIES["resistance_transient_decay"]) == 3
    assert FAMILY_OF["length_creep_twist"] == "length_creep" and FAMILY_OF["resistance_creep_time"] == "resistance_creep"


def test_default_holdout_keeps_every_kind_of_excitation_on_both_sides(clean_run):
    inp = [run_inputs(clean_run, 500.0)]
    h = split(inp, None)
    held = inp[0].heldout
    assert 0.15 < held.mean() < 0.45 and not held[:10].any()
    for kind, n in h.kinds.items():
        if n["train"] + n["heldout"] >= 2:
            assert n["train"] and n["heldout"], (kind, n)
    # blocks are cut at segment boundaries
    starts = np.flatnonzero(np.diff(held.astype(int)) == 1) + 1
    assert all(inp[0].segment[i] != inp[0].segment[i - 1] for i in starts)
    assert sum(len(u) for u in units(inp[0])) == held.sum()


def test_heating_only_early_is_still_held_out(tmp_path):
    """All heater steps in the first half of the run: the default still holds some out
    (the last 30 % of the time would hold none)."""
    rig = RIGS["short-3ply"]
    h = random_walk(rig, seed=3, minutes=10, heater_V=(3.0, 5.0, 7.0, 5.0), heat_at=0.15)
    heat_t = h.t[h.volts > 0]
    assert heat_t.max() < 0.65 * h.t[-1]
    length, res = run_plant(rig, h, [], seed=1)
    inp = [run_inputs(read_run(write(tmp_path / "heat.h5", h, length, res)), 180.0)]
    hold = split(inp, None)
    assert hold.kinds["heater_step"]["heldout"] >= 1 and hold.kinds["heater_step"]["train"] >= 1
    split(inp, "fraction:0.3")
    assert not (inp[0].heldout & (inp[0].volts > 0)).any()


@pytest.mark.parametrize("spec,expect", [("after:300", "t >= 300"), ("fraction:0.25", "last 25 %")])
def test_holdout_specs_override(clean_run, spec, expect):
    inp = [run_inputs(clean_run, 500.0)]
    h = split(inp, spec)
    first = int(np.argmax(inp[0].heldout))
    assert inp[0].heldout[first:].all() and expect in h.description


@pytest.mark.parametrize("spec", ["bogus:1", "run:0", "fraction:2", "after:1e9"])
def test_bad_holdout_specs_are_refused(clean_run, spec):
    with pytest.raises(HoldoutError):
        split([run_inputs(clean_run, 500.0)], spec)


def test_excitation_events_of_a_walk(clean_run):
    ev = excitation_events(run_inputs(clean_run, 500.0))
    assert len(ev["twist_up"]) > 5 and len(ev["twist_down"]) > 5 and len(ev["load_change"]) == 2
    assert len(ev["heater_on"]) == 0


def test_noise_model_finds_sigma_and_the_quantisation_step(clean_run):
    inp = [run_inputs(clean_run, 500.0)]
    rig = RIGS["short-3ply"]
    nz = noise_model(inp, "length")
    assert nz.step == pytest.approx(rig.length_step_mm, rel=1e-6)
    assert nz.rms == pytest.approx(np.hypot(rig.length_noise_mm, rig.length_step_mm / np.sqrt(12)), rel=0.15)
    assert noise_model(inp, "resistance").sigma == pytest.approx(rig.resistance_noise_ohm, rel=0.1)
    assert lattice_step(np.random.default_rng(0).normal(size=1000)) == 0.0


def test_white_noise_is_not_structure_and_a_once_per_turn_term_is():
    rng = np.random.default_rng(2)
    noise = Noise(1.0, 0.0, 1.0, 1000)
    turns = np.cumsum(rng.uniform(-0.3, 0.3, 3000))       # fast: the term changes within a window
    ang = 2 * np.pi * turns
    bases = {"motor_angle": np.column_stack([np.sin(ang), np.cos(ang)]), "time": np.arange(3000.0)[:, None]}
    flagged = sum(structure_test(rng.normal(size=3000), noise, 10.0, bases)["structured"] for _ in range(100))
    assert flagged <= 4
    res = rng.normal(size=3000) + 1.0 * np.sin(ang)
    t = structure_test(res, noise, 10.0, bases)
    assert t["structured"] and 0.5 < t["structured_rms"] < 0.9 and t["window_rms"] < 0.5
    assert t["follows"][0]["signal"] == "motor_angle" and t["follows"][0]["share"] > 0.8
    slow = structure_test(rng.normal(size=3000) + np.sin(np.arange(3000) / 200.0), noise, 10.0, bases)
    assert slow["structured"] and slow["window_rms"] > 0.5


def test_small_structure_below_the_floor_is_not_called_structure():
    rng = np.random.default_rng(3)
    res = rng.normal(size=20000) + 0.2 * np.sin(np.arange(20000) / 300.0)   # detectable, but 0.14 RMS < 0.5
    t = structure_test(res, Noise(1.0, 0.0, 1.0, 1000), 10.0)
    assert t["p"] < 0.01 and not t["structured"]


def test_block_bootstrap_comparison():
    rng = np.random.default_rng(4)
    sse = rng.uniform(90, 110, size=(20, 2))
    cnt = np.full((20, 2), 100.0)
    a = Scores(sse, cnt, ("length", "resistance"), [])
    same = compare(a, Scores(sse.copy(), cnt, a.outputs, []), 0.25)
    assert same.improvement["pooled"] == 0 and same.ci95["pooled"] == (0.0, 0.0)
    better = compare(a, Scores(sse * 0.5, cnt, a.outputs, []), 0.25)
    assert better.ci95["pooled"][0] > 0.5 and better.p_above["pooled"] == 1.0
    assert better.relative["length"] == pytest.approx(0.5)


def test_run_without_twist_is_a_model_mismatch(tmp_path, model):
    rig = RIGS["short-3ply"]
    h = random_walk(rig, seed=1, minutes=3)
    length, res = run_plant(rig, h, [], seed=1)
    result = diagnose([read_run(write(tmp_path / "nt.h5", h, length, res, nan=("turns",)))], model)
    assert result.verdict == "model_mismatch" and result.causes == []
    assert "turns" in result.mismatch[0]["reason"] and "--map turns" in result.mismatch[0]["remedy"]
    assert result.summary.startswith("model_mismatch: ") and "explained" not in result.summary
    json.dumps(result.to_json(), allow_nan=False)


def test_unmeasured_output_is_a_mismatch_unless_left_out(tmp_path, model):
    rig = RIGS["short-3ply"]
    h = random_walk(rig, seed=1, minutes=6)
    length, res = run_plant(rig, h, [], seed=1)
    path = write(tmp_path / "nr.h5", h, length, res, nan=("resistance",))
    result = diagnose([read_run(path)], model)
    assert result.verdict == "model_mismatch" and "--outputs length" in result.mismatch[0]["remedy"]
    alone = diagnose([read_run(path)], model, outputs=("length",))
    assert alone.verdict == "explained" and [g.output for g in alone.gain] == ["length"]


def test_rig_outside_the_model_range_is_a_mismatch(tmp_path, model):
    """A 5 m string: the untwisted length ends at its bound and the verdict says so."""
    rig = RIGS["long-8ply"].with_(untwisted_mm=5000.0, radius_mm=2.0, rate_hz=5.0)
    h = random_walk(rig, seed=2, minutes=5)
    length, res = run_plant(rig, h, [], seed=1)
    result = diagnose([read_run(write(tmp_path / "big.h5", h, length, res))], model)
    assert result.verdict == "model_mismatch", result.summary
    assert any("untwisted_length_mm" in m["reason"] for m in result.mismatch)


def test_scrambled_length_is_a_mismatch_not_explained(tmp_path, model):
    """A length column shuffled in time: no relation to anything; never 'explained'."""
    rig = RIGS["short-3ply"]
    h = random_walk(rig, seed=1, minutes=6)
    length, res = run_plant(rig, h, [], seed=1)
    length = np.random.default_rng(0).permutation(length)
    result = diagnose([read_run(write(tmp_path / "scr.h5", h, length, res))], model, max_causes=1)
    assert result.verdict == "model_mismatch" and result.causes == []
    assert any("length reading is mostly noise" in m["reason"] for m in result.mismatch)


def test_result_json_schema_and_provenance(clean_run, model):
    result = diagnose([clean_run], model, model_path="configs/bench/sim-baseline.yaml", seed=7)
    js = json.loads(json.dumps(result.to_json(), allow_nan=False))
    assert js["schema"] == "tsa-bench/diagnose" and js["schema_version"] == 3
    assert js["verdict"] in VERDICTS and js["summary"].startswith(js["verdict"])
    for key in ("cause", "causes", "named", "unexplained", "mismatch", "partial", "candidates", "gain", "noise",
                "residual_tests", "calibrated", "calibration", "holdout", "iterations", "provenance", "notes"):
        assert key in js, key
    prov = js["provenance"]
    assert prov["inputs"][0]["sha256"] == sha256_file(clean_run.path) and prov["seed"] == 7
    assert prov["model"]["sha256"] == sha256_file("configs/bench/sim-baseline.yaml") or prov["model"]["sha256"] is None
    assert prov["software"]["numpy"] and prov["seconds"] > 0 and prov["holdout"] == "default"
    assert set(js["residual_tests"]) == {"before", "after"}
    assert {"structured", "p", "structured_rms", "follows"} <= set(js["residual_tests"]["before"]["length"])
    for key in ("t", "heldout", "length_measured", "length_before", "length_after", "resistance_measured"):
        assert len(result.series[key]) == len(clean_run)
