"""The operation tree a protocol's ``steps:`` parse into, and what a step module sees of the parser.

Units: twist in turns, rates in turns/s, accelerations in turns/s^2.

Contract: :mod:`tsa_bench.plan.steps` (the parser) and the step modules it calls
(:mod:`tsa_bench.plan.tracking_step`, :mod:`tsa_bench.plan.twist_heat_step`) build
:data:`Op` trees; :mod:`tsa_bench.plan.compiler` turns them into segments. A step module
reads its keys through a :class:`StepParsing` (the parser itself) and imports nothing of
the parser.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Protocol, TypeAlias

from yaml import Node

from tsa_bench.plan.actions import Action
from tsa_bench.plan.yamlnodes import Reader


@dataclass(frozen=True, eq=False)
class MoveOp:
    """A move whose absolute target is known (``relative=False``) or resolved at compile time."""

    turns: float
    relative: bool
    rate_turns_per_s: float
    accel_turns_per_s2: float
    source: str
    node: Node      # where twist-limit errors point
    field: str


@dataclass(frozen=True, eq=False)
class ActionOp:
    """A final action (hold, heater, sampling, prompt) copied as-is into the plan."""

    action: Action
    source: str


@dataclass(frozen=True, eq=False)
class RepeatOp:
    """``body`` run ``count`` times; ``count`` is ``None`` when it was invalid (checked once)."""

    count: int | None
    body: tuple[Op, ...]
    source: str     # "file.yaml:LINE" of the repeat step


@dataclass(frozen=True, eq=False)
class ForEachOp:
    """One body per value of a ``for_each``, run in order (iteration i = cycle i)."""

    bodies: tuple[tuple[Op, ...], ...]
    source: str


@dataclass(frozen=True, eq=False)
class LostTwistOp:
    """Stands for an invalid motion step: the twist after it is unknown, so later
    relative moves are not range-checked (avoids follow-on errors)."""


Op: TypeAlias = MoveOp | ActionOp | RepeatOp | ForEachOp | LostTwistOp


class StepParsing(Protocol):
    """What a step module uses of the :class:`~tsa_bench.plan.steps.StepParser` that calls it."""

    reader: Reader
    folder: Path     # the protocol file's folder: paths in a step are relative to it

    def _motion(self, fields: dict[str, Node], node: Node, field: str) -> tuple[float, float] | None: ...

    def _hold_after(self, fields: dict[str, Node], field: str) -> float | None: ...

    def _voltage(self, node: Node, field: str) -> float | None: ...
