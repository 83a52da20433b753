"""Hardened YAML: one parse for every YAML file a person writes, safe on any input.

Contract of :func:`parse_yaml` / :func:`read_yaml`: the text is composed with PyYAML's
safe loader into a node graph (positions kept) and refused, with a
:class:`~tsa_bench.userfiles.errors.DocumentError` ``"file:line:col: message"``, when

* it is larger than ``max_bytes`` or not strict UTF-8 (files only), or not valid YAML;
* collections nest deeper than ``max_depth``, counted as written and again with
  aliases expanded (so no reader of the document can run out of stack);
* it holds more than ``max_nodes`` values as written (counted on the parser's events,
  with LibYAML's C parser when present, before anything is built: a 2 MB list of a
  million numbers is refused in a fraction of a second, not after building it);
* aliases expand it to more than ``max_nodes`` nodes (an "alias bomb" of a few hundred
  bytes would otherwise become gigabytes for any reader that walks it), or an alias
  refers to a collection that contains it (a cycle);
* a scalar holds a lone surrogate (``"\\ud800"``: text that no file or terminal can
  encode) or an integer of more than ``max_int_digits`` digits;
* it holds more than one document.

The checked :class:`YamlDocument` keeps the node graph (``root``) for readers that
report errors against nodes (the protocol reader does), and :meth:`YamlDocument.data`
converts it to plain Python (dict with text keys, list, str, int, float, bool, None;
an unquoted ``1e-3``, which YAML 1.1 leaves as text, is a number),
refusing duplicate keys, non-text keys, non-finite numbers and every tag that is not
plain YAML data (timestamps, binary, sets, ``!!python/...``, custom ``!tags``); merge
keys (``<<: *defaults``) are honoured.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from yaml import MappingNode, Node, ScalarNode, SequenceNode
from yaml.constructor import SafeConstructor
from yaml.error import Mark

from tsa_bench.userfiles.errors import DocumentError, position_of
from tsa_bench.userfiles.files import MAX_TEXT_BYTES, decode_text, read_bytes_file

STR, INT, FLOAT, BOOL, NULL = (f"tag:yaml.org,2002:{t}" for t in ("str", "int", "float", "bool", "null"))
SEQ, MAP, MERGE = "tag:yaml.org,2002:seq", "tag:yaml.org,2002:map", "tag:yaml.org,2002:merge"
_CONSTRUCT = SafeConstructor()
# YAML 1.1 (PyYAML) resolves an unquoted "1e-3" to text because it lacks a dot; a person
# means a number, so plain scalars of that shape are read as numbers (as by the protocol reader).
_EXPONENT_FLOAT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


@dataclass(frozen=True)
class YamlLimits:
    """What a document may hold. The defaults are far above any hand-written file."""

    max_bytes: int = MAX_TEXT_BYTES
    max_depth: int = 64
    max_nodes: int = 200_000
    max_int_digits: int = 40


def _has_surrogate(text: str) -> int:
    """Index of the first lone surrogate in ``text``, or -1."""
    for i, ch in enumerate(text):
        if "\ud800" <= ch <= "\udfff":
            return i
    return -1


class _Loader(yaml.SafeLoader):
    """The safe loader with nesting and size limits enforced while composing (before recursing)."""

    def __init__(self, text: str, max_depth: int, max_nodes: int) -> None:
        super().__init__(text)
        self._depth = 0
        self._max_depth = max_depth
        self._nodes = 0
        self._max_nodes = max_nodes

    def compose_node(self, parent: Node | None, index: Any) -> Node:  # type: ignore[override]
        if self._depth >= self._max_depth and not self.check_event(yaml.AliasEvent, yaml.ScalarEvent):
            raise _TooDeep(self.peek_event().start_mark)
        self._nodes += 1
        if self._nodes > self._max_nodes:
            raise _TooMany(self.peek_event().start_mark)
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


class _TooDeep(Exception):
    def __init__(self, mark: Mark) -> None:
        super().__init__()
        self.mark = mark


class _TooMany(Exception):
    """More values than the limit, as written."""

    def __init__(self, mark: Mark) -> None:
        super().__init__()
        self.mark = mark


_VALUE_EVENTS = (yaml.ScalarEvent, yaml.SequenceStartEvent, yaml.MappingStartEvent, yaml.AliasEvent)


def _count_values(text: str, limit: int) -> None:
    """_TooMany past ``limit`` values, counted on LibYAML's events (fast, nothing built); a
    syntax error is left to the composer, which words it. Without LibYAML, the composer counts."""
    if not getattr(yaml, "__with_libyaml__", False):
        return
    n = 0
    try:
        for event in yaml.parse(text, Loader=yaml.CSafeLoader):
            if isinstance(event, _VALUE_EVENTS):
                n += 1
                if n > limit:
                    raise _TooMany(event.start_mark)
    except yaml.YAMLError:
        return


def describe(node: Node) -> str:
    """Short description of a node for messages ("a mapping", "integer 3", ...)."""
    if isinstance(node, MappingNode):
        return "a mapping"
    if isinstance(node, SequenceNode):
        return "a list"
    shown = node.value if len(node.value) <= 40 else node.value[:37] + "..."
    return {BOOL: f"boolean {shown!r}", NULL: "null", INT: f"integer {shown}", FLOAT: f"number {shown}",
            STR: f"text {shown!r}"}.get(node.tag, f"{node.tag} {shown!r}")


class YamlDocument:
    """A checked YAML document: its text, its node graph and plain data on demand."""

    def __init__(self, filename: str, text: str, root: Node | None) -> None:
        self.filename = filename
        self.text = text
        self.root = root

    # -- positions -----------------------------------------------------------
    def error(self, at: Node | Mark | None, message: str) -> DocumentError:
        """A DocumentError at a node (its start), a mark, or the file (None)."""
        mark = at.start_mark if isinstance(at, Node) else at
        if mark is None:
            return DocumentError(self.filename, None, None, message)
        return DocumentError(self.filename, mark.line + 1, mark.column + 1, message)

    def node(self, *keys: str | int) -> Node | None:
        """The node at a key path (text keys in mappings, indices in lists), or None."""
        node = self.root
        for key in keys:
            if isinstance(node, MappingNode) and isinstance(key, str):
                node = next((v for k, v in node.value if isinstance(k, ScalarNode) and k.value == key), None)
            elif isinstance(node, SequenceNode) and isinstance(key, int) and 0 <= key < len(node.value):
                node = node.value[key]
            else:
                return None
        return node

    def where(self, *keys: str | int) -> str:
        """``"file:line:col"`` of the value at a key path (its deepest existing part)."""
        for n in range(len(keys), -1, -1):
            node = self.node(*keys[:n])
            if node is not None:
                return self.error(node, "").where
        return self.filename

    # -- plain data ----------------------------------------------------------
    def data(self, *, allow_nonfinite: bool = False) -> Any:
        """The document as plain Python; DocumentError for anything that is not plain data."""
        return None if self.root is None else self._data(self.root, allow_nonfinite)

    def _data(self, node: Node, nonfinite: bool) -> Any:
        if isinstance(node, MappingNode):
            if node.tag != MAP:
                raise self.error(node, f"unsupported tag {node.tag} on a mapping (plain YAML data only)")
            out: dict[str, Any] = {}
            merged: dict[str, Any] = {}
            for key_node, value_node in node.value:
                if key_node.tag == MERGE:
                    for part in (value_node.value if isinstance(value_node, SequenceNode) else [value_node]):
                        value = self._data(part, nonfinite)
                        if not isinstance(value, dict):
                            raise self.error(part, f"a merge key (<<) takes a mapping, got {describe(part)}")
                        for k, v in value.items():
                            merged.setdefault(k, v)
                    continue
                if not (isinstance(key_node, ScalarNode) and key_node.tag == STR):
                    raise self.error(key_node, f"keys must be text, got {describe(key_node)}")
                if key_node.value in out:
                    raise self.error(key_node, f"duplicate key {key_node.value!r}")
                out[key_node.value] = self._data(value_node, nonfinite)
            return {**merged, **out}
        if isinstance(node, SequenceNode):
            if node.tag != SEQ:
                raise self.error(node, f"unsupported tag {node.tag} on a list (plain YAML data only)")
            return [self._data(v, nonfinite) for v in node.value]
        if node.tag == STR:
            if node.style is None and _EXPONENT_FLOAT.match(node.value):
                return self._data(ScalarNode(FLOAT, node.value, node.start_mark, node.end_mark), nonfinite)
            return node.value
        if node.tag == INT:
            return int(_CONSTRUCT.construct_yaml_int(node))
        if node.tag == FLOAT:
            value = float(_CONSTRUCT.construct_yaml_float(node))
            if not nonfinite and not math.isfinite(value):
                raise self.error(node, f"must be a finite number, got {node.value}")
            return value
        if node.tag == BOOL:
            return bool(_CONSTRUCT.construct_yaml_bool(node))
        if node.tag == NULL:
            return None
        hint = " (quote it to make it text)" if node.tag.endswith(":timestamp") else ""
        raise self.error(node, f"unsupported value {describe(node)}{hint}; allowed: text, number, "
                               "boolean, null, list, mapping")


def _check_graph(doc: YamlDocument, limits: YamlLimits) -> None:
    """Scalars, cycles, expanded size and depth of the node graph (iterative, memoised)."""
    root = doc.root
    if root is None:
        return
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    grey: set[int] = set()
    stack: list[tuple[Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            grey.discard(key)
            kids = _children(node)
            size[key] = 1 + sum(size[id(k)] for k in kids)
            depth[key] = 1 + max((depth[id(k)] for k in kids), default=0)
            if size[key] > limits.max_nodes:
                raise doc.error(node, f"aliases expand this to more than {limits.max_nodes:,} values "
                                      f"(limit {limits.max_nodes:,}); write the values out or use fewer aliases")
            if depth[key] > limits.max_depth:
                raise doc.error(node, f"nested more than {limits.max_depth} levels deep once aliases are "
                                      f"expanded (limit {limits.max_depth})")
            continue
        if key in size:
            continue
        if key in grey:
            raise doc.error(node, "an alias refers to a collection that contains it (a cycle)")
        if isinstance(node, ScalarNode):
            _check_scalar(doc, node, limits)
            size[key], depth[key] = 1, 0
            continue
        grey.add(key)
        stack.append((node, True))
        for child in _children(node):
            if id(child) in grey:
                raise doc.error(child, "an alias refers to a collection that contains it (a cycle)")
            if id(child) not in size:
                stack.append((child, False))


def _children(node: Node) -> list[Node]:
    if isinstance(node, MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, SequenceNode):
        return list(node.value)
    return []


def _check_scalar(doc: YamlDocument, node: ScalarNode, limits: YamlLimits) -> None:
    bad = _has_surrogate(node.value)
    if bad >= 0:
        raise doc.error(node, f"text holds a lone surrogate U+{ord(node.value[bad]):04X} (an escape such as "
                              "\\ud800 that is not a character); write the character itself")
    if node.tag == INT:
        digits = sum(ch.isdigit() for ch in node.value)
        if digits > limits.max_int_digits:
            raise doc.error(node, f"integer of {digits} digits is too large (at most {limits.max_int_digits})")


def parse_yaml(text: str, filename: str = "<string>", limits: YamlLimits = YamlLimits()) -> YamlDocument:
    """Compose and check YAML text; raise DocumentError (see the module contract)."""
    if len(text) > limits.max_bytes:
        raise DocumentError(filename, None, None, f"more than {limits.max_bytes:,} characters")
    bad = _has_surrogate(text)
    if bad >= 0:
        line, column = position_of(text, bad)
        raise DocumentError(filename, line, column, "text holds a lone surrogate (not a character)")
    loader: _Loader | None = None
    try:
        _count_values(text, limits.max_nodes)
        loader = _Loader(text, limits.max_depth, limits.max_nodes)
        root = loader.get_single_node()
    except _TooMany as exc:
        raise DocumentError(filename, exc.mark.line + 1, exc.mark.column + 1,
                            f"holds more than {limits.max_nodes:,} values (lists, mappings and scalars as written; "
                            f"limit {limits.max_nodes:,}): far more than any setting needs") from None
    except _TooDeep as exc:
        raise DocumentError(filename, exc.mark.line + 1, exc.mark.column + 1,
                            f"nested more than {limits.max_depth} levels deep (limit {limits.max_depth})") from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        detail = "; ".join(p for p in (exc.context, exc.problem) if p) or "invalid YAML"
        if mark is None:
            raise DocumentError(filename, None, None, f"YAML syntax error: {detail}") from None
        raise DocumentError(filename, mark.line + 1, mark.column + 1, f"YAML syntax error: {detail}") from None
    except yaml.reader.ReaderError as exc:
        line, column = position_of(text, exc.position)
        raise DocumentError(filename, line, column,
                            f"YAML error: character U+{exc.character:04X} is not allowed in YAML text"
                            if isinstance(exc.character, int) else f"YAML error: {exc.reason}") from None
    except yaml.YAMLError as exc:
        raise DocumentError(filename, None, None, f"YAML error: {exc}") from None
    finally:
        if loader is not None:
            loader.dispose()
    doc = YamlDocument(filename, text, root)
    _check_graph(doc, limits)
    return doc


def read_yaml(path: str | Path, *, what: str = "file", limits: YamlLimits = YamlLimits()) -> YamlDocument:
    """Read a regular file (bounded, strict UTF-8) and :func:`parse_yaml` it."""
    name = str(path)
    return parse_yaml(decode_text(read_bytes_file(path, what, limits.max_bytes), name), name, limits)
