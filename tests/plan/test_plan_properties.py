"""Property: random valid move/hold step lists compile, and the summary agrees with a
direct re-computation (twist range = min/max over the start and all resolved targets)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tsa_bench.motion import TrapezoidProfile
from tsa_bench.benchdata import Limits
from tsa_bench.plan import load_plan_text

turns = st.floats(min_value=-50, max_value=50, allow_nan=False).map(lambda x: round(x, 3))
step = st.one_of(
    st.tuples(st.just("move_to"), turns),
    st.tuples(st.just("move_by"), turns),
    st.tuples(st.just("hold"), st.floats(min_value=0.001, max_value=100).map(lambda x: round(x, 3) or 0.001)),
)


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(step, min_size=1, max_size=12), count=st.integers(min_value=1, max_value=4))
def test_random_step_lists_compile_consistently(steps: list[tuple[str, float]], count: int) -> None:
    lines = []
    for kind, value in steps:
        key = "duration_s" if kind == "hold" else "turns"
        lines.append(f"      - {kind}: {{{key}: {value!r}}}\n")
    text = ("name: p\ndefaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}\nsteps:\n"
            f"  - repeat:\n      count: {count}\n      steps:\n" + "".join(lines))
    plan = load_plan_text(text, Limits())

    position, targets, move_s, hold_s = 0.0, [], 0.0, 0.0
    for _ in range(count):
        for kind, value in steps:
            if kind == "hold":
                hold_s += value
                continue
            target = value if kind == "move_to" else position + value
            move_s += TrapezoidProfile(target - position, 2, 20).duration
            position = target
            targets.append(target)

    summary = plan.summary()
    assert summary.segment_count == count * len(steps) == len(plan.segments)
    assert [s.action.target_turns for s in plan.segments if s.kind == "move"] == pytest.approx(targets, abs=1e-6)
    lo, hi = summary.twist_range_turns
    assert lo == pytest.approx(min([0.0, *targets]), abs=1e-6) and hi == pytest.approx(max([0.0, *targets]), abs=1e-6)
    assert summary.duration_s == pytest.approx(move_s + hold_s, rel=1e-6, abs=1e-6)
    assert [s.cycle for s in plan.segments] == [c for c in range(count) for _ in steps]
