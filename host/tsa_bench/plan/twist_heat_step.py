"""Parse the ``twist_heat`` step: twist and heat at the same time (a heater profile over a twist).

Units: twist in turns (absolute, as ``move_to``), voltages in V, times in s, rates in turns/s,
accelerations in turns/s^2.

Keys (the step is ``{twist_heat: {...}}``):

====================  =====================================================================
targets_turns         the sub-moves' absolute twist targets, in order (1 .. 10,000 of them)
voltages_V            one heater voltage per sub-move: set just before it starts and kept
                      while it runs (same length as ``targets_turns``)
hold_s                optional dwell after each sub-move (>= 0, default 0: back to back)
end_voltage_V         optional heater voltage once the last sub-move (and its dwell) is done;
                      default: the heater stays at the last voltage
rate_turns_per_s,     motion of every sub-move (default: the protocol ``defaults:``)
accel_turns_per_s2
====================  =====================================================================

Contract: the step compiles to existing queued segments only, so it runs unchanged on the
simulated device, on the firmware in simavr and on a serial device: for each sub-move ``i``
a ``heater`` segment (:class:`~tsa_bench.plan.actions.HeaterLevel`, recording the step, the
sub-move and its target) then a ``move`` to ``targets_turns[i]`` (then a ``hold`` when
``hold_s`` > 0), and a final ``heater`` for ``end_voltage_V``. The device applies a
SET_HEATER when the queue reaches it, between two moves, so the heater profile is a
staircase over the twist, one level per sub-move. Each sub-move is a trapezoid from rest
to rest: at every sub-move boundary the motor decelerates to a stop, the heater changes at
that instant, and the next sub-move accelerates from rest (an extra rate/accel seconds per
boundary compared with one move). Every voltage is checked against
``max_heater_voltage_V`` here and every target against the twist limits when the plan is
compiled, with the position of the offending list item.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from yaml import Node

from tsa_bench.plan.actions import HeaterLevel, Hold

if TYPE_CHECKING:
    from tsa_bench.plan.ops import Op, StepParsing

KEYS = ("targets_turns", "voltages_V", "hold_s", "end_voltage_V", "rate_turns_per_s", "accel_turns_per_s2")
#: Most sub-moves one step may have.
MAX_SUB_MOVES = 10_000


def parse_twist_heat(parser: StepParsing, node: Node, field: str, source: str) -> list[Op] | None:
    """The ``twist_heat`` step as heater, move (and hold) operations (None after reporting errors)."""
    from tsa_bench.plan.ops import ActionOp, LostTwistOp, MoveOp

    r = parser.reader
    fields = r.mapping(node, field, KEYS, required=("targets_turns", "voltages_V"))
    if fields is None:
        return None
    ok = True
    hold = parser._hold_after(fields, field)
    if "hold_s" in fields and hold is None:
        ok = False
    end_voltage = None
    if "end_voltage_V" in fields:
        end_voltage = parser._voltage(fields["end_voltage_V"], f"{field}.end_voltage_V")
        ok = ok and end_voltage is not None
    motion = parser._motion(fields, node, field)
    ok = ok and motion is not None
    targets = _list(parser, fields, field, "targets_turns", "targets")
    voltages = _list(parser, fields, field, "voltages_V", "voltages")
    if targets is None or voltages is None:
        return None
    if len(targets) != len(voltages):
        r.sink.add(fields["voltages_V"], f"{field}.voltages_V",
                   f"{len(voltages)} voltages for {len(targets)} sub-moves",
                   "one voltage per item of targets_turns")
        ok = False
    levels = [parser._voltage(v, f"{field}.voltages_V[{j}]") for j, v in enumerate(voltages)]
    turns = [r.number(t, f"{field}.targets_turns[{j}]", "turns") for j, t in enumerate(targets)]
    if not ok or any(v is None for v in levels):
        return None
    rate, accel = motion  # type: ignore[misc]
    n = len(targets)
    ops: list[Op] = []
    for j, (volts, target) in enumerate(zip(levels, turns)):
        if target is None:  # reported; the twist after it is unknown
            ops.append(LostTwistOp())
            continue
        ops.append(ActionOp(HeaterLevel(volts, "twist_heat", j + 1, n, target), source))  # type: ignore[arg-type]
        ops.append(MoveOp(target, False, rate, accel, source, targets[j], f"{field}.targets_turns[{j}]"))
        if hold:
            ops.append(ActionOp(Hold(hold), source))
    if end_voltage is not None:
        ops.append(ActionOp(HeaterLevel(end_voltage, "twist_heat", 0, n, None), source))
    return ops


def _list(parser: StepParsing, fields: dict[str, Node], field: str, key: str, what: str) -> list[Node] | None:
    r = parser.reader
    if key not in fields:
        return None
    items = r.sequence(fields[key], f"{field}.{key}", what)
    if items is None:
        return None
    if len(items) > MAX_SUB_MOVES:
        r.sink.add(fields[key], f"{field}.{key}", f"{len(items):,} {what}", f"at most {MAX_SUB_MOVES:,} sub-moves")
        return None
    return items
