"""Loading and compiling each step kind, relative moves, repeats and segment metadata."""

from __future__ import annotations

import json

from tsa_bench.benchdata import Limits
from tsa_bench.plan import Hold, Move, Prompt, SetHeater, SetSampling, load_plan_text
from plan_helpers import BENCH, protocol


def compile_steps(*steps: str, limits: Limits = BENCH):
    return load_plan_text(protocol(*steps), limits, "p.yaml")


def test_top_level_fields_and_defaults() -> None:
    text = (
        "name: demo\ndescription: a test\nmetadata: {scheme: 2, ply: 4, strings: 2x SCP, tags: [a, b]}\n"
        "load_g: 550\nsampling_period_s: 0.05\nlimits: {max_twist_turns: 30}\n"
        "steps:\n  - hold: {duration_s: 1}\n"
    )
    plan = load_plan_text(text, BENCH)
    assert (plan.name, plan.description, plan.load_g, plan.sampling_period_s) == ("demo", "a test", 550, 0.05)
    assert plan.metadata == {"scheme": 2, "ply": 4, "strings": "2x SCP", "tags": ["a", "b"]}
    assert plan.limits.max_twist_turns == 30 and plan.limits.max_rate_turns_per_s == 5
    assert plan.source_text == text and plan.path is None
    json.dumps(plan.metadata)


def test_optional_top_level_defaults() -> None:
    plan = load_plan_text("name: x\nsteps: [{hold: {duration_s: 2}}]\n", BENCH)
    assert plan.description == "" and plan.metadata == {} and plan.load_g is None
    assert plan.sampling_period_s == 0.1 and plan.limits == BENCH and plan.cycles == 0


def test_each_primitive_step_kind() -> None:
    plan = compile_steps(
        "move_to: {turns: 15, rate_turns_per_s: 3.33, accel_turns_per_s2: 50}",
        "hold: {duration_s: 1.5}",
        "heater: {voltage_V: 4}",
        "sampling: {period_s: 0.01}",
        'prompt: {text: "hang 200 g", load_g: 200}',
        "prompt: {text: check the strings}",
    )
    assert [s.action for s in plan.segments] == [
        Move(15, 3.33, 50), Hold(1.5), SetHeater(4), SetSampling(0.01),
        Prompt("hang 200 g", 200), Prompt("check the strings", None),
    ]
    assert [s.kind for s in plan.segments] == ["move", "hold", "heater", "sampling", "prompt", "prompt"]
    assert [s.index for s in plan.segments] == list(range(6))
    assert [s.source for s in plan.segments] == [f"p.yaml:{n}" for n in range(4, 10)]
    assert all(s.cycle is None for s in plan.segments)


def test_params_are_unit_suffixed_and_json_serialisable() -> None:
    plan = compile_steps("move_to: {turns: 2}", "hold: {duration_s: 1}", "heater: {voltage_V: 1}",
                         "sampling: {period_s: 1}", "prompt: {text: hi}")
    params = [s.params() for s in plan.segments]
    assert params[0] == {"target_turns": 2, "rate_turns_per_s": 1, "accel_turns_per_s2": 10}
    assert params[1:] == [{"duration_s": 1}, {"voltage_V": 1}, {"period_s": 1}, {"text": "hi", "load_g": None}]
    json.dumps(params)


def test_move_defaults_and_overrides() -> None:
    plan = compile_steps("move_to: {turns: 5}", "move_to: {turns: 6, rate_turns_per_s: 2}",
                         "move_to: {turns: 7, accel_turns_per_s2: 20}")
    assert [s.action for s in plan.segments] == [Move(5, 1, 10), Move(6, 2, 10), Move(7, 1, 20)]


def test_relative_moves_resolve_from_previous_target_starting_at_zero() -> None:
    plan = compile_steps("move_by: {turns: 2}", "move_by: {turns: 3.5}", "move_to: {turns: 10}",
                         "hold: {duration_s: 1}", "move_by: {turns: -12}")
    targets = [s.action.target_turns for s in plan.segments if s.kind == "move"]
    assert targets == [2, 5.5, 10, -2]


def test_relative_moves_do_not_drift() -> None:
    plan = compile_steps("repeat: {count: 30, steps: [{move_by: {turns: 0.1}}]}")
    assert plan.segments[-1].action.target_turns == 3.0


def test_rotation_sequence_expands_to_moves_and_holds() -> None:
    plan = compile_steps("rotation_sequence: {targets_turns: [20, 30, 25], hold_s: 180, rate_turns_per_s: 2}")
    assert [s.action for s in plan.segments] == [
        Move(20, 2, 10), Hold(180), Move(30, 2, 10), Hold(180), Move(25, 2, 10), Hold(180)]
    assert {s.source for s in plan.segments} == {"p.yaml:4"}


def test_zero_hold_adds_no_hold_segments() -> None:
    plan = compile_steps("rotation_sequence: {targets_turns: [1, 2], hold_s: 0}",
                         "voltage_steps: {voltages_V: [1, 0], hold_s: 0}")
    assert [s.kind for s in plan.segments] == ["move", "move", "heater", "heater"]


def test_voltage_steps_expand_to_heater_and_holds() -> None:
    plan = compile_steps("voltage_steps: {voltages_V: [0, 2, 4, 2, 0], hold_s: 60}")
    actions = [s.action for s in plan.segments]
    assert actions[::2] == [SetHeater(v) for v in (0, 2, 4, 2, 0)]
    assert actions[1::2] == [Hold(60)] * 5


def test_repeat_expansion_and_cycle_numbering() -> None:
    plan = compile_steps(
        "hold: {duration_s: 1}",
        "repeat: {count: 3, steps: [{move_by: {turns: 2}}, {hold: {duration_s: 1}}]}",
        "move_to: {turns: 0}",
    )
    assert plan.cycles == 3
    assert [s.cycle for s in plan.segments] == [None, 0, 0, 1, 1, 2, 2, None]
    assert [s.action.target_turns for s in plan.segments if s.kind == "move"] == [2, 4, 6, 0]


def test_nested_repeat_cycle_is_innermost_and_cycles_counts_outermost() -> None:
    text = (
        "name: n\ndefaults: {rate_turns_per_s: 1, accel_turns_per_s2: 10}\nsteps:\n"
        "  - repeat:\n      count: 2\n      steps:\n"
        "        - heater: {voltage_V: 1}\n"
        "        - repeat: {count: 3, steps: [{hold: {duration_s: 1}}]}\n"
        "  - repeat: {count: 4, steps: [{hold: {duration_s: 2}}]}\n"
    )
    plan = load_plan_text(text, BENCH, "n.yaml")
    assert [s.cycle for s in plan.segments] == [0, 0, 1, 2, 1, 0, 1, 2] + [0, 1, 2, 3]
    assert plan.cycles == 2 + 4
    assert plan.segments[0].source == "n.yaml:7" and plan.segments[1].source == "n.yaml:8"


def test_plan_and_segments_are_frozen() -> None:
    plan = compile_steps("hold: {duration_s: 1}")
    for obj, attr in ((plan, "name"), (plan.segments[0], "cycle"), (plan.segments[0].action, "duration_s")):
        try:
            setattr(obj, attr, 1)
        except AttributeError:
            continue
        raise AssertionError(f"{type(obj).__name__} is mutable")


def test_exponent_and_integer_forms_are_numbers() -> None:
    plan = compile_steps("sampling: {period_s: 1e-3}", "hold: {duration_s: 1_000}", "move_to: {turns: -2.5E0}")
    assert [s.params() for s in plan.segments][:2] == [{"period_s": 0.001}, {"duration_s": 1000}]
    assert plan.segments[2].action.target_turns == -2.5


def test_protocol_limits_tighten_checks() -> None:
    text = "name: t\nlimits: {max_heater_voltage_V: 5}\nsteps:\n  - heater: {voltage_V: 5}\n"
    assert load_plan_text(text, BENCH).limits.max_heater_voltage_V == 5


def test_unlimited_bench_accepts_large_values() -> None:
    plan = compile_steps("move_to: {turns: 1000, rate_turns_per_s: 50, accel_turns_per_s2: 1000}",
                         "heater: {voltage_V: 40}", limits=Limits())
    assert plan.segments[0].action.target_turns == 1000
