"""Protocol variables: ``$name`` references in step values, resolved on the YAML nodes.

Contract: a scalar that is exactly ``$name`` (or ``${name}``) becomes the variable's
value with its type (a number stays a number: ``turns: $t``). Inside longer text,
``$name`` and ``${name}`` are replaced by the value as text (numbers as ``%g``), and
``$$`` is a literal ``$``. A ``$`` not followed by a name (``$5``, a lone ``$``) is
left as it is. Names are identifiers (letters, digits, ``_``; not starting with a
digit). Variables come from the protocol's top-level ``variables:`` mapping and from
``for_each`` loops (the innermost definition wins). Substituted nodes keep the
position of the reference, so every later error still points into the file.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from yaml import MappingNode, Node, ScalarNode, SequenceNode

from tsa_bench.plan.yamlnodes import BOOL_TAG, FLOAT_TAG, INT_TAG, STR_TAG

NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_WHOLE = re.compile(r"^\$(?:([A-Za-z_][A-Za-z0-9_]*)|\{([A-Za-z_][A-Za-z0-9_]*)\})$")
_REF = re.compile(r"\$\$|\$\{([A-Za-z_][A-Za-z0-9_]*)\}|\$([A-Za-z_][A-Za-z0-9_]*)")

Value = int | float | str | bool


class UnknownVariable(Exception):
    """A ``$name`` with no definition in scope; ``node`` is where it is written."""

    def __init__(self, node: Node, name: str, known: list[str]) -> None:
        self.node, self.name, self.known = node, name, known
        shown = ", ".join(f"${k}" for k in known) or "none"
        super().__init__(f"unknown variable ${name} (defined here: {shown}; write $$ for a literal $)")


def as_text(value: Value) -> str:
    """A variable's value written into text."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def _typed(node: ScalarNode, value: Value) -> ScalarNode:
    if isinstance(value, bool):
        tag, text = BOOL_TAG, as_text(value)
    elif isinstance(value, int):
        tag, text = INT_TAG, str(value)
    elif isinstance(value, float):
        tag, text = FLOAT_TAG, repr(value)
    else:
        tag, text = STR_TAG, value
    return ScalarNode(tag, text, node.start_mark, node.end_mark, style="'" if tag == STR_TAG else None)


def _has_reference(node: Node) -> bool:
    if isinstance(node, ScalarNode):
        return "$" in node.value
    if isinstance(node, SequenceNode):
        return any(_has_reference(v) for v in node.value)
    if isinstance(node, MappingNode):
        return any(_has_reference(v) for _, v in node.value)
    return False


def substitute(node: Node, scope: Mapping[str, Value]) -> Node:
    """``node`` with every reference resolved (the same node when it holds none).

    Raises :class:`UnknownVariable` for the first reference without a definition.
    Mapping keys are never substituted.
    """
    if not _has_reference(node):
        return node
    if isinstance(node, SequenceNode):
        return SequenceNode(node.tag, [substitute(v, scope) for v in node.value], node.start_mark,
                            node.end_mark, flow_style=node.flow_style)
    if isinstance(node, MappingNode):
        return MappingNode(node.tag, [(k, substitute(v, scope)) for k, v in node.value], node.start_mark,
                           node.end_mark, flow_style=node.flow_style)
    assert isinstance(node, ScalarNode)
    whole = _WHOLE.match(node.value)
    if whole and node.style is None:  # a plain `$name` takes the value's type
        name = whole.group(1) or whole.group(2)
        if name not in scope:
            raise UnknownVariable(node, name, sorted(scope))
        return _typed(node, scope[name])

    def replace(m: re.Match) -> str:
        if m.group(0) == "$$":
            return "$"
        name = m.group(1) or m.group(2)
        if name not in scope:
            raise UnknownVariable(node, name, sorted(scope))
        return as_text(scope[name])

    text = _REF.sub(replace, node.value)
    return ScalarNode(STR_TAG, text, node.start_mark, node.end_mark, style="'")
