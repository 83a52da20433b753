"""`validate` refuses a track_length that cannot run, saying why, before anything moves."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.plan import PlanErrors, TrackLength, load_plan_text
from tests.control.helpers import BENCH_PATH, MODEL, SCHEME2, protocol


def _validate(tmp_path, text: str, bench=str(BENCH_PATH)):
    p = tmp_path / "track.yaml"
    p.write_text(text, encoding="utf-8")
    return CliRunner().invoke(main, ["validate", str(p), "--bench", bench])


def _model(tmp_path, **changes) -> str:
    doc = json.loads(MODEL.read_text())
    for key, value in changes.items():
        if value is None:
            doc["options"].pop(key, None)
        else:
            doc[key] = value
    p = tmp_path / "m.json"
    p.write_text(json.dumps(doc))
    return str(p)


def test_a_valid_track_length_compiles_with_its_model_and_range(tmp_path):
    res = _validate(tmp_path, protocol("targets: [{length_mm: 201, hold_s: 5}, {length_mm: 211}]"))
    assert res.exit_code == 0, res.output
    assert "track_length to 201 mm (hold 5 s), 211 mm (hold 0 s) from resistance" in res.output
    plan = load_plan_text(protocol("length_mm: 205"), SCHEME2.limits)
    a = plan.segments[-1].action
    assert isinstance(a, TrackLength) and a.targets == ((205.0, 0.0),) and a.model_path == str(MODEL)
    lo, hi = a.valid_length_mm
    assert 190 < lo < 200 < 215 < hi < 225


def test_a_target_outside_the_validity_range_is_refused_where_it_is(tmp_path):
    res = _validate(tmp_path, protocol("targets: [{length_mm: 205}, {length_mm: 240}]"))
    assert res.exit_code == 2
    assert "track.yaml:10:" in res.output and "targets[1].length_mm" in res.output
    assert "target 240 mm is outside the model's validity range" in res.output and "Traceback" not in res.output


@pytest.mark.parametrize("changes, reason", [
    ({"model": "strain-resistance"}, "is a 'strain-resistance' model; track_length needs a 'self-sensing' model"),
    ({"length_range_mm": None}, "has no validity range"),
    ({"format": "other"}, "'format' is 'other'"),
])
def test_a_model_file_of_the_wrong_kind_is_refused_with_the_reason(tmp_path, changes, reason):
    model = _model(tmp_path, **changes)
    res = _validate(tmp_path, protocol("length_mm: 205").replace(str(MODEL), model))
    assert res.exit_code == 2 and reason in res.output, res.output
    assert "track_length.model" in res.output


def test_a_model_of_another_string_is_refused_for_this_bench(tmp_path):
    res = _validate(tmp_path, protocol("length_mm: 205"), bench="configs/bench/sim-3ply.yaml")
    assert res.exit_code == 2
    assert "was identified on runs of bench 'simulated TSA bench, Scheme 2" in res.output
    assert "(another string)" in res.output


def test_a_missing_model_and_a_relative_move_after_tracking_are_refused():
    with pytest.raises(PlanErrors, match="no such file"):
        load_plan_text(protocol("length_mm: 205").replace(str(MODEL), "/nonexistent/m.json"), SCHEME2.limits)
    with pytest.raises(PlanErrors, match="move_by after the track_length"):
        load_plan_text(protocol("length_mm: 205", after="  - move_by: {turns: 2}\n"), SCHEME2.limits)
    plan = load_plan_text(protocol("length_mm: 205", after="  - move_to: {turns: 0}\n  - move_by: {turns: 2}\n"),
                          SCHEME2.limits)
    assert plan.segments[-1].action.target_turns == 2
