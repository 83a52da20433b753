"""Parse the ``steps:`` list of a protocol into an operation tree.

Step kinds (each step is a one-key mapping ``{kind: {...}}``):

==================  =====================================================================
move_to             ``turns`` (absolute target), optional ``rate_turns_per_s``, ``accel_turns_per_s2``
move_by             ``turns`` (relative to the previous target), optional rate/accel
hold                ``duration_s`` (> 0, at most 7 days)
heater              ``voltage_V`` (0 .. max_heater_voltage_V)
sampling            ``period_s`` (0.001 .. 60 s)
prompt              ``text``, optional ``load_g`` (new hanging mass, 0 .. 4294967.295 g, or null)
rotation_sequence   ``targets_turns`` (absolute), ``hold_s`` (>= 0, after each), optional rate/accel
voltage_steps       ``voltages_V``, ``hold_s`` (>= 0, after each voltage)
repeat              ``count`` (integer >= 1), ``steps`` (nestable)
track_length        closed-loop length control from resistance (:mod:`tsa_bench.plan.tracking_step`)
twist_heat          twist and heat at once: ``targets_turns`` and one ``voltages_V`` per sub-move,
                    optional ``hold_s``, ``end_voltage_V``, rate/accel (:mod:`tsa_bench.plan.twist_heat_step`)
hold_until_settled  ``max_duration_s`` (> 0, at most 7 days), optional ``window_s`` (default 30,
                    at most max_duration_s), ``min_duration_s`` (default window_s),
                    ``max_dR_dt_ohm_per_s``, ``max_dL_dt_mm_per_s`` (> 0; at least one)
for_each            ``variable`` (a name), ``values`` (a non-empty list of numbers or texts),
                    ``steps``: the steps once per value, with ``$variable`` set to it (nestable)
==================  =====================================================================

Variables (:mod:`tsa_bench.plan.variables`): any value inside a step may be ``$name``
(typed) or hold ``$name`` in text; names come from the top-level ``variables:`` and
from enclosing ``for_each`` loops. A ``for_each`` counts as a repeat for ``cycle``
(the value's 0-based index) and for the nesting limit.

Moves lacking rate/accel take them from the protocol ``defaults:``. Static checks
(types, signs, rate/accel/voltage limits) happen here; twist targets are checked when
the tree is compiled, because relative moves only resolve then.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path, PurePath

from yaml import MappingNode, Node, ScalarNode

from tsa_bench.plan.actions import Hold, Prompt, SetHeater, SetSampling, Settle
from tsa_bench.benchdata.limits import Limits
from tsa_bench.plan.ops import ActionOp, ForEachOp, LostTwistOp, MoveOp, Op, RepeatOp
from tsa_bench.plan.tracking_step import parse_track_length
from tsa_bench.plan.twist_heat_step import parse_twist_heat
from tsa_bench.plan.variables import NAME, UnknownVariable, Value, substitute
from tsa_bench.plan.yamlnodes import (
    BOOL_TAG, EXPONENT_FLOAT, FLOAT_TAG, INT_TAG, NULL_TAG, STR_TAG, Reader, describe,
)

MIN_SAMPLING_PERIOD_S = 0.001
MAX_SAMPLING_PERIOD_S = 60.0
MAX_REPEAT_DEPTH = 8
#: Longest single hold (s), 7 days: the device runs it as DWELLs of at most 4294.967 s each.
MAX_HOLD_S = 7 * 24 * 3600.0
#: Largest hanging mass (g): what a bench command carries (SIM_SET_LOAD, u32 milligrams).
MAX_LOAD_G = (2**32 - 1) / 1000
#: Default slope window of hold_until_settled (s).
DEFAULT_SETTLE_WINDOW_S = 30.0
#: Most values one for_each may list, and most steps all loops together may expand to
#: while parsing (each value parses its body once).
MAX_FOR_EACH_VALUES = 100_000
MAX_PARSED_STEPS = 100_000

STEP_KINDS: tuple[str, ...] = (
    "move_to", "move_by", "hold", "heater", "sampling", "prompt",
    "rotation_sequence", "voltage_steps", "repeat", "hold_until_settled", "for_each", "track_length",
    "twist_heat",
)
_MOTION_KEYS = ("rate_turns_per_s", "accel_turns_per_s2")
_MOVING_KINDS = frozenset({"move_to", "move_by", "rotation_sequence", "repeat", "for_each", "track_length",
                            "twist_heat"})
# Stand-in rate/accel for a move whose own rate/accel was invalid: its target is still
# range-checked, and a protocol with errors never becomes a Plan, so it is never used.
_PLACEHOLDER_MOTION = (1.0, 1.0)


@dataclass(frozen=True)
class MotionDefaults:
    """Protocol ``defaults:``; ``*_invalid`` = the key was given but already reported as bad."""

    rate_turns_per_s: float | None = None
    accel_turns_per_s2: float | None = None
    rate_invalid: bool = False
    accel_invalid: bool = False


class StepParser:
    """Turns step nodes into :data:`Op` s, reporting problems through ``reader``."""

    def __init__(self, reader: Reader, limits: Limits, defaults: MotionDefaults, filename: str,
                 variables: dict[str, Value] | None = None) -> None:
        self.reader = reader
        self.limits = limits
        self.defaults = defaults
        self.basename = PurePath(filename).name if not filename.startswith("<") else filename
        self.folder = Path(filename).parent if not filename.startswith("<") else Path.cwd()
        self.scope: dict[str, Value] = dict(variables or {})
        self._parsed = 0
        self._too_many_reported = False
        self._handlers: dict[str, Callable[[Node, str, str, int], list[Op] | None]] = {
            "move_to": self._move_to,
            "move_by": self._move_by,
            "hold": self._hold,
            "heater": self._heater,
            "sampling": self._sampling,
            "prompt": self._prompt,
            "rotation_sequence": self._rotation_sequence,
            "voltage_steps": self._voltage_steps,
            "repeat": self._repeat,
            "hold_until_settled": self._hold_until_settled,
            "for_each": self._for_each,
            "track_length": lambda node, field, source, depth: parse_track_length(self, node, field, source),
            "twist_heat": lambda node, field, source, depth: parse_twist_heat(self, node, field, source),
        }

    # ---------------------------------------------------------------- structure
    def parse_steps(self, node: Node, field: str, depth: int = 0) -> list[Op]:
        """Parse a non-empty list of steps (``depth`` = number of enclosing repeats)."""
        items = self.reader.sequence(node, field, what="steps")
        ops: list[Op] = []
        for i, item in enumerate(items or ()):
            ops.extend(self._step(item, f"{field}[{i}]", depth))
        return ops

    def _step(self, node: Node, field: str, depth: int) -> list[Op]:
        kinds = ", ".join(STEP_KINDS)
        if not isinstance(node, MappingNode):
            self.reader.sink.add(
                node, field,
                f"each step must be a one-key mapping like 'hold: {{duration_s: 1}}', got {describe(node)}", kinds)
            return [LostTwistOp()]
        if len(node.value) != 1:
            names = ", ".join(repr(k.value) for k, _ in node.value if isinstance(k, ScalarNode))
            self.reader.sink.add(
                node, field,
                f"each step must be a one-key mapping (the step kind), got {len(node.value)} keys ({names}); "
                "split it into separate list items", kinds)
            return [LostTwistOp()]
        key_node, value_node = node.value[0]
        kind = key_node.value if isinstance(key_node, ScalarNode) and key_node.tag == STR_TAG else None
        if kind is None or kind not in self._handlers:
            shown = repr(kind) if kind is not None else describe(key_node)
            self.reader.sink.add(key_node, field, f"unknown step kind {shown}", kinds)
            return [LostTwistOp()]
        self._parsed += 1
        if self._parsed > MAX_PARSED_STEPS:
            if not self._too_many_reported:
                self._too_many_reported = True
                self.reader.sink.add(node, field, f"for_each loops expand to more than {MAX_PARSED_STEPS:,} steps",
                                     "fewer values or smaller loop bodies")
            return [LostTwistOp()]
        if kind != "for_each":  # a loop substitutes its values itself, its body step by step
            try:
                value_node = substitute(value_node, self.scope)
            except UnknownVariable as exc:
                self.reader.sink.add(exc.node, field, str(exc))
                return [LostTwistOp()] if kind in _MOVING_KINDS else []
        source = f"{self.basename}:{node.start_mark.line + 1}"
        ops = self._handlers[kind](value_node, f"{field}.{kind}", source, depth)
        if ops is None:
            return [LostTwistOp()] if kind in _MOVING_KINDS else []
        return ops

    # ---------------------------------------------------------------- helpers
    def _motion(self, fields: dict[str, Node], node: Node, field: str) -> tuple[float, float] | None:
        """Rate and accel of a move: its own keys, else the protocol defaults."""
        lim = self.limits
        rate = self._motion_value(
            fields, node, field, "rate_turns_per_s", "turns/s", lim.max_rate_turns_per_s,
            "max_rate_turns_per_s", self.defaults.rate_turns_per_s, self.defaults.rate_invalid)
        accel = self._motion_value(
            fields, node, field, "accel_turns_per_s2", "turns/s^2", lim.max_accel_turns_per_s2,
            "max_accel_turns_per_s2", self.defaults.accel_turns_per_s2, self.defaults.accel_invalid)
        return None if rate is None or accel is None else (rate, accel)

    def _motion_value(
        self, fields: dict[str, Node], node: Node, field: str, key: str, unit: str,
        limit: float | None, limit_name: str, default: float | None, default_invalid: bool,
    ) -> float | None:
        if key in fields:
            return self.reader.number(fields[key], f"{field}.{key}", unit, gt=0, le=limit, le_name=limit_name)
        if default is None and not default_invalid:
            self.reader.sink.add(node, f"{field}.{key}", f"missing {key} and no defaults.{key} is set",
                                 f"give {key} here or under defaults:")
        return default

    def _hold_after(self, fields: dict[str, Node], field: str) -> float | None:
        if "hold_s" not in fields:
            return None
        return self.reader.number(fields["hold_s"], f"{field}.hold_s", "s", ge=0, le=MAX_HOLD_S, le_name="7 days")

    def _voltage(self, node: Node, field: str) -> float | None:
        return self.reader.number(node, field, "V", ge=0, le=self.limits.max_heater_voltage_V,
                                  le_name="max_heater_voltage_V")

    # ---------------------------------------------------------------- step kinds
    def _move(self, node: Node, field: str, source: str, relative: bool) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("turns", *_MOTION_KEYS), required=("turns",))
        if fields is None:
            return None
        turns = self.reader.number(fields["turns"], f"{field}.turns", "turns") if "turns" in fields else None
        rate, accel = self._motion(fields, node, field) or _PLACEHOLDER_MOTION
        if turns is None:
            return None
        return [MoveOp(turns, relative, rate, accel, source, fields["turns"], f"{field}.turns")]

    def _move_to(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        return self._move(node, field, source, relative=False)

    def _move_by(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        return self._move(node, field, source, relative=True)

    def _hold(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("duration_s",), required=("duration_s",))
        if not fields or "duration_s" not in fields:
            return None
        duration = self.reader.number(fields["duration_s"], f"{field}.duration_s", "s", gt=0, le=MAX_HOLD_S,
                                      le_name="7 days")
        return None if duration is None else [ActionOp(Hold(duration), source)]

    def _heater(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("voltage_V",), required=("voltage_V",))
        if not fields or "voltage_V" not in fields:
            return None
        voltage = self._voltage(fields["voltage_V"], f"{field}.voltage_V")
        return None if voltage is None else [ActionOp(SetHeater(voltage), source)]

    def _sampling(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("period_s",), required=("period_s",))
        if not fields or "period_s" not in fields:
            return None
        period = self.reader.number(fields["period_s"], f"{field}.period_s", "s",
                                    ge=MIN_SAMPLING_PERIOD_S, le=MAX_SAMPLING_PERIOD_S)
        return None if period is None else [ActionOp(SetSampling(period), source)]

    def _prompt(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("text", "load_g"), required=("text",))
        if not fields or "text" not in fields:
            return None
        text = self.reader.string(fields["text"], f"{field}.text")
        load_node = fields.get("load_g")
        load: float | None = None
        if load_node is not None and load_node.tag != NULL_TAG:
            load = self.reader.number(load_node, f"{field}.load_g", "g", ge=0, le=MAX_LOAD_G,
                                      le_name="what a bench command carries")
            if load is None:
                return None
        return None if text is None else [ActionOp(Prompt(text, load), source)]

    def _rotation_sequence(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("targets_turns", "hold_s", *_MOTION_KEYS),
                                     required=("targets_turns", "hold_s"))
        if fields is None:
            return None
        hold = self._hold_after(fields, field)
        rate, accel = self._motion(fields, node, field) or _PLACEHOLDER_MOTION
        items = self.reader.sequence(fields["targets_turns"], f"{field}.targets_turns", "targets") \
            if "targets_turns" in fields else None
        if items is None:
            return None
        ops: list[Op] = []
        for j, item in enumerate(items):
            item_field = f"{field}.targets_turns[{j}]"
            turns = self.reader.number(item, item_field, "turns")
            if turns is None:
                ops.append(LostTwistOp())
                continue
            ops.append(MoveOp(turns, False, rate, accel, source, item, item_field))
            if hold:
                ops.append(ActionOp(Hold(hold), source))
        return ops

    def _voltage_steps(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("voltages_V", "hold_s"), required=("voltages_V", "hold_s"))
        if fields is None:
            return None
        hold = self._hold_after(fields, field)
        items = self.reader.sequence(fields["voltages_V"], f"{field}.voltages_V", "voltages") \
            if "voltages_V" in fields else None
        ops: list[Op] = []
        for j, item in enumerate(items or ()):
            voltage = self._voltage(item, f"{field}.voltages_V[{j}]")
            if voltage is not None:
                ops.append(ActionOp(SetHeater(voltage), source))
                if hold:
                    ops.append(ActionOp(Hold(hold), source))
        return ops if items is not None and hold is not None else None

    def _repeat(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("count", "steps"), required=("count", "steps"))
        if fields is None:
            return None
        if depth >= MAX_REPEAT_DEPTH:
            self.reader.sink.add(node, field, f"repeats nested more than {MAX_REPEAT_DEPTH} deep",
                                 f"at most {MAX_REPEAT_DEPTH} nested repeats")
            return None
        count = self.reader.integer(fields["count"], f"{field}.count", ge=1) if "count" in fields else None
        body = self.parse_steps(fields["steps"], f"{field}.steps", depth + 1) if "steps" in fields else []
        return [RepeatOp(count, tuple(body), source)]

    def _hold_until_settled(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        keys = ("max_duration_s", "window_s", "min_duration_s", "max_dR_dt_ohm_per_s", "max_dL_dt_mm_per_s")
        fields = self.reader.mapping(node, field, keys, required=("max_duration_s",))
        if not fields or "max_duration_s" not in fields:
            return None
        r = self.reader
        longest = r.number(fields["max_duration_s"], f"{field}.max_duration_s", "s", gt=0, le=MAX_HOLD_S,
                           le_name="7 days")
        window = DEFAULT_SETTLE_WINDOW_S if longest is None else min(DEFAULT_SETTLE_WINDOW_S, longest)
        if "window_s" in fields:
            window = r.number(fields["window_s"], f"{field}.window_s", "s", gt=0,
                              le=longest if longest is not None else MAX_HOLD_S, le_name="max_duration_s")
        shortest = window
        if "min_duration_s" in fields:
            shortest = r.number(fields["min_duration_s"], f"{field}.min_duration_s", "s", ge=0,
                                le=longest if longest is not None else MAX_HOLD_S, le_name="max_duration_s")
        thresholds = {}
        for key, unit in (("max_dR_dt_ohm_per_s", "ohm/s"), ("max_dL_dt_mm_per_s", "mm/s")):
            thresholds[key] = None
            if key in fields and fields[key].tag != NULL_TAG:
                thresholds[key] = r.number(fields[key], f"{field}.{key}", unit, gt=0)
                if thresholds[key] is None:
                    return None
        if all(v is None for v in thresholds.values()):
            r.sink.add(node, field, "give at least one settling threshold",
                       "max_dR_dt_ohm_per_s and/or max_dL_dt_mm_per_s")
            return None
        if longest is None or window is None or shortest is None:
            return None
        return [ActionOp(Settle(longest, window, shortest, thresholds["max_dR_dt_ohm_per_s"],
                                thresholds["max_dL_dt_mm_per_s"]), source)]

    def _for_each(self, node: Node, field: str, source: str, depth: int) -> list[Op] | None:
        fields = self.reader.mapping(node, field, ("variable", "values", "steps"),
                                     required=("variable", "values", "steps"))
        if fields is None:
            return None
        if depth >= MAX_REPEAT_DEPTH:
            self.reader.sink.add(node, field, f"loops nested more than {MAX_REPEAT_DEPTH} deep",
                                 f"at most {MAX_REPEAT_DEPTH} nested repeat/for_each blocks")
            return None
        name = self.reader.string(fields["variable"], f"{field}.variable") if "variable" in fields else None
        if name is not None and not NAME.match(name):
            self.reader.sink.add(fields["variable"], f"{field}.variable", f"{name!r} is not a variable name",
                                 "letters, digits and _, not starting with a digit")
            name = None
        values = self._loop_values(fields, field) if "values" in fields else None
        if name is None or values is None or "steps" not in fields:
            return None
        cost = len(values) * _steps_in(fields["steps"])
        if self._parsed + cost > MAX_PARSED_STEPS:  # refused before parsing: a loop bomb costs nothing
            self._too_many_reported = True
            self.reader.sink.add(node, field, f"for_each loops expand to more than {MAX_PARSED_STEPS:,} steps "
                                              f"(here about {self._parsed + cost:,})",
                                 "fewer values or smaller loop bodies")
            return None
        outer = self.scope
        bodies = []
        try:
            for value in values:
                self.scope = {**outer, name: value}
                bodies.append(tuple(self.parse_steps(fields["steps"], f"{field}.steps", depth + 1)))
        finally:
            self.scope = outer
        return [ForEachOp(tuple(bodies), source)]

    def _loop_values(self, fields: dict[str, Node], field: str) -> list[Value] | None:
        try:
            node = substitute(fields["values"], self.scope)
        except UnknownVariable as exc:
            self.reader.sink.add(exc.node, f"{field}.values", str(exc))
            return None
        items = self.reader.sequence(node, f"{field}.values", "values")
        if items is None:
            return None
        if len(items) > MAX_FOR_EACH_VALUES:
            self.reader.sink.add(node, f"{field}.values", f"{len(items):,} values",
                                 f"at most {MAX_FOR_EACH_VALUES:,}")
            return None
        out: list[Value] = []
        for j, item in enumerate(items):
            value = scalar_value(self.reader, item, f"{field}.values[{j}]")
            if value is None:
                return None
            out.append(value)
        return out


def _steps_in(node: Node) -> int:
    """Step nodes a steps list parses to, counting nested loops' values (an estimate from the
    nodes alone, before any substitution)."""
    from yaml import SequenceNode

    if not isinstance(node, SequenceNode):
        return 1
    total = 0
    for step in node.value:
        total += 1
        if isinstance(step, MappingNode) and len(step.value) == 1 and isinstance(step.value[0][1], MappingNode):
            kind = step.value[0][0].value if isinstance(step.value[0][0], ScalarNode) else ""
            inner = {k.value: v for k, v in step.value[0][1].value if isinstance(k, ScalarNode)}
            if kind in ("repeat", "for_each") and "steps" in inner:
                times = len(inner["values"].value) if kind == "for_each" and isinstance(
                    inner.get("values"), SequenceNode) else 1
                total += times * _steps_in(inner["steps"])
    return total


def scalar_value(reader: Reader, node: Node, field: str) -> Value | None:
    """A variable's value: a finite number, a boolean or a non-empty text (else an error)."""
    if isinstance(node, ScalarNode) and node.tag in (INT_TAG, FLOAT_TAG):
        number = reader.raw_number(node, field)
        if number is None:
            return None
        return int(number) if node.tag == INT_TAG and number.is_integer() else number
    if isinstance(node, ScalarNode) and node.tag == BOOL_TAG:
        return reader.plain_data(node, field)
    if isinstance(node, ScalarNode) and node.tag == STR_TAG:
        exp = reader.raw_number(node, field) if _looks_numeric(node) else None
        return exp if exp is not None else node.value
    reader.sink.add(node, field, f"expected a number or a text, got {describe(node)}", "a number or a text")
    return None


def _looks_numeric(node: ScalarNode) -> bool:
    return node.style is None and bool(EXPONENT_FLOAT.match(node.value))
