"""Typed reads from composed YAML nodes (``yaml.compose`` + SafeLoader).

Every read takes the node and its dotted field path; on a problem it records a
:class:`~tsa_bench.plan.errors.PlanError` at the node's position and returns ``None``,
so validation carries on and collects every error in one pass.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

from yaml import MappingNode, Node, ScalarNode, SequenceNode
from yaml.constructor import SafeConstructor

from tsa_bench.plan.errors import ErrorSink

INT_TAG = "tag:yaml.org,2002:int"
FLOAT_TAG = "tag:yaml.org,2002:float"
BOOL_TAG = "tag:yaml.org,2002:bool"
NULL_TAG = "tag:yaml.org,2002:null"
STR_TAG = "tag:yaml.org,2002:str"

# YAML 1.1 (PyYAML) resolves an unquoted "1e-3" to a string because it lacks a dot;
# a reader would call it a number, so plain scalars of that shape are accepted as floats.
_EXPONENT_FLOAT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")
EXPONENT_FLOAT = _EXPONENT_FLOAT
_CONSTRUCT = SafeConstructor()
_MAX_DEPTH = 32


def join(prefix: str, key: str) -> str:
    """Dotted path ``prefix.key`` (just ``key`` at the top level)."""
    return f"{prefix}.{key}" if prefix else key


def describe(node: Node) -> str:
    """Short human description of what a node holds, for 'expected X, got Y' messages."""
    if isinstance(node, MappingNode):
        return "a mapping"
    if isinstance(node, SequenceNode):
        return "a list"
    shown = node.value if len(node.value) <= 40 else node.value[:37] + "..."
    return {
        BOOL_TAG: f"boolean {shown!r}",
        NULL_TAG: "null",
        INT_TAG: f"integer {shown}",
        FLOAT_TAG: f"number {shown}",
        STR_TAG: f"string {shown!r}",
    }.get(node.tag, f"{node.tag} {shown!r}")


def _fmt(x: float) -> str:
    return f"{x:g}"


class Reader:
    """Validating accessors that report into one :class:`ErrorSink`."""

    def __init__(self, sink: ErrorSink) -> None:
        self.sink = sink

    def mapping(
        self,
        node: Node,
        field: str,
        allowed: Sequence[str],
        required: Sequence[str] = (),
    ) -> dict[str, Node] | None:
        """Read a mapping whose keys must be among ``allowed``; report unknown/duplicate/missing keys.

        Returns ``{key: value node}`` of the known keys, or ``None`` if ``node`` is not a mapping.
        """
        allowed_text = ", ".join(allowed)
        if not isinstance(node, MappingNode):
            self.sink.add(node, field, f"expected a mapping, got {describe(node)}", allowed_text)
            return None
        out: dict[str, Node] = {}
        seen: set[str] = set()
        for key_node, value_node in node.value:
            if not (isinstance(key_node, ScalarNode) and key_node.tag == STR_TAG):
                self.sink.add(key_node, field, f"keys must be names, got {describe(key_node)}", allowed_text)
                continue
            key = key_node.value
            if key in seen:
                self.sink.add(key_node, join(field, key), f"duplicate key {key!r}")
                continue
            seen.add(key)
            if key not in allowed:
                self.sink.add(key_node, join(field, key), f"unknown key {key!r}", allowed_text)
                continue
            out[key] = value_node
        for key in required:
            if key not in seen:
                self.sink.add(node, join(field, key), f"missing required key {key!r}", allowed_text)
        return out

    def sequence(self, node: Node, field: str, what: str = "items") -> list[Node] | None:
        """Read a non-empty list; ``what`` names its items in messages."""
        if not isinstance(node, SequenceNode):
            self.sink.add(node, field, f"expected a list of {what}, got {describe(node)}")
            return None
        if not node.value:
            self.sink.add(node, field, f"list of {what} must not be empty", f"at least one {what[:-1]}")
            return None
        return list(node.value)

    def string(self, node: Node, field: str) -> str | None:
        """Read a non-empty string (quoted or plain)."""
        if not (isinstance(node, ScalarNode) and node.tag == STR_TAG):
            self.sink.add(node, field, f"expected a string, got {describe(node)}", "text")
            return None
        if not node.value.strip():
            self.sink.add(node, field, "must not be empty", "non-empty text")
            return None
        return node.value

    def raw_number(self, node: Node, field: str) -> float | None:
        """Read a finite int or float (booleans, strings and null are refused)."""
        value: float | None = None
        if isinstance(node, ScalarNode):
            if node.tag == INT_TAG:
                value = float(_CONSTRUCT.construct_yaml_int(node))
            elif node.tag == FLOAT_TAG:
                value = float(_CONSTRUCT.construct_yaml_float(node))
            elif node.tag == STR_TAG and node.style is None and _EXPONENT_FLOAT.match(node.value):
                value = float(node.value)
        if value is None:
            hint = " (booleans are not numbers)" if node.tag == BOOL_TAG else ""
            if isinstance(node, ScalarNode) and node.tag == STR_TAG and node.style in ("'", '"'):
                hint = " (remove the quotes if a number was meant)"
            self.sink.add(node, field, f"expected a number, got {describe(node)}{hint}", "a finite number")
            return None
        if not math.isfinite(value):
            self.sink.add(node, field, f"must be finite, got {node.value}", "a finite number")
            return None
        return value

    def number(
        self,
        node: Node,
        field: str,
        unit: str,
        *,
        gt: float | None = None,
        ge: float | None = None,
        le: float | None = None,
        le_name: str | None = None,
        ge_name: str | None = None,
    ) -> float | None:
        """Read a finite number in unit ``unit`` and check the given bounds.

        ``le_name``/``ge_name`` name the limit a bound comes from, for the message.
        """
        value = self.raw_number(node, field)
        if value is None:
            return None
        low = f"> {_fmt(gt)}" if gt is not None else f">= {_fmt(ge)}" if ge is not None else ""
        high = f"<= {_fmt(le)}" if le is not None else ""
        allowed = " and ".join(p for p in (low, high) if p) + f" {unit}"
        if gt is not None and not value > gt:
            self.sink.add(node, field, f"must be > {_fmt(gt)} {unit}, got {_fmt(value)}", allowed)
            return None
        if ge is not None and value < ge:
            source = f" ({ge_name})" if ge_name else ""
            self.sink.add(node, field, f"must be >= {_fmt(ge)} {unit}{source}, got {_fmt(value)}", allowed)
            return None
        if le is not None and value > le:
            source = f" ({le_name})" if le_name else ""
            self.sink.add(node, field, f"must be <= {_fmt(le)} {unit}{source}, got {_fmt(value)}", allowed)
            return None
        return value

    def integer(self, node: Node, field: str, *, ge: int) -> int | None:
        """Read an integer >= ``ge`` (floats such as 2.5 or 2.0 are refused)."""
        if not (isinstance(node, ScalarNode) and node.tag == INT_TAG):
            self.sink.add(node, field, f"expected an integer, got {describe(node)}", f"integer >= {ge}")
            return None
        value = int(_CONSTRUCT.construct_yaml_int(node))
        if value < ge:
            self.sink.add(node, field, f"must be >= {ge}, got {value}", f"integer >= {ge}")
            return None
        return value

    def plain_data(self, node: Node, field: str, depth: int = 0) -> Any:
        """Convert free-form YAML to JSON-compatible Python (dict/list/str/int/float/bool/None).

        Reports (and drops) non-string keys, non-finite floats and other YAML types such
        as timestamps or binary.
        """
        if depth > _MAX_DEPTH:
            self.sink.add(node, field, f"nested deeper than {_MAX_DEPTH} levels")
            return None
        if isinstance(node, MappingNode):
            out: dict[str, Any] = {}
            for key_node, value_node in node.value:
                if not (isinstance(key_node, ScalarNode) and key_node.tag == STR_TAG):
                    self.sink.add(key_node, field, f"keys must be strings, got {describe(key_node)}")
                    continue
                out[key_node.value] = self.plain_data(value_node, join(field, key_node.value), depth + 1)
            return out
        if isinstance(node, SequenceNode):
            return [self.plain_data(v, f"{field}[{i}]", depth + 1) for i, v in enumerate(node.value)]
        if node.tag == INT_TAG:
            return int(_CONSTRUCT.construct_yaml_int(node))
        if node.tag == FLOAT_TAG:
            return self.raw_number(node, field)
        if node.tag == BOOL_TAG:
            return bool(_CONSTRUCT.construct_yaml_bool(node))
        if node.tag == NULL_TAG:
            return None
        if node.tag == STR_TAG:
            return node.value
        allowed = "string, number, boolean, null, list, mapping"
        self.sink.add(node, field, f"unsupported value {describe(node)}", allowed)
        return None
