"""Plan segments as device commands: long holds as several DWELLs; what cannot be sent."""

from __future__ import annotations

import pytest

from tests.runner.helpers import BENCH, plan_from_text
from tsa_bench.benchdata import Limits
from tsa_bench.plan import load_plan_text
from tsa_bench.runner.commands import MAX_DWELL_US, device_commands, dwell_chunks_us, plan_problems


@pytest.mark.parametrize("hold_s", [0.001, 4294.967295, 4294.967296, 10_000, 604_800])
def test_holds_become_dwells_that_add_up_exactly(hold_s):
    chunks = dwell_chunks_us(hold_s)
    assert sum(chunks) == round(hold_s * 1e6) and all(0 < c <= MAX_DWELL_US for c in chunks)
    assert len(chunks) == -(-round(hold_s * 1e6) // MAX_DWELL_US)
    assert max(chunks) - min(chunks) <= 1


def test_plan_problems_names_what_does_not_fit_the_wire():
    plan = plan_from_text("name: t\nsteps:\n  - hold: {duration_s: 10000}\n")
    assert [len(device_commands(s, 3200)) for s in plan.segments] == [3]
    assert plan_problems(plan, BENCH.steps_per_turn) == []
    free = Limits()  # a bench without limits: only the wire bounds the values
    plan = load_plan_text("name: t\nsteps:\n  - move_to: {turns: 1e9, rate_turns_per_s: 1, accel_turns_per_s2: 1}\n"
                          "  - heater: {voltage_V: 70}\n", free, "t.yaml")
    problems = plan_problems(plan, 3200)
    assert len(problems) == 2 and problems[0].startswith("t.yaml:3: move") and "MoveTo" in problems[0]
    assert "SetHeater" in problems[1]


def test_plan_problems_from_distinct_segments_equal_those_from_every_segment():
    """The checking walk's first segment per distinct step and target gives exactly the
    problems (and their order) of reading every segment."""
    import dataclasses

    free = Limits()
    text = ("name: t\nload_g: 10\nsteps:\n"
            "  - repeat:\n      count: 20\n      steps:\n"       # beyond the step range from cycle 6 on
            "        - move_by: {turns: 1.0e5, rate_turns_per_s: 1, accel_turns_per_s2: 1}\n"
            "        - hold: {duration_s: 1}\n"
            "        - prompt: {text: hang it, load_g: 20}\n"
            "        - heater: {voltage_V: 3}\n"
            "  - repeat:\n      count: 3\n      steps:\n"
            "        - heater: {voltage_V: 70}\n"
            "        - move_by: {turns: 2.5e8, rate_turns_per_s: 1, accel_turns_per_s2: 1}\n"
            "        - prompt: {text: again, load_g: 30}\n"
            "  - move_to: {turns: 0, rate_turns_per_s: 1, accel_turns_per_s2: 1}\n")
    plan = load_plan_text(text, free, "t.yaml")
    assert plan.segments.distinct is not None and len(plan.segments.distinct) < len(plan.segments) / 2
    every = dataclasses.replace(plan, segments=list(plan.segments))   # no distinct list: reads each segment
    problems = plan_problems(plan, 3200)
    assert problems == plan_problems(every, 3200)
    assert [p.split(": ")[0] for p in problems] == ["t.yaml:7", "t.yaml:14", "t.yaml:15"]   # move, heater, move
    assert "MoveTo" in problems[0] and "SetHeater" in problems[1] and "MoveTo" in problems[2]
