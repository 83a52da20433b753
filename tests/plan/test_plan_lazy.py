"""The lazily expanded plan equals the eager expansion, segment for segment.

The reference below is the recursive expansion the compiler used before segments were
expanded on demand; every shipped protocol (and a nested loop protocol with relative
moves) must give the same segments through the lazy sequence, read in order, backwards
and at random, with spans small enough that the cache evicts.
"""

from __future__ import annotations

import pickle
import random

import pytest

from tests.plan.plan_helpers import BENCH, PROTOCOL_DIR, errors_of
from tsa_bench.plan import Move, Segment, TrackLength, load_plan, load_plan_text
from tsa_bench.plan import compiler, loader, model
from tsa_bench.plan.ops import ActionOp, ForEachOp, LostTwistOp, MoveOp, RepeatOp

NESTED = """name: nested
defaults: {rate_turns_per_s: 1, accel_turns_per_s2: 10}
steps:
  - move_to: {turns: 1}
  - for_each:
      variable: v
      values: [1, 2, 3]
      steps:
        - heater: {voltage_V: $v}
        - repeat:
            count: 5
            steps:
              - move_by: {turns: 0.1}
              - repeat: {count: 2, steps: [{move_by: {turns: -0.03}}, {hold: {duration_s: $v}}]}
              - move_by: {turns: 0.09}
  - move_to: {turns: 0}
"""


def _eager(ops) -> list[Segment]:
    """The former compiler's expansion (valid plans only)."""
    out: list[Segment] = []
    position: list[float | None] = [0.0]

    def run(ops, cycle):
        for op in ops:
            if isinstance(op, ActionOp):
                out.append(Segment(len(out), op.action, cycle, op.source))
                if isinstance(op.action, TrackLength):
                    position[0] = None
            elif isinstance(op, MoveOp):
                target = (None if position[0] is None else round(position[0] + op.turns, 9)) if op.relative \
                    else op.turns
                position[0] = target
                if target is not None:
                    out.append(Segment(len(out), Move(target, op.rate_turns_per_s, op.accel_turns_per_s2),
                                       cycle, op.source))
            elif isinstance(op, RepeatOp):
                for c in range(op.count):
                    run(op.body, c)
            elif isinstance(op, ForEachOp):
                for c, body in enumerate(op.bodies):
                    run(body, c)
            else:
                assert isinstance(op, LostTwistOp)
                position[0] = None

    run(ops, None)
    return out


@pytest.fixture
def small_spans(monkeypatch):
    """Spans of 7 segments and a cache of 3 spans, so every protocol crosses spans and evicts;
    records the operation tree each load compiles."""
    monkeypatch.setattr(compiler, "CHECKPOINT_SEGMENTS", 7)
    monkeypatch.setattr(model, "CACHED_SEGMENTS", 21)
    trees = []

    def capture(ops, *args):
        trees.append(ops)
        return compiler.compile_ops(ops, *args)

    monkeypatch.setattr(loader, "compile_ops", capture)
    return trees


def _same(plan, expected: list[Segment]) -> None:
    segs = plan.segments
    assert len(segs) == len(expected)
    assert list(segs) == expected                                   # in order
    assert [segs[i] for i in reversed(range(len(segs)))] == expected[::-1]   # backwards
    order = list(range(len(segs)))
    random.Random(len(segs)).shuffle(order)
    assert all(segs[i] == expected[i] for i in order)               # at random
    assert segs[-1] == expected[-1] and segs[3:11] == expected[3:11]
    assert len(segs._cache) <= 3                                     # bounded whatever the plan's length


@pytest.mark.parametrize("name", sorted(p.name for p in PROTOCOL_DIR.glob("*.yaml")))
def test_shipped_protocols_expand_lazily_as_eagerly(small_spans, name):
    plan = load_plan(PROTOCOL_DIR / name, BENCH)
    _same(plan, _eager(small_spans[-1]))


def test_nested_loops_and_relative_moves(small_spans):
    plan = load_plan_text(NESTED, BENCH, "nested.yaml")
    expected = _eager(small_spans[-1])
    assert len(expected) == 2 + 3 * (1 + 5 * (2 + 2 * 2))
    _same(plan, expected)
    assert list(pickle.loads(pickle.dumps(plan)).segments) == expected   # a plan still travels to a process
    s = plan.summary()
    assert s.segment_count == len(expected) and s.final_twist_turns == 0
    assert s.twist_range_turns == (0.0, max(e.action.target_turns for e in expected if e.kind == "move"))


def test_lazy_plan_still_refuses_every_out_of_range_cycle(small_spans):
    errs = errors_of(NESTED.replace("count: 5", "count: 50"), BENCH.__class__(max_twist_turns=5))
    text = str(errs)
    assert "exceeds max_twist_turns 5" in text and "first in cycle" in text and "times in all" in text


def test_empty_plan_and_out_of_range_index():
    plan = load_plan_text("name: e\nsteps:\n  - hold: {duration_s: 1}\n", BENCH, "e.yaml")
    assert len(plan.segments) == 1 and plan.segments[-1].kind == "hold"
    with pytest.raises(IndexError):
        plan.segments[1]


def test_a_plan_that_fits_the_cache_is_walked_once():
    plan = load_plan(PROTOCOL_DIR / "lifetime.yaml", BENCH)
    segs = plan.segments
    assert len(segs) <= model.CACHED_SEGMENTS

    def no_second_walk(k):
        raise AssertionError(f"span {k} expanded again")

    segs._expand = no_second_walk
    assert len(list(segs)) == len(segs) and segs[-1].kind == "heater" and plan.summary().cycles == 596
