"""A JSON Schema (draft 2020-12) of the protocol format, for editors.

Contract: :func:`protocol_schema` describes what :func:`~tsa_bench.plan.load_plan`
accepts structurally: the top-level keys, every step kind with its required and
optional keys, and the types of their values (a number may also be a ``$variable``).
It is what an editor can check while typing; ranges that depend on the bench limits,
twist targets reached through ``move_by``, and the settling criterion's consistency are
left to ``tsa-bench validate``. ``configs/schema/protocol.schema.json`` is this schema
written out (``python3 scripts/gen_protocol_schema.py``); a test keeps them equal. Point
an editor at it, e.g. with the YAML language server::

    # yaml-language-server: $schema=../schema/protocol.schema.json
"""

from __future__ import annotations

import json
from typing import Any

from tsa_bench.benchdata.limits import Limits
from tsa_bench.plan.steps import MAX_FOR_EACH_VALUES, MAX_HOLD_S, MAX_LOAD_G, MAX_SAMPLING_PERIOD_S, \
    MIN_SAMPLING_PERIOD_S

SCHEMA_ID = "https://tsa-bench.invalid/schema/protocol.schema.json"
VARIABLE = {"type": "string", "pattern": r"^\$(\{[A-Za-z_][A-Za-z0-9_]*\}|[A-Za-z_][A-Za-z0-9_]*)$",
            "description": "a $variable (top-level variables: or an enclosing for_each)"}


def _num(description: str, **bounds: float) -> dict[str, Any]:
    return {"description": description, "anyOf": [{"type": "number", **bounds}, {"$ref": "#/$defs/variable"}]}


def _text(description: str) -> dict[str, Any]:
    return {"type": "string", "minLength": 1, "description": description}


_RATE = _num("motor rate, turns/s (default: defaults.rate_turns_per_s)", exclusiveMinimum=0)
_ACCEL = _num("acceleration and deceleration, turns/s^2 (default: defaults.accel_turns_per_s2)", exclusiveMinimum=0)

#: step kind -> (description, required keys, {key: schema})
STEPS: dict[str, tuple[str, tuple[str, ...], dict[str, Any]]] = {
    "move_to": ("move the motor to an absolute twist", ("turns",),
                {"turns": _num("target twist, turns (0 = untwisted start)"), "rate_turns_per_s": _RATE,
                 "accel_turns_per_s2": _ACCEL}),
    "move_by": ("move the motor by a twist relative to the previous target", ("turns",),
                {"turns": _num("twist change, turns"), "rate_turns_per_s": _RATE, "accel_turns_per_s2": _ACCEL}),
    "hold": ("keep everything as it is while sampling", ("duration_s",),
             {"duration_s": _num("s", exclusiveMinimum=0, maximum=MAX_HOLD_S)}),
    "hold_until_settled": (
        "hold until |dR/dt| and |dL/dt| over the last window_s are within the thresholds "
        "(not before min_duration_s, never after max_duration_s)", ("max_duration_s",),
        {"max_duration_s": _num("s", exclusiveMinimum=0, maximum=MAX_HOLD_S),
         "window_s": _num("slope window, s (default 30 or max_duration_s)", exclusiveMinimum=0),
         "min_duration_s": _num("s (default window_s)", minimum=0),
         "max_dR_dt_ohm_per_s": {"anyOf": [_num("ohm/s", exclusiveMinimum=0), {"type": "null"}]},
         "max_dL_dt_mm_per_s": {"anyOf": [_num("mm/s", exclusiveMinimum=0), {"type": "null"}]}}),
    "heater": ("set the heater voltage", ("voltage_V",), {"voltage_V": _num("V", minimum=0)}),
    "sampling": ("change the sampling period", ("period_s",),
                 {"period_s": _num("s", minimum=MIN_SAMPLING_PERIOD_S, maximum=MAX_SAMPLING_PERIOD_S)}),
    "prompt": ("pause for the operator", ("text",),
               {"text": _text("what the operator is asked to do"),
                "load_g": {"anyOf": [_num("new hanging mass, g", minimum=0, maximum=MAX_LOAD_G), {"type": "null"}]}}),
    "rotation_sequence": ("move to each target, holding hold_s after each", ("targets_turns", "hold_s"),
                          {"targets_turns": {"type": "array", "minItems": 1, "items": _num("turns")},
                           "hold_s": _num("s", minimum=0, maximum=MAX_HOLD_S), "rate_turns_per_s": _RATE,
                           "accel_turns_per_s2": _ACCEL}),
    "voltage_steps": ("set each voltage, holding hold_s after each", ("voltages_V", "hold_s"),
                      {"voltages_V": {"type": "array", "minItems": 1, "items": _num("V", minimum=0)},
                       "hold_s": _num("s", minimum=0, maximum=MAX_HOLD_S)}),
    "repeat": ("run the steps count times", ("count", "steps"),
               {"count": {"anyOf": [{"type": "integer", "minimum": 1}, {"$ref": "#/$defs/variable"}]},
                "steps": {"$ref": "#/$defs/steps"}}),
    "for_each": ("run the steps once per value, with $variable set to it", ("variable", "values", "steps"),
                 {"variable": {"type": "string", "pattern": r"^[A-Za-z_][A-Za-z0-9_]*$"},
                  "values": {"type": "array", "minItems": 1, "maxItems": MAX_FOR_EACH_VALUES,
                             "items": {"type": ["number", "string", "boolean"]}},
                  "steps": {"$ref": "#/$defs/steps"}}),
    "twist_heat": (
        "twist and heat at once: before each sub-move the heater is set to its voltage (docs/twist-heat.md)",
        ("targets_turns", "voltages_V"),
        {"targets_turns": {"type": "array", "minItems": 1, "items": _num("absolute sub-move target, turns")},
         "voltages_V": {"type": "array", "minItems": 1, "items": _num("heater voltage during that sub-move, V",
                                                                      minimum=0)},
         "hold_s": _num("dwell after each sub-move, s (default 0)", minimum=0, maximum=MAX_HOLD_S),
         "end_voltage_V": _num("heater voltage after the last sub-move, V (default: kept)", minimum=0),
         "rate_turns_per_s": _RATE, "accel_turns_per_s2": _ACCEL}),
    "track_length": (
        "closed-loop length control from resistance alone (self-sensing model; docs/control.md)", ("model",),
        {"model": _text("self-sensing model JSON from `tsa-bench fit self-sensing` (relative to the protocol)"),
         "length_mm": _num("one target length, mm", exclusiveMinimum=0),
         "hold_s": _num("keep the target this long once reached, s", minimum=0, maximum=MAX_HOLD_S),
         "targets": {"type": "array", "minItems": 1, "items": {
             "type": "object", "required": ["length_mm"], "additionalProperties": False,
             "properties": {"length_mm": _num("target length, mm", exclusiveMinimum=0),
                            "hold_s": _num("s", minimum=0, maximum=MAX_HOLD_S)}}},
         "tolerance_mm": _num("error at which a target counts as reached, mm (default 0.1)", exclusiveMinimum=0),
         "gain": _num("fraction of the error corrected per move (default 0.8)", exclusiveMinimum=0, maximum=1.5),
         "initial_mm_per_turn": _num("first guess of dL/dturn, mm/turn (default -0.8)"),
         "settle_s": _num("wait after each stop before judging, s (default 5)", exclusiveMinimum=0),
         "window_s": _num("estimate averaged over at most this much of a hold, s (default 10)", exclusiveMinimum=0),
         "max_step_turns": _num("largest single correction, turns (default 10)", exclusiveMinimum=0),
         "rate_turns_per_s": _RATE, "accel_turns_per_s2": _ACCEL,
         "timeout_s": _num("per target, s (default 180)", exclusiveMinimum=0),
         "on_timeout": {"enum": ["continue", "fail"]}}),
}


def _step(kind: str) -> dict[str, Any]:
    description, required, props = STEPS[kind]
    return {"type": "object", "description": description, "required": [kind], "additionalProperties": False,
            "properties": {kind: {"type": "object", "required": list(required), "additionalProperties": False,
                                  "properties": props}}}


def protocol_schema() -> dict[str, Any]:
    """The schema (module contract)."""
    limits = {name: {"type": "number"} for name in Limits.field_names()}
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "$id": SCHEMA_ID,
        "title": "tsa-bench protocol",
        "description": "An experiment for tsa-bench (README.md, host/tsa_bench/plan/). Generated from "
                       "host/tsa_bench/plan/schema.py; `tsa-bench validate` checks the rest.",
        "type": "object",
        "required": ["name", "steps"],
        "additionalProperties": False,
        "properties": {
            "name": _text("the protocol's name (run files are named after it)"),
            "description": {"type": "string"},
            "metadata": {"type": "object", "description": "free-form notes stored in the run file"},
            "load_g": {"anyOf": [{"type": "number", "minimum": 0, "maximum": MAX_LOAD_G}, {"type": "null"},
                                 {"$ref": "#/$defs/variable"}],
                       "description": "initial hanging mass, g"},
            "sampling_period_s": {"anyOf": [{"type": "number", "minimum": MIN_SAMPLING_PERIOD_S,
                                             "maximum": MAX_SAMPLING_PERIOD_S}, {"$ref": "#/$defs/variable"}]},
            "limits": {"type": "object", "additionalProperties": False, "properties": limits,
                       "description": "may only tighten the bench file's limits"},
            "defaults": {"type": "object", "additionalProperties": False,
                         "properties": {"rate_turns_per_s": _RATE, "accel_turns_per_s2": _ACCEL}},
            "variables": {"type": "object", "description": "name: value, used as $name in steps, load_g and "
                                                           "sampling_period_s (tsa-bench run --set name=value)",
                          "propertyNames": {"pattern": r"^[A-Za-z_][A-Za-z0-9_]*$"},
                          "additionalProperties": {"type": ["number", "string", "boolean"]}},
            "steps": {"$ref": "#/$defs/steps"},
        },
        "$defs": {
            "variable": VARIABLE,
            "steps": {"type": "array", "minItems": 1, "items": {"$ref": "#/$defs/step"}},
            "step": {"oneOf": [{"$ref": f"#/$defs/step_{kind}"} for kind in STEPS]},
            **{f"step_{kind}": _step(kind) for kind in STEPS},
        },
    }


def schema_text() -> str:
    """The schema as the JSON file holds it."""
    return json.dumps(protocol_schema(), indent=2) + "\n"
