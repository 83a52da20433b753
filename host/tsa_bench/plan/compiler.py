"""Expand an operation tree into the flat, executable segment list.

Contract: the run starts at 0 turns; ``move_by`` targets are the previous target plus
the step's turns (rounded to 1e-9 turns so repeated fractional steps do not drift).
Every resolved target is checked against the twist limits; an out-of-range step is
reported once (with the first repeat cycle it happens in and how often it recurs).
Segments in a repeat carry the 0-based iteration of the innermost repeat as ``cycle``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from yaml import Node

from tsa_bench.plan.actions import Move, Segment, TrackLength
from tsa_bench.plan.errors import ErrorSink
from tsa_bench.plan.limits import Limits
from tsa_bench.plan.steps import ActionOp, ForEachOp, LostTwistOp, MoveOp, Op, RepeatOp

#: Upper bound on the expanded plan size (protects memory against e.g. nested huge counts).
MAX_SEGMENTS = 1_000_000

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


@dataclass
class _Compiler:
    limits: Limits
    sink: ErrorSink
    segments: list[Segment] = field(default_factory=list)
    position_turns: float | None = 0.0   # None: unknown after an invalid motion step
    violations: dict[int, _TwistViolation] = field(default_factory=dict)
    tracked_at: str | None = None        # source of the track_length that made the twist unknown

    def run(self, ops: Sequence[Op], cycle: int | None, trail: tuple[tuple[RepeatOp | ForEachOp, int], ...]) -> None:
        segments = self.segments
        for op in ops:
            if type(op) is ActionOp:
                segments.append(Segment(len(segments), op.action, cycle, op.source))
                if isinstance(op.action, TrackLength):  # the twist it ends at is decided while running
                    self.position_turns, self.tracked_at = None, op.source
            elif type(op) is MoveOp:
                if op.relative:
                    pos = self.position_turns
                    target = None if pos is None else round(pos + op.turns, _TARGET_DECIMALS)
                    if pos is None and self.tracked_at is not None:
                        self.sink.add(op.node, op.field, f"move_by after the track_length at {self.tracked_at}: "
                                                         "the twist there is decided while running",
                                      "move_to (an absolute twist)")
                else:
                    target = op.turns
                self.position_turns = target
                if not op.relative:
                    self.tracked_at = None
                if target is None:
                    continue
                self._check_twist(op, target, trail)
                move = Move(target, op.rate_turns_per_s, op.accel_turns_per_s2)
                segments.append(Segment(len(segments), move, cycle, op.source))
            elif type(op) is RepeatOp:
                for c in range(op.count or 1):
                    self.run(op.body, c, (*trail, (op, c)))
                if op.count is None:
                    self.position_turns = None
            elif type(op) is ForEachOp:
                for c, body in enumerate(op.bodies):
                    self.run(body, c, (*trail, (op, c)))
            else:  # LostTwistOp
                self.position_turns = None

    def _check_twist(self, op: MoveOp, target: float, trail: tuple[tuple[RepeatOp | ForEachOp, int], ...]) -> None:
        hi, lo = self.limits.max_twist_turns, self.limits.min_twist_turns
        if (hi is None or target <= hi) and (lo is None or target >= lo):
            return
        seen = self.violations.get(id(op))
        if seen is not None:
            seen.occurrences += 1
            return
        where = " > ".join(f"cycle {c} of the {'repeat' if isinstance(rep, RepeatOp) else 'for_each'} at "
                           f"{rep.source}" for rep, c in trail)
        self.violations[id(op)] = _TwistViolation(op, target, where)

    def report(self) -> None:
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


def compile_ops(ops: Sequence[Op], limits: Limits, sink: ErrorSink, steps_node: Node | None = None
                ) -> tuple[Segment, ...]:
    """Expand ``ops`` into segments, reporting twist-limit violations into ``sink``.

    Refuses plans larger than :data:`MAX_SEGMENTS` (one error at ``steps_node``, no segments).
    """
    size = expanded_size(ops)
    if size > MAX_SEGMENTS:
        sink.add(steps_node, "steps", f"protocol expands to {size:,} segments",
                 f"at most {MAX_SEGMENTS:,} segments")
        return ()
    compiler = _Compiler(limits, sink)
    compiler.run(ops, None, ())
    compiler.report()
    return tuple(compiler.segments)
