"""The compiled plan and its summary figures.

Units: turns, V, s, g as in :mod:`tsa_bench.plan.actions`. Summary conventions: the run
starts at 0 turns with the heater at 0 V, so both ranges include 0; move durations are
trapezoidal-profile estimates; prompts wait for the operator and count 0 s; a
``hold_until_settled`` counts its maximum duration and a ``track_length`` every target's
timeout and hold (the estimate is an upper bound); the twist a ``track_length`` reaches is
decided while running, so the twist range is that of the moves.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, overload

from tsa_bench.motion import TrapezoidProfile
from tsa_bench.plan.actions import KINDS, Hold, Move, Prompt, Segment, SetHeater, SetSampling, Settle, TrackLength
from tsa_bench.benchdata.limits import Limits


#: Most expanded segments a :class:`Segments` keeps at once (in spans of its checkpoint size).
CACHED_SEGMENTS = 16_384


class Segments(Sequence[Segment]):
    """The segments of a compiled plan, expanded on demand (read-only sequence).

    ``len``, indexing (negative too), slicing (a list) and iteration behave as on a tuple of
    every segment; only the spans of ``span_size`` segments last used are kept (at most
    :data:`CACHED_SEGMENTS` segments), so memory does not grow with the plan's length.
    Reading in order, as the runner does, expands each span once. ``expand(k)`` gives the
    segments of span ``k`` (built by :func:`tsa_bench.plan.compiler.compile_ops`); ``walked``
    are spans 0, 1, ... already expanded, kept in the cache.
    """

    def __init__(self, count: int, span_size: int, expand: Callable[[int], list[Segment]],
                 walked: Sequence[list[Segment]] = (), distinct: tuple[Segment, ...] | None = None,
                 prompts: tuple[Segment, ...] | None = None) -> None:
        self._n, self._size, self._expand = count, span_size, expand
        self._cache: OrderedDict[int, list[Segment]] = OrderedDict()
        self._keep = max(1, CACHED_SEGMENTS // span_size)
        for k, span in enumerate(walked[:self._keep]):   # spans already expanded (by the compiler's walk)
            self._cache[k] = span
        #: the first segment of every distinct step and target, in plan order (a segment not listed
        #: repeats a listed one's action and source); None: not known (read every segment)
        self.distinct = distinct
        #: every prompt segment in plan order; None: not known
        self.prompts = prompts

    @classmethod
    def empty(cls) -> Segments:
        """No segments (a plan without steps)."""
        return cls(0, 1, _no_segments)

    def __len__(self) -> int:
        return self._n

    def _span(self, k: int) -> list[Segment]:
        cache = self._cache
        span = cache.get(k)
        if span is None:
            span = cache[k] = self._expand(k)
            if len(cache) > self._keep:
                cache.popitem(last=False)
        elif k != next(reversed(cache)):
            cache.move_to_end(k)
        return span

    @overload
    def __getitem__(self, i: int) -> Segment: ...
    @overload
    def __getitem__(self, i: slice) -> list[Segment]: ...

    def __getitem__(self, i: int | slice) -> Segment | list[Segment]:
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(self._n))]
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError(f"segment index {i} out of range (plan of {self._n} segments)")
        return self._span(i // self._size)[i % self._size]

    def __iter__(self) -> Iterator[Segment]:
        for k in range((self._n + self._size - 1) // self._size):
            yield from self._span(k)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, (Segments, tuple, list)):
            return len(self) == len(other) and all(a == b for a, b in zip(self, other))
        return NotImplemented

    def __repr__(self) -> str:
        return f"Segments({self._n} segments, expanded on demand)"


def _no_segments(k: int) -> list[Segment]:
    return []


@dataclass(frozen=True)
class PlanSummary:
    """Headline figures of a compiled plan (see module docstring for conventions)."""

    segment_count: int
    counts_by_kind: dict[str, int]            # every kind in KINDS, possibly 0
    duration_s: float                         # move_duration_s + hold_duration_s
    move_duration_s: float
    hold_duration_s: float
    twist_range_turns: tuple[float, float]    # (min, max), including the 0-turn start
    voltage_range_V: tuple[float, float]      # (min, max), including the initial 0 V
    sampling_period_range_s: tuple[float, float]
    cycles: int                               # iterations of the outermost repeat block(s)
    prompt_count: int
    loads_g: tuple[float, ...]                # hanging masses in order (initial, then prompt changes)
    final_twist_turns: float
    final_voltage_V: float


@dataclass(frozen=True)
class Plan:
    """A validated protocol compiled to segments; built only by the loader.

    ``segments`` are expanded on demand (:class:`Segments`): any number of ``repeat``
    cycles costs the memory of a few thousand segments.

    ``source_text`` is the YAML exactly as read; ``limits`` are the effective limits
    (bench tightened by the protocol); ``cycles`` counts the iterations of the outermost
    repeat block(s).
    """

    name: str
    description: str
    path: str | None
    source_text: str
    segments: Segments
    sampling_period_s: float
    load_g: float | None
    limits: Limits
    metadata: dict[str, Any] = field(default_factory=dict)
    cycles: int = 0

    def summary(self) -> PlanSummary:
        """The :class:`PlanSummary` (one pass over the segments, computed once)."""
        known = self.__dict__.get("_summary")
        if known is None:
            known = self._summarise()
            object.__setattr__(self, "_summary", known)
        return known

    def _summarise(self) -> PlanSummary:
        counts = dict.fromkeys(KINDS, 0)
        position = 0.0
        twist_lo = twist_hi = 0.0
        voltage = volt_lo = volt_hi = 0.0
        period_lo = period_hi = self.sampling_period_s
        move_s = hold_s = 0.0
        loads: list[float] = [] if self.load_g is None else [self.load_g]
        durations: dict[tuple[float, float, float], float] = {}
        for seg in self.segments:
            action = seg.action
            counts[action.kind] += 1
            if isinstance(action, Move):
                key = (action.target_turns - position, action.rate_turns_per_s, action.accel_turns_per_s2)
                if key not in durations:
                    durations[key] = TrapezoidProfile(*key).duration
                move_s += durations[key]
                position = action.target_turns
                twist_lo, twist_hi = min(twist_lo, position), max(twist_hi, position)
            elif isinstance(action, Hold):
                hold_s += action.duration_s
            elif isinstance(action, Settle):
                hold_s += action.max_duration_s
            elif isinstance(action, TrackLength):
                hold_s += action.longest_s
            elif isinstance(action, SetHeater):
                voltage = action.voltage_V
                volt_lo, volt_hi = min(volt_lo, voltage), max(volt_hi, voltage)
            elif isinstance(action, SetSampling):
                period_lo, period_hi = min(period_lo, action.period_s), max(period_hi, action.period_s)
            elif isinstance(action, Prompt) and action.load_g is not None:
                if not loads or loads[-1] != action.load_g:
                    loads.append(action.load_g)
        return PlanSummary(
            segment_count=len(self.segments),
            counts_by_kind=counts,
            duration_s=move_s + hold_s,
            move_duration_s=move_s,
            hold_duration_s=hold_s,
            twist_range_turns=(twist_lo, twist_hi),
            voltage_range_V=(volt_lo, volt_hi),
            sampling_period_range_s=(period_lo, period_hi),
            cycles=self.cycles,
            prompt_count=counts["prompt"],
            loads_g=tuple(loads),
            final_twist_turns=position,
            final_voltage_V=voltage,
        )
