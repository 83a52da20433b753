"""Malformed protocols: every error names file, line, column, dotted field and what is allowed."""

from __future__ import annotations

import pytest

from tsa_bench.benchdata import Limits
from tsa_bench.plan import PlanError, PlanErrors, load_plan
from plan_helpers import BENCH, HEADER, errors_of, protocol

# (id, YAML text, expected 1-based line, expected field, expected message fragment)
CASES: list[tuple[str, str, int, str, str]] = [
    ("yaml-syntax", "name: t\nsteps:\n  - hold: {duration_s: 1\n  - hold: {duration_s: 2}\n", 4, "", "YAML syntax"),
    ("top-level-list", "- hold: {duration_s: 1}\n", 1, "", "top level must be a mapping"),
    ("top-level-scalar", "just text\n", 1, "", "top level must be a mapping"),
    ("empty-file", "# only a comment\n", 1, "", "empty"),
    ("unknown-top-key", "name: t\ncolour: red\nsteps: [{hold: {duration_s: 1}}]\n", 2, "colour", "unknown key"),
    ("missing-name", "steps: [{hold: {duration_s: 1}}]\n", 1, "name", "missing required key"),
    ("missing-steps", "name: t\n", 1, "steps", "missing required key"),
    ("duplicate-key", "name: t\nname: u\nsteps: [{hold: {duration_s: 1}}]\n", 2, "name", "duplicate key"),
    ("unknown-step-kind", protocol("twist: {turns: 3}"), 4, "steps[0]", "unknown step kind 'twist'"),
    ("step-two-keys", protocol("{hold: {duration_s: 1}, heater: {voltage_V: 1}}"), 4, "steps[0]", "one-key mapping"),
    ("step-scalar", protocol("hold"), 4, "steps[0]", "one-key mapping"),
    ("unknown-key-in-step", protocol("hold: {duration_s: 1, speed: 2}"), 4, "steps[0].hold.speed", "unknown key"),
    ("missing-key-in-step", protocol("move_to: {rate_turns_per_s: 1}"), 4, "steps[0].move_to.turns", "missing required"),
    ("string-for-number", protocol("hold: {duration_s: ten}"), 4, "steps[0].hold.duration_s", "expected a number"),
    ("quoted-number", protocol('hold: {duration_s: "10"}'), 4, "steps[0].hold.duration_s", "remove the quotes"),
    ("bool-for-number", protocol("heater: {voltage_V: true}"), 4, "steps[0].heater.voltage_V", "booleans are not"),
    ("zero-duration", protocol("hold: {duration_s: 0}"), 4, "steps[0].hold.duration_s", "must be > 0"),
    ("negative-duration", protocol("hold: {duration_s: -3}"), 4, "steps[0].hold.duration_s", "must be > 0"),
    ("negative-hold_s", protocol("rotation_sequence: {targets_turns: [1], hold_s: -5}"), 4,
     "steps[0].rotation_sequence.hold_s", "must be >= 0"),
    ("nan", protocol("hold: {duration_s: .nan}"), 4, "steps[0].hold.duration_s", "finite"),
    ("inf", protocol("move_to: {turns: .inf}"), 4, "steps[0].move_to.turns", "finite"),
    ("twist-above-max", protocol("move_to: {turns: 150}"), 4, "steps[0].move_to.turns", "exceeds max_twist_turns"),
    ("twist-below-min", protocol("move_to: {turns: -20}"), 4, "steps[0].move_to.turns", "below min_twist_turns"),
    ("twist-via-move_by", protocol("move_to: {turns: 90}", "move_by: {turns: 6}", "move_by: {turns: 6}"), 6,
     "steps[2].move_by.turns", "102 turns exceeds"),
    ("twist-in-sequence", protocol("rotation_sequence: {targets_turns: [20, 120], hold_s: 1}"), 4,
     "steps[0].rotation_sequence.targets_turns[1]", "exceeds max_twist_turns"),
    ("twist-via-repeat", HEADER + "  - repeat:\n      count: 30\n      steps: [{move_by: {turns: 4}}]\n", 6,
     "steps[0].repeat.steps[0].move_by.turns", "first in cycle 25 of the repeat at p.yaml:4"),
    ("voltage-above-max", protocol("heater: {voltage_V: 12.5}"), 4, "steps[0].heater.voltage_V", "max_heater_voltage_V"),
    ("voltage-negative", protocol("heater: {voltage_V: -1}"), 4, "steps[0].heater.voltage_V", "must be >= 0"),
    ("voltage-in-steps", protocol("voltage_steps: {voltages_V: [1, 20], hold_s: 1}"), 4,
     "steps[0].voltage_steps.voltages_V[1]", "max_heater_voltage_V"),
    ("rate-zero", protocol("move_to: {turns: 1, rate_turns_per_s: 0}"), 4,
     "steps[0].move_to.rate_turns_per_s", "must be > 0"),
    ("rate-above-max", protocol("move_to: {turns: 1, rate_turns_per_s: 6}"), 4,
     "steps[0].move_to.rate_turns_per_s", "max_rate_turns_per_s"),
    ("accel-above-max", protocol("move_by: {turns: 1, accel_turns_per_s2: 500}"), 4,
     "steps[0].move_by.accel_turns_per_s2", "max_accel_turns_per_s2"),
    ("default-rate-above-max", "name: t\ndefaults: {rate_turns_per_s: 9}\nsteps: [{hold: {duration_s: 1}}]\n", 2,
     "defaults.rate_turns_per_s", "max_rate_turns_per_s"),
    ("no-rate-anywhere", "name: t\nsteps:\n  - move_to: {turns: 1, accel_turns_per_s2: 5}\n", 3,
     "steps[0].move_to.rate_turns_per_s", "no defaults.rate_turns_per_s"),
    ("empty-steps", "name: t\nsteps: []\n", 2, "steps", "must not be empty"),
    ("steps-not-list", "name: t\nsteps: {hold: 1}\n", 2, "steps", "expected a list"),
    ("empty-targets", protocol("rotation_sequence: {targets_turns: [], hold_s: 1}"), 4,
     "steps[0].rotation_sequence.targets_turns", "must not be empty"),
    ("empty-voltages", protocol("voltage_steps: {voltages_V: [], hold_s: 1}"), 4,
     "steps[0].voltage_steps.voltages_V", "must not be empty"),
    ("empty-repeat-steps", protocol("repeat: {count: 2, steps: []}"), 4, "steps[0].repeat.steps", "must not be empty"),
    ("repeat-count-zero", protocol("repeat: {count: 0, steps: [{hold: {duration_s: 1}}]}"), 4,
     "steps[0].repeat.count", "must be >= 1"),
    ("repeat-count-float", protocol("repeat: {count: 2.5, steps: [{hold: {duration_s: 1}}]}"), 4,
     "steps[0].repeat.count", "expected an integer"),
    ("sampling-zero", protocol("sampling: {period_s: 0}"), 4, "steps[0].sampling.period_s", ">= 0.001"),
    ("sampling-too-slow", protocol("sampling: {period_s: 61}"), 4, "steps[0].sampling.period_s", "<= 60"),
    ("top-sampling-negative", "name: t\nsampling_period_s: -0.1\nsteps: [{hold: {duration_s: 1}}]\n", 2,
     "sampling_period_s", ">= 0.001"),
    ("loosen-max-twist", "name: t\nlimits: {max_twist_turns: 120}\nsteps: [{hold: {duration_s: 1}}]\n", 2,
     "limits.max_twist_turns", "may only tighten"),
    ("loosen-min-twist", "name: t\nlimits:\n  min_twist_turns: -50\nsteps: [{hold: {duration_s: 1}}]\n", 3,
     "limits.min_twist_turns", "may only tighten"),
    ("unknown-limit", "name: t\nlimits: {max_speed: 1}\nsteps: [{hold: {duration_s: 1}}]\n", 2,
     "limits.max_speed", "unknown key"),
    ("limits-crossed", "name: t\nlimits: {min_twist_turns: 50, max_twist_turns: 40}\nsteps: [{hold: {duration_s: 1}}]\n",
     2, "limits", "above max_twist_turns"),
    ("prompt-empty-text", protocol('prompt: {text: "  "}'), 4, "steps[0].prompt.text", "must not be empty"),
    ("prompt-negative-load", protocol("prompt: {text: hi, load_g: -5}"), 4, "steps[0].prompt.load_g", ">= 0"),
    ("metadata-not-mapping", "name: t\nmetadata: [1, 2]\nsteps: [{hold: {duration_s: 1}}]\n", 2,
     "metadata", "expected a mapping"),
    ("name-not-string", "name: [a]\nsteps: [{hold: {duration_s: 1}}]\n", 1, "name", "expected a string"),
]


@pytest.mark.parametrize(("text", "line", "field", "fragment"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_malformed_protocol_reports_position_and_field(text: str, line: int, field: str, fragment: str) -> None:
    errors = errors_of(text).errors
    matching = [e for e in errors if e.line == line and e.field == field and fragment in e.message]
    assert matching, "\n".join(str(e) for e in errors)
    err = matching[0]
    assert err.file == "p.yaml" and err.column is not None and err.column >= 1
    rendered = str(err)
    assert rendered.startswith(f"p.yaml:{line}:{err.column}: ")
    if field:
        assert f": {field}: " in rendered


def test_error_string_format_with_allowed() -> None:
    err = errors_of(protocol("hold: {duration_s: 1, speed: 2}")).errors[0]
    assert str(err) == "p.yaml:4:27: steps[0].hold.speed: unknown key 'speed' (allowed: duration_s)"
    assert (err.line, err.column, err.field, err.message) == (4, 27, "steps[0].hold.speed", "unknown key 'speed'")


def test_all_errors_are_collected_in_file_order() -> None:
    text = HEADER + "  - hold: {duration_s: -1}\n  - heater: {voltage_V: 50}\n  - twist: {}\n  - move_to: {turns: 500}\n"
    errs = errors_of(text)
    assert [e.line for e in errs.errors] == [4, 5, 6, 7]
    assert len(str(errs).splitlines()) == 4
    assert all(isinstance(e, PlanError) for e in errs.errors)


def test_invalid_motion_step_does_not_cause_follow_on_twist_errors() -> None:
    # The broken move_to makes the twist unknown, so the move_by after it is not range-checked.
    errs = errors_of(protocol("move_to: {turns: x}", "move_by: {turns: 99}", "move_by: {turns: 99}"))
    assert [e.field for e in errs.errors] == ["steps[0].move_to.turns"]


def test_repeated_violation_is_reported_once_with_count() -> None:
    errs = errors_of(protocol("repeat: {count: 10, steps: [{move_to: {turns: 200}}]}"))
    assert len(errs.errors) == 1 and "10 times" in errs.errors[0].message


def test_missing_file_names_the_path(tmp_path) -> None:
    path = tmp_path / "nope.yaml"
    with pytest.raises(PlanErrors) as info:
        load_plan(path, BENCH)
    (err,) = info.value.errors
    assert err.file == str(path) and err.line is None
    assert "not found" in str(err) and str(path) in str(err)


def test_directory_is_reported_as_unreadable(tmp_path) -> None:
    with pytest.raises(PlanErrors, match="cannot read"):
        load_plan(tmp_path, BENCH)


def test_file_errors_use_the_given_path(tmp_path) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(protocol("hold: {duration_s: 0}"))
    with pytest.raises(PlanErrors) as info:
        load_plan(path, BENCH)
    assert str(info.value).startswith(f"{path}:4:")


def test_huge_expansion_is_refused() -> None:
    text = protocol("repeat: {count: 100000, steps: [{repeat: {count: 100000, steps: [{hold: {duration_s: 1}}]}}]}")
    errs = errors_of(text, Limits())
    assert "segments" in str(errs)
