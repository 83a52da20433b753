"""Load, validate and compile a YAML protocol into a :class:`~tsa_bench.plan.model.Plan`.

Top-level keys: ``name`` (required), ``description``, ``metadata`` (free-form mapping),
``load_g`` (initial hanging mass, 0 .. 4294967.295 g), ``sampling_period_s`` (0.001 .. 60 s, default
0.1), ``limits`` (any subset of :class:`Limits` fields; may only tighten the bench),
``defaults`` (``rate_turns_per_s``, ``accel_turns_per_s2`` for moves lacking them; they may
use variables),
``variables`` (name: number or text, used as ``$name`` in steps, ``load_g`` and
``sampling_period_s``; see :mod:`tsa_bench.plan.variables`; a caller may give other values
for declared variables, as ``tsa-bench run --set NAME=VALUE`` does) and ``steps`` (required, non-empty; see
:mod:`tsa_bench.plan.steps`).

Contract: every problem found is raised together as one :class:`PlanErrors`; positions
come from the YAML node marks.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from yaml import MappingNode, Node

from tsa_bench.userfiles import DocumentError, parse_yaml, read_text_file
from tsa_bench.plan.compiler import compile_ops, outer_cycles
from tsa_bench.plan.errors import ErrorSink, PlanError, PlanErrors
from tsa_bench.benchdata.limits import Limits, loosening_problem
from tsa_bench.plan.model import Plan, Segments
from tsa_bench.plan.steps import (
    MAX_LOAD_G, MAX_SAMPLING_PERIOD_S, MIN_SAMPLING_PERIOD_S, MotionDefaults, StepParser, scalar_value,
)
from tsa_bench.plan.variables import NAME, UnknownVariable, Value, substitute
from tsa_bench.plan.yamlnodes import NULL_TAG, Reader

DEFAULT_SAMPLING_PERIOD_S = 0.1
TOP_LEVEL_KEYS: tuple[str, ...] = (
    "name", "description", "metadata", "load_g", "sampling_period_s", "limits", "defaults", "variables", "steps",
)
_REQUIRED_KEYS = ("name", "steps")
_UNIT = {
    "max_twist_turns": "turns",
    "min_twist_turns": "turns",
    "max_heater_voltage_V": "V",
    "max_rate_turns_per_s": "turns/s",
    "max_accel_turns_per_s2": "turns/s^2",
}


def load_plan(path: str | Path, limits: Limits, variables: dict[str, Value] | None = None) -> Plan:
    """Read and compile the protocol at ``path`` under the bench ``limits``; ``variables``
    replace the values of variables the protocol declares.

    Raises :class:`PlanErrors` for a missing/unreadable file or any protocol problem.
    """
    name = str(path)
    try:
        text = read_text_file(path, "protocol file")
    except DocumentError as exc:
        raise PlanErrors([_plan_error(exc)]) from None
    return _load(text, limits, name, name, variables)


def load_plan_text(text: str, limits: Limits, filename: str = "<string>",
                   variables: dict[str, Value] | None = None) -> Plan:
    """Compile protocol YAML given as text; ``filename`` is used in messages and segment sources."""
    return _load(text, limits, filename, None, variables)


def _plan_error(exc: DocumentError) -> PlanError:
    return PlanError(exc.file, exc.line, exc.column, "", exc.message)


def _compose(text: str, filename: str, sink: ErrorSink) -> Node | None:
    """The checked node graph of the hardened YAML reader (:mod:`tsa_bench.userfiles`)."""
    try:
        return parse_yaml(text, filename).root
    except DocumentError as exc:
        sink.errors.append(_plan_error(exc))
    return None


def _load(text: str, bench: Limits, filename: str, path: str | None, given: dict[str, Value] | None = None) -> Plan:
    sink = ErrorSink(filename)
    reader = Reader(sink)
    root = _compose(text, filename, sink)
    sink.raise_if_any()
    allowed_top = ", ".join(TOP_LEVEL_KEYS)
    if root is None:
        sink.add(yaml.error.Mark(filename, 0, 0, 0, None, None), "", "protocol is empty", allowed_top)
        sink.raise_if_any()
    if not isinstance(root, MappingNode):
        sink.add(root, "", "top level must be a mapping of protocol keys", allowed_top)
        sink.raise_if_any()
    top = reader.mapping(root, "", TOP_LEVEL_KEYS, _REQUIRED_KEYS) or {}

    name = reader.string(top["name"], "name") if "name" in top else None
    description = reader.string(top["description"], "description") if "description" in top else ""
    metadata = _metadata(reader, top.get("metadata"))
    variables = _variables(reader, top.get("variables"))
    _override(reader, root, top.get("variables"), variables, given or {})
    for key in ("load_g", "sampling_period_s"):
        if key in top:
            top[key] = _substituted(reader, top[key], variables, key) or top[key]
    load_g = None
    if "load_g" in top and top["load_g"].tag != NULL_TAG:
        load_g = reader.number(top["load_g"], "load_g", "g", ge=0, le=MAX_LOAD_G,
                               le_name="what a bench command carries")
    period_s: float | None = DEFAULT_SAMPLING_PERIOD_S
    if "sampling_period_s" in top:
        period_s = reader.number(top["sampling_period_s"], "sampling_period_s", "s",
                                 ge=MIN_SAMPLING_PERIOD_S, le=MAX_SAMPLING_PERIOD_S)
    limits = _protocol_limits(reader, top.get("limits"), bench)
    defaults = _defaults(reader, _substituted(reader, top.get("defaults"), variables, "defaults"), limits)

    segments = Segments.empty()
    cycles = 0
    if "steps" in top:
        ops = StepParser(reader, limits, defaults, filename, variables).parse_steps(top["steps"], "steps")
        segments = compile_ops(ops, limits, sink, top["steps"])
        cycles = outer_cycles(ops)
    sink.raise_if_any()
    assert name is not None and description is not None and period_s is not None
    return Plan(
        name=name,
        description=description,
        path=path,
        source_text=text,
        segments=segments,
        sampling_period_s=period_s,
        load_g=load_g,
        limits=limits,
        metadata=metadata,
        cycles=cycles,
    )


def _substituted(reader: Reader, node: Node | None, variables: dict[str, Value], field: str) -> Node | None:
    if node is None:
        return None
    try:
        return substitute(node, variables)
    except UnknownVariable as exc:
        reader.sink.add(exc.node, field, str(exc))
        return None


def _variables(reader: Reader, node: Node | None) -> dict[str, Value]:
    if node is None or node.tag == NULL_TAG:
        return {}
    out: dict[str, Value] = {}
    if not isinstance(node, MappingNode):
        reader.sink.add(node, "variables", "expected a mapping of name: value", "name: number or text")
        return out
    names = [k.value for k, _ in node.value if isinstance(k, yaml.ScalarNode)]
    fields = reader.mapping(node, "variables", names) or {}
    key_nodes = {k.value: k for k, _ in node.value if isinstance(k, yaml.ScalarNode)}
    for name, value_node in fields.items():
        if not NAME.match(name):
            reader.sink.add(key_nodes[name], f"variables.{name}", f"{name!r} is not a variable name",
                            "letters, digits and _, not starting with a digit")
            continue
        value = scalar_value(reader, value_node, f"variables.{name}")
        if value is not None:
            out[name] = value
    return out


def _override(reader: Reader, root: Node, node: Node | None, variables: dict[str, Value],
              given: dict[str, Value]) -> None:
    """Values given from outside replace declared ones; an undeclared name is an error."""
    for name, value in given.items():
        if name not in variables:
            declared = ", ".join(variables) or "none"
            reader.sink.add(node if node is not None else root, f"variables.{name}",
                            f"a value was given for {name}, which this protocol does not declare "
                            f"(it declares: {declared})")
        elif isinstance(value, bool) or not isinstance(value, (int, float, str)):
            reader.sink.add(node, f"variables.{name}", f"the value given for {name} must be a number or a text")
        else:
            variables[name] = value


def _metadata(reader: Reader, node: Node | None) -> dict[str, Any]:
    if node is None or node.tag == NULL_TAG:
        return {}
    if not isinstance(node, MappingNode):
        reader.sink.add(node, "metadata", "expected a mapping of free-form notes", "a mapping")
        return {}
    data = reader.plain_data(node, "metadata")
    return data if isinstance(data, dict) else {}


def _protocol_limits(reader: Reader, node: Node | None, bench: Limits) -> Limits:
    """Bench limits tightened by the protocol ``limits:``; the bench limits if that is invalid."""
    if node is None:
        return bench
    fields = reader.mapping(node, "limits", Limits.field_names())
    if fields is None:
        return bench
    before = len(reader.sink)
    proposed: dict[str, float] = {}
    for key, value_node in fields.items():
        field = f"limits.{key}"
        positive = key in ("max_rate_turns_per_s", "max_accel_turns_per_s2")
        value = reader.number(value_node, field, _UNIT[key], gt=0 if positive else None,
                              ge=0 if key == "max_heater_voltage_V" else None)
        if value is None:
            continue
        problem = loosening_problem(key, getattr(bench, key), value)
        if problem:
            bound = getattr(bench, key)
            side = ">=" if key == "min_twist_turns" else "<="
            reader.sink.add(value_node, field,
                            f"protocol limits may only tighten the bench limits: {problem}",
                            f"{side} {bound:g} {_UNIT[key]}")
            continue
        proposed[key] = value
    if len(reader.sink) > before:
        return bench
    try:
        return bench.tightened(proposed)
    except ValueError as exc:   # e.g. min_twist_turns above max_twist_turns
        reader.sink.add(node, "limits", str(exc))
        return bench


def _defaults(reader: Reader, node: Node | None, limits: Limits) -> MotionDefaults:
    if node is None:
        return MotionDefaults()
    fields = reader.mapping(node, "defaults", ("rate_turns_per_s", "accel_turns_per_s2"))
    if fields is None:
        return MotionDefaults(rate_invalid=True, accel_invalid=True)
    rate = accel = None
    if "rate_turns_per_s" in fields:
        rate = reader.number(fields["rate_turns_per_s"], "defaults.rate_turns_per_s", "turns/s", gt=0,
                             le=limits.max_rate_turns_per_s, le_name="max_rate_turns_per_s")
    if "accel_turns_per_s2" in fields:
        accel = reader.number(fields["accel_turns_per_s2"], "defaults.accel_turns_per_s2", "turns/s^2", gt=0,
                              le=limits.max_accel_turns_per_s2, le_name="max_accel_turns_per_s2")
    return MotionDefaults(
        rate_turns_per_s=rate,
        accel_turns_per_s2=accel,
        rate_invalid="rate_turns_per_s" in fields and rate is None,
        accel_invalid="accel_turns_per_s2" in fields and accel is None,
    )
