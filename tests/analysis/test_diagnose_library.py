"""`diagnose` on the project's own plant (tests/analysis/hidden.py: the thesis-like protocol,
library effects hidden with drawn parameters): named right, with the gain on the output it
affects; clean runs explained. The full matrix over seeds is scripts/bench/diagnose_power.py."""

from __future__ import annotations

import pytest

from tests.analysis.hidden import generate
from tsa_bench.analysis import diagnose, load_model
from tsa_bench.store import read_run

AFFECTED = {"resistance_transient_decay": "resistance", "twist_hysteresis": "length", "load_dependence": "length",
            "thermal_dynamics": "length"}


@pytest.fixture(scope="module")
def model():
    return load_model(None)


@pytest.mark.parametrize("effect", ["resistance_transient_decay", "twist_hysteresis", "load_dependence"])
def test_hidden_library_effect_is_named_in_its_own_form(tmp_path, model, effect):
    info = generate(tmp_path / "run.h5", (effect,), seed=1, short=True)
    result = diagnose([read_run(info["path"])], model, max_causes=1)
    assert result.verdict == "named" and result.causes == [effect], (info["drawn"], result.summary, result.notes)
    assert result.named[0].variant == effect          # the library's own form, not an alternative
    gain = {g.output: g.relative for g in result.gain}[AFFECTED[effect]]
    assert gain >= 0.30, (info["drawn"], result.gain)


def test_heating_names_thermal_dynamics_then_the_temperature_coefficient(tmp_path, model):
    info = generate(tmp_path / "run.h5", ("thermal_dynamics", "resistance_temperature"), seed=3)
    result = diagnose([read_run(info["path"])], model, max_causes=2)
    assert result.causes == ["thermal_dynamics", "resistance_temperature"], (info["drawn"], result.summary)
    assert {g.output: g.relative for g in result.gain}["length"] >= 0.30


@pytest.mark.parametrize("seed", [101, 102])
def test_clean_library_runs_are_explained(tmp_path, model, seed):
    info = generate(tmp_path / "clean.h5", (), seed=seed, short=True)
    result = diagnose([read_run(info["path"])], model)
    assert result.verdict == "explained" and result.causes == [], (result.summary, result.notes)
    assert all(g.relative == 0.0 for g in result.gain)


def test_several_runs_hold_out_a_whole_run(tmp_path, model):
    """Two runs of one actuator with the same kinds of excitation: the last one is held out."""
    a = generate(tmp_path / "a.h5", ("twist_hysteresis",), seed=4, short=True)
    b = generate(tmp_path / "b.h5", ("twist_hysteresis",), seed=4, short=True, noise_seed=77)
    runs = [read_run(a["path"]), read_run(b["path"])]
    result = diagnose(runs, model, max_causes=1)
    assert result.causes == ["twist_hysteresis"], (result.summary, result.notes)
    held = result.series["heldout"]
    assert held.sum() == len(runs[1]) and not held[: len(runs[0])].any()
    assert "whole last run" in result.holdout["description"]
