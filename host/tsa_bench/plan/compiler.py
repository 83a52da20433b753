"""Expand an operation tree into the executable segment list, lazily.

Contract: the run starts at 0 turns; ``move_by`` targets are the previous target plus
the step's turns (rounded to 1e-9 turns so repeated fractional steps do not drift).
Every resolved target is checked against the twist limits; an out-of-range step is
reported once (with the first repeat cycle it happens in and how often it recurs).
Segments in a repeat carry the 0-based iteration of the innermost repeat as ``cycle``.

Memory: :func:`compile_ops` walks the whole expansion once (every segment is checked,
none is kept) and returns :class:`~tsa_bench.plan.model.Segments`, a sequence that
expands ``repeat`` and ``for_each`` blocks again on demand, from checkpoints of the walk
taken every :data:`CHECKPOINT_SEGMENTS` segments, keeping only a bounded number of
expanded segments (the first spans of the checking walk itself, so a plan that fits the
cache is expanded once). The walk of a checkpoint onwards is the same code as the checking
walk, so the segments read later are exactly those that were checked. The checking walk
also lists the first segment of every distinct step and target (a step in a repeat gives
the same segment in every cycle, up to its index and cycle) and every prompt
(:attr:`Segments.distinct`, :attr:`Segments.prompts`; None beyond :data:`MAX_DISTINCT`),
so that checks of a segment's action need not read every segment.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from yaml import Node

from tsa_bench.plan.actions import Move, Prompt, Segment, TrackLength
from tsa_bench.plan.errors import ErrorSink
from tsa_bench.benchdata.limits import Limits
from tsa_bench.plan import model
from tsa_bench.plan.model import Segments
from tsa_bench.plan.ops import ActionOp, ForEachOp, LostTwistOp, MoveOp, Op, RepeatOp

#: Upper bound on the expanded plan size (protects memory against e.g. nested huge counts).
MAX_SEGMENTS = 1_000_000
#: Segments between two checkpoints of the expansion (also the unit expanded on demand).
CHECKPOINT_SEGMENTS = 1024
#: Most distinct segments (or prompts) the checking walk lists for :attr:`Segments.distinct`.
MAX_DISTINCT = 4096

_TARGET_DECIMALS = 9


def expanded_size(ops: Sequence[Op]) -> int:
    """Number of segments ``ops`` expand to (invalid repeat counts count as 1)."""
    total = 0
    for op in ops:
        if isinstance(op, RepeatOp):
            total += (op.count or 1) * expanded_size(op.body)
        elif isinstance(op, ForEachOp):
            total += sum(expanded_size(body) for body in op.bodies)
        elif not isinstance(op, LostTwistOp):
            total += 1
    return total


def outer_cycles(ops: Sequence[Op]) -> int:
    """Total iterations of the top-level (outermost) repeat and for_each blocks."""
    return sum(op.count or 0 for op in ops if isinstance(op, RepeatOp)) + sum(
        len(op.bodies) for op in ops if isinstance(op, ForEachOp))


@dataclass
class _TwistViolation:
    op: MoveOp
    target_turns: float
    where: str          # repeat cycles of the first occurrence, "" outside repeats
    occurrences: int = 1


#: A resumable point of the walk: (stack frames, twist, track_length source, next index).
#: A frame is (ops walked, next op, cycle of its segments, enclosing loop or None, iteration).
Checkpoint = tuple[tuple[tuple, ...], "float | None", "str | None", int]


class _Walker:
    """Depth-first walk of the operation tree with an explicit stack, so that it can be
    saved (:meth:`checkpoint`) and resumed. With a ``sink`` it checks (twist limits,
    ``move_by`` after ``track_length``) as it goes; without one it only expands."""

    def __init__(self, limits: Limits, sink: ErrorSink | None, start: Checkpoint) -> None:
        self.limits, self.sink = limits, sink
        frames, self.position_turns, self.tracked_at, self.index = start
        self.stack = [list(fr) for fr in frames]   # None position: unknown after an invalid motion step
        self.violations: dict[int, _TwistViolation] = {}
        # checking walk: the first segment of every distinct (step, target) and every prompt, in order
        self.firsts: dict[Any, Segment] | None = {} if sink is not None else None
        self.prompts: list[Segment] | None = [] if sink is not None else None

    @classmethod
    def at_start(cls, ops: Sequence[Op], limits: Limits, sink: ErrorSink | None) -> _Walker:
        return cls(limits, sink, (((tuple(ops), 0, None, None, 0),), 0.0, None, 0))

    def checkpoint(self) -> Checkpoint:
        return tuple(tuple(fr) for fr in self.stack), self.position_turns, self.tracked_at, self.index

    def next(self) -> Segment | None:
        """The next segment, or None at the end of the plan."""
        stack = self.stack
        while stack:
            frame = stack[-1]
            ops, i = frame[0], frame[1]
            if i >= len(ops):           # end of a body: next iteration of its loop, or leave it
                stack.pop()
                loop, it = frame[3], frame[4] + 1
                if type(loop) is RepeatOp:
                    if it < (loop.count or 1):
                        stack.append([loop.body, 0, it, loop, it])
                    elif loop.count is None:
                        self.position_turns = None
                elif type(loop) is ForEachOp and it < len(loop.bodies):
                    stack.append([loop.bodies[it], 0, it, loop, it])
                continue
            frame[1] = i + 1
            op = ops[i]
            kind = type(op)
            if kind is ActionOp:
                action = op.action
                if isinstance(action, TrackLength):  # the twist it ends at is decided while running
                    self.position_turns, self.tracked_at = None, op.source
                seg = self._segment(action, frame[2], op.source)
                if self.firsts is not None:
                    self._note(id(op), seg)
                    if isinstance(action, Prompt) and self.prompts is not None:
                        self.prompts.append(seg)
                        if len(self.prompts) > MAX_DISTINCT:
                            self.prompts = None
                return seg
            if kind is MoveOp:
                target = self._target(op)
                if target is None:
                    continue
                seg = self._segment(Move(target, op.rate_turns_per_s, op.accel_turns_per_s2), frame[2], op.source)
                if self.sink is not None:
                    self._check_twist(op, target)
                    if self.firsts is not None:
                        self._note((id(op), target), seg)
                return seg
            if kind is RepeatOp:
                stack.append([op.body, 0, 0, op, 0])
            elif kind is ForEachOp:
                if op.bodies:
                    stack.append([op.bodies[0], 0, 0, op, 0])
            elif kind is LostTwistOp:
                self.position_turns = None
            else:
                raise TypeError(f"the compiler does not know the operation {op!r}")
        return None

    def _note(self, key: Any, seg: Segment) -> None:
        firsts = self.firsts
        if firsts is not None and key not in firsts:
            firsts[key] = seg
            if len(firsts) > MAX_DISTINCT:
                self.firsts = None

    def _segment(self, action, cycle: int | None, source: str) -> Segment:
        seg = Segment(self.index, action, cycle, source)
        self.index += 1
        return seg

    def _target(self, op: MoveOp) -> float | None:
        if op.relative:
            pos = self.position_turns
            target = None if pos is None else round(pos + op.turns, _TARGET_DECIMALS)
            if pos is None and self.tracked_at is not None and self.sink is not None:
                self.sink.add(op.node, op.field, f"move_by after the track_length at {self.tracked_at}: "
                                                 "the twist there is decided while running",
                              "move_to (an absolute twist)")
        else:
            target = op.turns
            self.tracked_at = None
        self.position_turns = target
        return target

    def _check_twist(self, op: MoveOp, target: float) -> None:
        hi, lo = self.limits.max_twist_turns, self.limits.min_twist_turns
        if (hi is None or target <= hi) and (lo is None or target >= lo):
            return
        seen = self.violations.get(id(op))
        if seen is not None:
            seen.occurrences += 1
            return
        where = " > ".join(f"cycle {fr[4]} of the {'repeat' if isinstance(fr[3], RepeatOp) else 'for_each'} at "
                           f"{fr[3].source}" for fr in self.stack if fr[3] is not None)
        self.violations[id(op)] = _TwistViolation(op, target, where)

    def report(self) -> None:
        assert self.sink is not None
        lo, hi = self.limits.min_twist_turns, self.limits.max_twist_turns
        allowed = f"{'-inf' if lo is None else f'{lo:g}'} .. {'inf' if hi is None else f'{hi:g}'} turns"
        for v in self.violations.values():
            above = hi is not None and v.target_turns > hi
            bound = f"max_twist_turns {hi:g}" if above else f"min_twist_turns {lo:g}"
            verb = "exceeds" if above else "is below"
            notes = [
                "reached through move_by" if v.op.relative else "",
                f"first in {v.where}" if v.where else "",
                f"out of range {v.occurrences} times in all" if v.occurrences > 1 else "",
            ]
            note = "; ".join(n for n in notes if n)
            self.sink.add(v.op.node, v.op.field,
                          f"twist target {v.target_turns:g} turns {verb} {bound}" + (f" ({note})" if note else ""),
                          allowed)


class _Expansion:
    """Expands the segments of one checkpoint span again (the :class:`Segments` source)."""

    def __init__(self, limits: Limits, checkpoints: list[Checkpoint]) -> None:
        self.limits, self.checkpoints = limits, checkpoints

    def span(self, k: int) -> list[Segment]:
        """Segments ``k * CHECKPOINT_SEGMENTS`` up to the next checkpoint (or the end)."""
        walker = _Walker(self.limits, None, self.checkpoints[k])
        out: list[Segment] = []
        for _ in range(CHECKPOINT_SEGMENTS):
            seg = walker.next()
            if seg is None:
                break
            out.append(seg)
        return out


def compile_ops(ops: Sequence[Op], limits: Limits, sink: ErrorSink, steps_node: Node | None = None) -> Segments:
    """Check the expansion of ``ops``, reporting twist-limit violations into ``sink``, and
    return its lazily expanded :class:`Segments`.

    Refuses plans larger than :data:`MAX_SEGMENTS` (one error at ``steps_node``, no segments).
    """
    size = expanded_size(ops)
    if size > MAX_SEGMENTS:
        sink.add(steps_node, "steps", f"protocol expands to {size:,} segments",
                 f"at most {MAX_SEGMENTS:,} segments")
        return Segments.empty()
    walker = _Walker.at_start(ops, limits, sink)
    checkpoints: list[Checkpoint] = []
    step = walker.next
    # the first spans walked here are kept (as many as Segments caches), so that a plan that
    # fits the cache is never expanded twice
    keep = max(1, model.CACHED_SEGMENTS // CHECKPOINT_SEGMENTS)
    spans: list[list[Segment]] = []
    span: list[Segment] | None = None
    while True:
        if walker.index % CHECKPOINT_SEGMENTS == 0:
            checkpoints.append(walker.checkpoint())
            span = None
            if len(spans) < keep:
                span = []
                spans.append(span)
        seg = step()
        if seg is None:
            break
        if span is not None:
            span.append(seg)
    walker.report()
    firsts = tuple(walker.firsts.values()) if walker.firsts is not None else None
    prompts = tuple(walker.prompts) if walker.prompts is not None else None
    return Segments(walker.index, CHECKPOINT_SEGMENTS, _Expansion(limits, checkpoints).span,
                    walked=[sp for sp in spans if sp], distinct=firsts if prompts is not None else None,
                    prompts=prompts if firsts is not None else None)

