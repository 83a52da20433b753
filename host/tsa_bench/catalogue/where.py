"""Search conditions: ``sample=S3``, ``load_g>=200``, ``plan~lifetime``, ``batch=B7``.

Contract: :func:`parse_condition` splits ``FIELD OP VALUE`` (operators ``>= <= != = > < ~``;
``~`` is "contains", case-insensitive) and checks it against :data:`~.schema.FIELDS`:
a number field takes a number, a time field a date or an ISO time (a date or a time
without a zone is local time), and ``<``/``>`` on a text field compare text. A name that
is not a field is a key of the run's metadata (``--meta KEY=VALUE``; ``meta.KEY`` says so
explicitly): ``=``, ``!=`` and ``~`` compare its text (in the database), the order
operators its number (:func:`matches`, in Python, so a value that is no number simply
does not match on every database). As in SQL, a row without the field matches no
condition on it. Bad input raises
:class:`WhereError` naming the condition.
"""

from __future__ import annotations

import datetime as dt
import re
from dataclasses import dataclass

from sqlalchemy import ColumnElement, and_, func

from tsa_bench.catalogue.schema import FIELDS, runs

OPERATORS = (">=", "<=", "!=", "=", ">", "<", "~")
_SPLIT = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_.-]*)\s*(>=|<=|!=|=|>|<|~)(.*)$")


class WhereError(ValueError):
    """A search condition that cannot be used; the message names it."""


@dataclass(frozen=True)
class Condition:
    field: str          # a column of FIELDS, or "meta.KEY"
    op: str
    value: object       # float, naive UTC datetime or text


def parse_time(text: str) -> dt.datetime:
    """A date (``2026-11-01``, local midnight) or ISO time as a naive UTC datetime; ValueError if neither."""
    value = dt.datetime.fromisoformat(text.strip())
    if value.tzinfo is None:
        value = value.astimezone()     # local time
    return value.astimezone(dt.timezone.utc).replace(tzinfo=None)


def parse_condition(expr: str) -> Condition:
    """``FIELD OP VALUE`` checked (module contract)."""
    m = _SPLIT.match(expr)
    if not m:
        raise WhereError(f"--where {expr!r}: expected FIELD OP VALUE with OP one of {' '.join(OPERATORS)} "
                         "(e.g. sample=S3, load_g>=200)")
    name, op, raw = m.group(1), m.group(2), m.group(3).strip()
    if name.startswith("meta."):
        return Condition(name, op, _meta_value(expr, name, op, raw))
    kind = FIELDS.get(name)
    if kind is None:
        return Condition(f"meta.{name}", op, _meta_value(expr, name, op, raw))
    if kind == "number":
        if op == "~":
            raise WhereError(f"--where {expr!r}: {name} is a number; use = != < <= > >=")
        try:
            return Condition(name, op, float(raw))
        except ValueError:
            raise WhereError(f"--where {expr!r}: {name} is a number, {raw!r} is not") from None
    if kind == "time":
        if op == "~":
            raise WhereError(f"--where {expr!r}: {name} is a time; use = != < <= > >=")
        try:
            return Condition(name, op, parse_time(raw))
        except ValueError:
            raise WhereError(f"--where {expr!r}: {name} is a time, {raw!r} is not a date (2026-11-01) "
                             "or an ISO time (2026-11-01T14:30)") from None
    return Condition(name, op, raw)


def _meta_value(expr: str, name: str, op: str, raw: str) -> object:
    if op in ("=", "!=", "~"):
        return raw
    try:
        return float(raw)
    except ValueError:
        raise WhereError(f"--where {expr!r}: {op} compares numbers and {raw!r} is not one "
                         f"({name} is a metadata key; = != ~ compare its text)") from None


def _compare(column, op: str, value) -> ColumnElement[bool]:
    if op == "~":
        text = str(value).replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")
        return func.lower(column).like(f"%{text.lower()}%", escape="\\")
    return {
        "=": lambda: column == value, "!=": lambda: column != value, ">": lambda: column > value,
        "<": lambda: column < value, ">=": lambda: column >= value, "<=": lambda: column <= value,
    }[op]()


def in_python(cond: Condition) -> bool:
    """Whether the condition is checked by :func:`matches` rather than in SQL."""
    return cond.field.startswith("meta.") and isinstance(cond.value, float)


def matches(cond: Condition, meta: dict) -> bool:
    """A numeric condition on a metadata key, for one row's metadata."""
    try:
        x = float(meta.get(cond.field[len("meta."):]))
    except (TypeError, ValueError):
        return False
    if x != x:
        return False
    y = float(cond.value)  # type: ignore[arg-type]
    return {"=": x == y, "!=": x != y, ">": x > y, "<": x < y, ">=": x >= y, "<=": x <= y}[cond.op]


def clause(cond: Condition) -> ColumnElement[bool]:
    """The SQL condition of one parsed condition (not one :func:`in_python` takes)."""
    if cond.field.startswith("meta."):
        return _compare(runs.c.meta[cond.field[len("meta."):]].as_string(), cond.op, cond.value)
    return _compare(runs.c[cond.field], cond.op, cond.value)


def clauses(conditions: list[Condition]) -> ColumnElement[bool] | None:
    """The SQL conditions at once (AND), or None for none."""
    parts = [clause(c) for c in conditions if not in_python(c)]
    return and_(*parts) if parts else None
