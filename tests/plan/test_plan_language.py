"""Protocol language: variables, for_each loops, hold_until_settled, and the JSON Schema."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from tests.plan.plan_helpers import BENCH, PROTOCOL_DIR, errors_of, protocol
from tsa_bench.userfiles import parse_yaml
from tsa_bench.plan import Hold, Move, Prompt, Settle, load_plan, load_plan_text
from tsa_bench.plan.schema import STEPS, schema_text
from tsa_bench.plan.steps import STEP_KINDS

ROOT = Path(__file__).resolve().parents[2]

LOAD_SERIES = """name: loads
variables: {rest: 5, rate: 2}
defaults: {rate_turns_per_s: $rate, accel_turns_per_s2: 10}
steps:
  - for_each:
      variable: load
      values: [200, 550, 1000]
      steps:
        - prompt: {text: "hang $load g (costs $$3, ${load}g)", load_g: $load}
        - for_each:
            variable: t
            values: [5, 10]
            steps:
              - move_to: {turns: $t}
              - hold: {duration_s: $rest}
"""


def test_for_each_expands_a_load_series_without_copies():
    plan = load_plan_text(LOAD_SERIES, BENCH, "loads.yaml")
    kinds = [s.kind for s in plan.segments]
    assert kinds == ["prompt", "move", "hold", "move", "hold"] * 3
    prompts = [s.action for s in plan.segments if isinstance(s.action, Prompt)]
    assert [p.load_g for p in prompts] == [200.0, 550.0, 1000.0]
    assert prompts[1].text == "hang 550 g (costs $3, 550g)"       # $$ is a literal $, ${name} inside words
    moves = [s.action for s in plan.segments if isinstance(s.action, Move)]
    assert [m.target_turns for m in moves] == [5, 10] * 3 and {m.rate_turns_per_s for m in moves} == {2.0}
    assert {s.action.duration_s for s in plan.segments if isinstance(s.action, Hold)} == {5.0}
    # cycle = the innermost loop's value index; sources point at the loop body's lines
    assert [s.cycle for s in plan.segments[:5]] == [0, 0, 0, 1, 1]
    assert plan.segments[0].source == "loads.yaml:9" and plan.segments[1].source == "loads.yaml:14"
    assert plan.cycles == 3 and plan.summary().loads_g == (200.0, 550.0, 1000.0)


def test_variable_errors_point_at_the_reference():
    errs = errors_of(protocol("move_to: {turns: $nowhere}", "hold: {duration_s: 1}"))
    (err,) = errs.errors
    assert (err.line, err.column) == (4, 22) and "unknown variable $nowhere" in err.message
    text = "name: t\nvariables: {2bad: 1, ok: [1, 2]}\nsteps:\n  - hold: {duration_s: 1}\n"
    msgs = str(errors_of(text))
    assert "p.yaml:2:13: variables.2bad: '2bad' is not a variable name" in msgs
    assert "p.yaml:2:26: variables.ok: expected a number or a text" in msgs


def test_a_loop_value_out_of_range_is_reported_with_its_cycle():
    text = protocol("for_each: {variable: t, values: [10, 200, 20], steps: [{move_to: {turns: $t}}]}")
    (err,) = errors_of(text).errors
    assert "twist target 200 turns exceeds max_twist_turns 100" in err.message
    assert "cycle 1 of the for_each at p.yaml:4" in err.message and err.line == 4


@pytest.mark.parametrize("step,part", [
    ("for_each: {variable: x, values: [], steps: [{hold: {duration_s: 1}}]}", "list of values must not be empty"),
    ("for_each: {variable: 'a b', values: [1], steps: [{hold: {duration_s: 1}}]}", "is not a variable name"),
    ("for_each: {variable: x, values: [[1]], steps: [{hold: {duration_s: 1}}]}", "expected a number or a text"),
    ("for_each: {variable: x, values: [1]}", "missing required key 'steps'"),
    ("for_each: {variable: x, values: [a], steps: [{hold: {duration_s: $x}}]}", "expected a number, got string 'a'"),
    ("hold_until_settled: {max_duration_s: 60}", "give at least one settling threshold"),
    ("hold_until_settled: {max_duration_s: 60, window_s: 90, max_dL_dt_mm_per_s: 0.01}",
     "must be <= 60 s (max_duration_s)"),
    ("hold_until_settled: {max_duration_s: 60, max_dR_dt_ohm_per_s: 0}", "must be > 0 ohm/s"),
    ("hold_until_settled: {window_s: 10, max_dR_dt_ohm_per_s: 1e-4}", "missing required key 'max_duration_s'"),
])
def test_language_errors(step, part):
    assert part in str(errors_of(protocol(step)))


def test_loops_that_expand_too_far_are_refused_quickly():
    values = "[" + ", ".join(str(i % 50) for i in range(2000)) + "]"
    inner = f"{{for_each: {{variable: b, values: {values}, steps: [{{move_to: {{turns: $b}}}}]}}}}"
    text = protocol(f"for_each: {{variable: a, values: {values}, steps: [{inner}]}}")
    assert "for_each loops expand to more than" in str(errors_of(text))


def test_hold_until_settled_defaults():
    plan = load_plan_text(protocol("hold_until_settled: {max_duration_s: 180, max_dR_dt_ohm_per_s: 5.0e-5}",
                                   "hold_until_settled: {max_duration_s: 10, max_dL_dt_mm_per_s: 1e-3}"),
                          BENCH, "p.yaml")
    a, b = (s.action for s in plan.segments)
    assert a == Settle(180.0, 30.0, 30.0, 5e-5, None) and b == Settle(10.0, 10.0, 10.0, None, 1e-3)
    assert plan.summary().hold_duration_s == 190.0  # an upper bound: each at its maximum


def test_the_settled_thesis_protocol_is_the_fixed_one_with_settling_holds():
    fixed = load_plan(PROTOCOL_DIR / "quasi-static-self-sensing.yaml", BENCH)
    settled = load_plan(PROTOCOL_DIR / "quasi-static-self-sensing-settled.yaml", BENCH)
    assert [s.kind for s in settled.segments] == [
        "settle" if s.kind == "hold" and s.action.duration_s == 180 else s.kind for s in fixed.segments]
    assert [s.action for s in settled.segments if s.kind == "move"] == \
        [s.action for s in fixed.segments if s.kind == "move"]
    assert {s.action.max_duration_s for s in settled.segments if s.kind == "settle"} == {180.0}


def _data(path: Path):
    return parse_yaml(path.read_text(), str(path)).data()  # as an editor reads it (1e-3 is a number)


def test_the_schema_file_is_generated_and_accepts_every_shipped_protocol():
    schema_file = ROOT / "configs" / "schema" / "protocol.schema.json"
    assert schema_file.read_text() == schema_text(), "stale: run scripts/gen_protocol_schema.py"
    schema = json.loads(schema_file.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    assert set(STEPS) == set(STEP_KINDS)
    validator = jsonschema.Draft202012Validator(schema)
    for path in sorted(PROTOCOL_DIR.glob("*.yaml")):
        assert not list(validator.iter_errors(_data(path))), path.name
    assert not list(validator.iter_errors(parse_yaml(LOAD_SERIES, "x").data()))


@pytest.mark.parametrize("text", [
    protocol("hold: {duration: 1}"),                       # unknown key (typo)
    protocol("move_to: {rate_turns_per_s: 1}"),             # missing required key
    protocol("wiggle: {turns: 1}"),                         # unknown step kind
    protocol("hold: {duration_s: -1}"),                     # out of range
    protocol("hold: {duration_s: 1}", "move_by: {turns: one}"),
    "name: t\nsteps: []\n",
    "steps:\n  - hold: {duration_s: 1}\n",                  # no name
])
def test_the_schema_refuses_what_validate_refuses(text):
    validator = jsonschema.Draft202012Validator(json.loads(schema_text()))
    assert list(validator.iter_errors(parse_yaml(text, "x").data()))
    errors_of(text)
