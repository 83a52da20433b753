"""The thesis's measurements as records: read and check ``configs/thesis/*.yaml``.

Units: every record carries its own unit (:mod:`tsa_bench.units`); values are kept as
printed, converted only when compared.

Contract: :func:`load_records` reads one or more record files (docs/thesis-records.md)
and returns :class:`Record` s in file order. A file holds ``chapter``, ``title``,
optional ``bases`` (short names for long agreement or not-simulated texts), optional
``defaults`` (keys merged into every record, mappings key by key) and ``records``.
Every record needs ``id`` (unique over all files), ``quantity``, ``value`` (a number,
or ``[low, high]`` for a reported range), ``unit``, ``conditions`` and ``source``
(with at least ``section``), and exactly one of ``measure`` (how the reproduction
computes the quantity, :data:`tsa_bench.reproduce.measures.MEASURES`) or
``not_simulated`` (why it cannot). A record compared as ``=`` (the default relation)
needs a ``tolerance`` (``abs``, ``rel``, ``factor`` or ``sd: true`` with a ``basis``) or
an ``uncertainty`` (``sd``, ``rounding`` or ``read_off``) to judge agreement by.
The unit must parse and, when a measure is given, have the dimension of what the
measure computes. Every problem raises :class:`RecordsError` listing each as
``file:line:col: field: message``; nothing is half-loaded.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from yaml import Node

from tsa_bench.userfiles import DocumentError, read_yaml
from tsa_bench.plan.errors import ErrorSink, PlanError
from tsa_bench.plan.yamlnodes import Reader, describe
from tsa_bench.units import UnitError, parse_unit

ROOT = Path(__file__).resolve().parents[3]
RECORDS_DIR = ROOT / "configs" / "thesis"

FILE_KEYS = ("chapter", "title", "bases", "defaults", "records")
RECORD_KEYS = ("id", "quantity", "value", "unit", "relation", "uncertainty", "tolerance", "conditions", "source",
               "measure", "not_simulated", "reading", "derived", "note")
CONDITION_KEYS = ("strings", "ply", "scheme", "load_g", "twist_turns", "voltage_V", "step_s", "cycles", "input",
                  "output", "model", "set", "tsa", "setpoint_deg")
SOURCE_KEYS = ("section", "table", "figure", "equation", "note")
RELATIONS = ("=", "~", "<", ">", "<=", ">=")
UNCERTAINTY_KINDS = ("sd", "rounding", "read_off")
TOLERANCE_KINDS = ("abs", "rel", "factor", "sd")
_ID = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


class RecordsError(ValueError):
    """Record files that cannot be used; ``str()`` lists every problem with file:line:col."""

    def __init__(self, errors: list[PlanError]) -> None:
        self.errors = errors
        super().__init__("\n".join(str(e) for e in errors))


@dataclass(frozen=True)
class Record:
    """One reported measurement (module contract). ``value`` is None for a range."""

    id: str
    quantity: str
    unit: str
    value: float | None
    range: tuple[float, float] | None
    relation: str
    conditions: dict[str, Any]
    source: dict[str, str]
    file: str
    line: int
    chapter: int
    uncertainty: dict[str, float] = field(default_factory=dict)
    tolerance: dict[str, Any] = field(default_factory=dict)
    measure: dict[str, Any] | None = None
    not_simulated: str | None = None
    reading: str = ""
    derived: str = ""
    note: str = ""

    @property
    def source_text(self) -> str:
        """'3.1.4, Table 3.1, Fig. 3.1(a), eq. 3.5' style reference."""
        s = self.source
        parts = [s["section"]]
        for key, label in (("table", "Table"), ("figure", "Fig."), ("equation", "eq.")):
            if s.get(key):
                parts.append(f"{label} {s[key]}")
        return ", ".join(parts)

    @property
    def shown_value(self) -> str:
        """The value as reported, with its relation and unit."""
        if self.range is not None:
            return f"{self.range[0]:g}-{self.range[1]:g} {self.unit}"
        rel = "" if self.relation == "=" else f"{self.relation} "
        sd = f" +- {self.uncertainty['sd']:g}" if "sd" in self.uncertainty else ""
        return f"{rel}{self.value:g}{sd} {self.unit}"


def read_document(path: Path, what: str, sink: ErrorSink) -> Node | None:
    """The file's YAML node graph through the one hardened reader (tsa_bench.userfiles), or None
    with the problem (file:line:col) recorded in ``sink``."""
    try:
        return read_yaml(path, what=what).root
    except DocumentError as exc:
        sink.errors.append(PlanError(exc.file, exc.line, exc.column, "", exc.message))
        return None


def _merge(defaults: dict[str, Any], rec: dict[str, Any]) -> dict[str, Any]:
    out = dict(defaults)
    for k, v in rec.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = {**out[k], **v}
        else:
            out[k] = v
    return out


class _FileReader:
    """Reads one record file into Records, reporting into a shared sink."""

    def __init__(self, path: Path, sink: ErrorSink, seen: dict[str, str]) -> None:
        self.path = path
        self.sink = sink
        self.reader = Reader(sink)
        self.seen = seen

    def read(self) -> list[Record]:
        root = read_document(self.path, "thesis record file", self.sink)
        if root is None:
            if not self.sink:
                self.sink.add(None, "", "the file is empty", ", ".join(FILE_KEYS))
            return []
        top = self.reader.mapping(root, "", FILE_KEYS, ("chapter", "records")) or {}
        chapter = self.reader.integer(top["chapter"], "chapter", ge=1) if "chapter" in top else None
        bases = self.reader.plain_data(top["bases"], "bases") if "bases" in top else {}
        if not isinstance(bases, dict) or not all(isinstance(v, str) for v in bases.values()):
            self.sink.add(top["bases"], "bases", "expected a mapping of name: text")
            bases = {}
        defaults_node = top.get("defaults")
        defaults: dict[str, Any] = {}
        if defaults_node is not None:
            dm = self.reader.mapping(defaults_node, "defaults", RECORD_KEYS)
            if dm is not None:
                defaults = {k: self.reader.plain_data(v, f"defaults.{k}") for k, v in dm.items()}
        items = self.reader.sequence(top["records"], "records", "records") if "records" in top else None
        out = []
        for i, node in enumerate(items or []):
            rec = self._record(node, f"records[{i}]", defaults, bases, chapter or 0)
            if rec is not None:
                out.append(rec)
        return out

    def _record(self, node: Node, where: str, defaults: dict[str, Any], bases: dict[str, str],
                chapter: int) -> Record | None:
        from tsa_bench.reproduce.measures import MEASURES, MeasureError, measure_unit

        m = self.reader.mapping(node, where, RECORD_KEYS)
        if m is None:
            return None
        n_err = len(self.sink)
        raw = _merge(defaults, {k: self.reader.plain_data(v, f"{where}.{k}") for k, v in m.items()})
        nodes = {k: m.get(k, node) for k in RECORD_KEYS}

        def need(key: str) -> Any:
            if key not in raw:
                self.sink.add(node, f"{where}.{key}", f"missing required key {key!r}")
            return raw.get(key)

        rid = need("id")
        if rid is not None and (not isinstance(rid, str) or not _ID.match(rid)):
            self.sink.add(nodes["id"], f"{where}.id", f"expected an id of letters, digits, '.', '_', '-', got {rid!r}")
            rid = None
        if rid is not None:
            if rid in self.seen:
                self.sink.add(nodes["id"], f"{where}.id", f"duplicate id {rid!r} (first in {self.seen[rid]})")
            else:
                self.seen[rid] = f"{self.path}:{node.start_mark.line + 1}"
        where = f"{where} ({rid})" if rid else where
        quantity = need("quantity")
        if quantity is not None and (not isinstance(quantity, str) or not quantity.strip()):
            self.sink.add(nodes["quantity"], f"{where}.quantity", "expected a description of what was measured")
        value, rng = None, None
        v = need("value")
        if isinstance(v, list):
            if len(v) == 2 and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v) and v[0] < v[1]:
                rng = (float(v[0]), float(v[1]))
            else:
                self.sink.add(nodes["value"], f"{where}.value", f"a range is [low, high] with low < high, got {v!r}")
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            value = float(v)
        elif v is not None:
            self.sink.add(nodes["value"], f"{where}.value", f"expected a number or [low, high], got {v!r}")
        unit = need("unit")
        parsed = None
        if unit is not None:
            try:
                parsed = parse_unit(str(unit))
            except UnitError as exc:
                self.sink.add(nodes["unit"], f"{where}.unit", str(exc))
        relation = raw.get("relation", "=")
        if relation not in RELATIONS:
            self.sink.add(nodes["relation"], f"{where}.relation", f"unknown relation {relation!r}", ", ".join(RELATIONS))
            relation = "="
        unc = raw.get("uncertainty") or {}
        if not isinstance(unc, dict) or set(unc) - set(UNCERTAINTY_KINDS) or len(unc) > 1 or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and x >= 0 for x in unc.values()):
            self.sink.add(nodes["uncertainty"], f"{where}.uncertainty", f"expected one of {{kind: number >= 0}}, got {unc!r}",
                          ", ".join(UNCERTAINTY_KINDS))
            unc = {}
        tol = raw.get("tolerance") or {}
        tol = self._tolerance(tol, nodes["tolerance"], f"{where}.tolerance", bases, unc)
        if relation in ("=", "~") and rng is None and not tol and not unc and "not_simulated" not in raw:
            self.sink.add(node, f"{where}.tolerance", "a compared value needs a tolerance or an uncertainty to be judged by",
                          ", ".join(TOLERANCE_KINDS))
        conditions = need("conditions")
        if conditions is not None:
            if not isinstance(conditions, dict):
                self.sink.add(nodes["conditions"], f"{where}.conditions", "expected a mapping", ", ".join(CONDITION_KEYS))
                conditions = {}
            for k in set(conditions) - set(CONDITION_KEYS):
                self.sink.add(nodes["conditions"], f"{where}.conditions.{k}", f"unknown condition {k!r}",
                              ", ".join(CONDITION_KEYS))
        source = need("source")
        if source is not None:
            if not isinstance(source, dict) or "section" not in source:
                self.sink.add(nodes["source"], f"{where}.source", "needs at least a 'section'", ", ".join(SOURCE_KEYS))
                source = None
            else:
                for k in set(source) - set(SOURCE_KEYS):
                    self.sink.add(nodes["source"], f"{where}.source.{k}", f"unknown key {k!r}", ", ".join(SOURCE_KEYS))
                source = {k: str(val) for k, val in source.items()}
        measure, not_sim = raw.get("measure"), raw.get("not_simulated")
        if (measure is None) == (not_sim is None):
            self.sink.add(node, where, "needs exactly one of 'measure' (how to compute it) and 'not_simulated' (why not)")
        if not_sim is not None:
            not_sim = bases.get(not_sim, not_sim) if isinstance(not_sim, str) else None
            if not not_sim:
                self.sink.add(nodes["not_simulated"], f"{where}.not_simulated", "expected the reason as text")
        if measure is not None:
            if not isinstance(measure, dict) or "name" not in measure:
                self.sink.add(nodes["measure"], f"{where}.measure", "expected {name: ..., arguments}",
                              ", ".join(MEASURES))
                measure = None
            elif measure["name"] not in MEASURES:
                self.sink.add(nodes["measure"], f"{where}.measure.name", f"unknown measure {measure['name']!r}",
                              ", ".join(MEASURES))
                measure = None
            else:
                try:
                    expected = parse_unit(measure_unit(measure, conditions or {}))
                except MeasureError as exc:
                    self.sink.add(nodes["measure"], f"{where}.measure", str(exc))
                    expected = None
                if parsed is not None and expected is not None and parsed.signature != expected.signature:
                    self.sink.add(nodes["unit"], f"{where}.unit",
                                  f"unit '{unit}' ({parsed.dimension_text}) does not fit what {measure['name']} "
                                  f"computes ({expected.dimension_text}, e.g. {expected.text})")
        for key in ("reading", "derived", "note"):
            if key in raw and not isinstance(raw[key], str):
                self.sink.add(nodes[key], f"{where}.{key}", f"expected text, got {describe(nodes[key])}")
        if len(self.sink) > n_err:
            return None
        return Record(id=rid, quantity=quantity.strip(), unit=str(unit), value=value, range=rng, relation=relation,
                      conditions=dict(conditions), source=source, file=str(self.path), line=node.start_mark.line + 1,
                      chapter=chapter, uncertainty={k: float(x) for k, x in unc.items()}, tolerance=tol,
                      measure=measure, not_simulated=not_sim, reading=raw.get("reading", "").strip(),
                      derived=raw.get("derived", "").strip(), note=raw.get("note", "").strip())

    def _tolerance(self, tol: Any, node: Node, where: str, bases: dict[str, str],
                   unc: dict[str, float]) -> dict[str, Any]:
        if not tol:
            return {}
        if not isinstance(tol, dict):
            self.sink.add(node, where, "expected a mapping {kind: value, basis: text}", ", ".join(TOLERANCE_KINDS))
            return {}
        kinds = [k for k in tol if k in TOLERANCE_KINDS]
        extra = set(tol) - set(TOLERANCE_KINDS) - {"basis"}
        if len(kinds) != 1 or extra:
            self.sink.add(node, where, f"expected exactly one of {', '.join(TOLERANCE_KINDS)} and a basis, got {tol!r}")
            return {}
        kind = kinds[0]
        val = tol[kind]
        if kind == "sd":
            if val is not True or "sd" not in unc:
                self.sink.add(node, where, "'sd: true' judges by the record's uncertainty {sd: ...}, which is missing")
                return {}
        elif isinstance(val, bool) or not isinstance(val, (int, float)) or val < 0 or (kind == "factor" and val < 1):
            self.sink.add(node, where, f"{kind} must be a number >= {1 if kind == 'factor' else 0}, got {val!r}")
            return {}
        basis = tol.get("basis")
        if not isinstance(basis, str) or not basis.strip():
            self.sink.add(node, where, "needs a 'basis': why this is the thesis's own spread")
            return {}
        return {"kind": kind, "value": float(val) if kind != "sd" else unc["sd"], "basis": bases.get(basis, basis)}


#: files of the records directory that hold no records
NOT_RECORDS = ("calibration.yaml", "held-out.yaml")


def record_files(directory: str | Path | None = None) -> list[Path]:
    """The record files of a directory (default configs/thesis/), excluding the calibration plan
    and the held-out declaration."""
    d = Path(directory) if directory is not None else RECORDS_DIR
    return sorted(p for p in d.glob("*.yaml") if p.name not in NOT_RECORDS)


def load_records(paths: list[str | Path] | None = None) -> list[Record]:
    """Read and check record files (default: every file of configs/thesis/); raise RecordsError."""
    files = [Path(p) for p in paths] if paths is not None else record_files()
    seen: dict[str, str] = {}
    errors: list[PlanError] = []
    out: list[Record] = []
    for path in files:
        sink = ErrorSink(str(path))
        out += _FileReader(path, sink, seen).read()
        errors += sink.errors
    if errors:
        raise RecordsError(errors)
    return out


__all__ = ["Record", "RecordsError", "load_records", "record_files", "RECORDS_DIR"]
