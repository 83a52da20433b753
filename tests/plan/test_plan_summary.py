"""PlanSummary figures and the human-readable format_summary printout."""

from __future__ import annotations

import pytest

from tsa_bench.motion import TrapezoidProfile
from tsa_bench.plan import format_duration, format_summary, load_plan_text
from plan_helpers import BENCH, protocol


def test_summary_figures() -> None:
    text = "load_g: 100\n" + protocol(
        "move_to: {turns: 10}",
        "hold: {duration_s: 5}",
        "voltage_steps: {voltages_V: [2, 6, 0], hold_s: 10}",
        "prompt: {text: more, load_g: 200}",
        "sampling: {period_s: 0.02}",
        "repeat: {count: 4, steps: [{move_by: {turns: -4}}, {hold: {duration_s: 1}}]}",
        "move_to: {turns: 0}",
    )
    s = load_plan_text(text, BENCH).summary()
    assert s.segment_count == 1 + 1 + 6 + 1 + 1 + 8 + 1
    assert s.counts_by_kind == {"move": 6, "hold": 8, "settle": 0, "heater": 3, "sampling": 1, "prompt": 1,
                                 "track_length": 0}
    assert s.twist_range_turns == (-6, 10) and s.final_twist_turns == 0
    assert s.voltage_range_V == (0, 6) and s.final_voltage_V == 0
    assert s.sampling_period_range_s == (0.02, 0.1)
    assert s.cycles == 4 and s.prompt_count == 1 and s.loads_g == (100, 200)
    moves = TrapezoidProfile(10, 1, 10).duration + 4 * TrapezoidProfile(-4, 1, 10).duration \
        + TrapezoidProfile(6, 1, 10).duration
    assert s.move_duration_s == pytest.approx(moves)
    assert s.hold_duration_s == pytest.approx(5 + 30 + 4)
    assert s.duration_s == pytest.approx(moves + 39)


def test_summary_of_plan_without_moves_or_heat() -> None:
    s = load_plan_text(protocol("prompt: {text: wait}"), BENCH).summary()
    assert s.duration_s == 0 and s.twist_range_turns == (0, 0) and s.voltage_range_V == (0, 0)
    assert s.loads_g == () and s.cycles == 0


@pytest.mark.parametrize(("seconds", "text"), [(0, "0:00:00"), (59.6, "0:01:00"), (3661, "1:01:01"),
                                               (10_000, "2:46:40"), (36_000 * 3, "30:00:00")])
def test_format_duration(seconds: float, text: str) -> None:
    assert format_duration(seconds) == text


def test_format_summary_mentions_key_figures() -> None:
    text = "name: demo\nload_g: 550\n" + protocol(
        "prompt: {text: hang, load_g: 600}",
        "repeat: {count: 596, steps: [{move_by: {turns: 2}}, {hold: {duration_s: 1}}, {move_by: {turns: -2}}]}",
        "heater: {voltage_V: 3}", "heater: {voltage_V: 0}",
    ).replace("name: t\n", "")
    out = format_summary(load_plan_text(text, BENCH, "demo.yaml"))
    for fragment in ("demo", "Segments:   1,791", "0 .. 2 turns", "0 .. 3 V", "550 g, 600 g",
                     "Prompts:    1", "Cycles:     596", "estimated", "cycle 595, demo.yaml:6"):
        assert fragment in out, fragment
    assert "... " in out  # long plans list only the first and last segments


def test_format_summary_lists_short_plans_fully() -> None:
    plan = load_plan_text(protocol("hold: {duration_s: 1}", "heater: {voltage_V: 0}"), BENCH, "s.yaml")
    out = format_summary(plan)
    assert "#0      hold     1 s  (s.yaml:4)" in out and "#1      heater   0 V  (s.yaml:5)" in out
    assert "#" not in format_summary(plan, max_listed=0)
