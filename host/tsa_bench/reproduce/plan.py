"""The calibration plan (``configs/thesis/calibration.yaml``): which records build, fit or check each preset.

Units: parameter bounds in the units of the parameter (the suffix of its name, as in
the bench files: ``_mm``, ``_N``, ``_ohm``, ...).

Contract: :func:`load_plan` reads the plan and checks it against the records::

    built_from:                       # parameters typed in from a record
      <preset>: {<parameter path>: <record id>, ...}
    fits:                             # run in order; a later fit starts from the earlier results
      - name: <what this fit is for>
        parameters: {<preset>:<parameter path>: [low, high], ...}   # <preset1>,<preset2>:<path> ties
                                      # one value to several presets (e.g. the rig's sensor noise)
        records: [<record id>, ...]   # the records the parameters are fitted to
        maxfev: <int>                 # optional: at most this many simulations (default: the script's)
        extension:                    # optional: a plant effect the fit adds, judged on held-out records
          effect: <effect name>
          parameters: [<preset>:<parameter path>, ...]   # among the parameters above
    reasons: {<record id>: <why the simulation does not match it>, ...}
    derived:                          # optional: held-out records computed from fitted ones
      <record id>: {from: [<record id>, ...], how: <how it follows from them>}
    by_construction: {<record id>: <why the simulation cannot fail it>, ...}   # optional

The held-out records are declared apart, before the calibration, in
``held-out.yaml`` beside the plan (:data:`HELD_OUT_FILE`)::

    held_out: [<record id>, ...]

When that file exists, every simulated record must be exactly one of built-from,
fitted or held out: a fit naming a held-out record, or a simulated record in none of
the three, is an error. Without the file (a record directory of one's own) every record
neither built-from nor fitted is held out.

A preset is a bench file name (``sim-3ply`` = configs/bench/sim-3ply.yaml) or
``manipulator`` (configs/manipulator/thesis.yaml). A parameter path is a dotted path in
the preset's ``plant`` mapping (``radius_mm``, ``effects.string_compliance.stiffness_N``)
or in the manipulator file (``control.motor_rev_per_s_per_V``). A record is
*built-from* when a parameter was typed in from it (the reproduction then only checks
consistency and never counts it as agreement), *fitted* when a fit used it, and
*held-out* when the held-out file declares it. A ``derived`` record must name at least
one fitted record it follows from (the table shows it and never counts it); a
``by_construction`` record is one the simulation satisfies whatever its parameters (a
protocol's duration). Every id must exist among the records; every problem raises
:class:`~tsa_bench.reproduce.records.RecordsError` with file:line:col.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from yaml import Node

from tsa_bench.plan.errors import ErrorSink, PlanError
from tsa_bench.plan.yamlnodes import Reader
from tsa_bench.reproduce.records import RECORDS_DIR, Record, RecordsError, read_document

PLAN_FILE = RECORDS_DIR / "calibration.yaml"
HELD_OUT_NAME = "held-out.yaml"
HELD_OUT_FILE = RECORDS_DIR / HELD_OUT_NAME
MANIPULATOR = "manipulator"


@dataclass
class Fit:
    """One fit: parameters (``(presets, path) -> (low, high)``, one value set in every preset
    named) and the records they are fitted to."""

    name: str
    parameters: dict[tuple[tuple[str, ...], str], tuple[float, float]] = field(default_factory=dict)
    records: list[str] = field(default_factory=list)
    #: effect name and the parameters that switch it on (fitted once without them: the gain is measured)
    extension: tuple[str, list[tuple[tuple[str, ...], str]]] | None = None
    #: at most this many simulations (None: the caller's budget)
    maxfev: int | None = None


@dataclass
class CalibrationPlan:
    built_from: dict[str, dict[str, str]]
    fits: list[Fit]
    reasons: dict[str, str]
    path: str = ""
    #: the declared held-out ids (None: no held-out file; every other record is held out)
    held_out: frozenset[str] | None = None
    held_out_path: str = ""
    #: record id -> (the records it is computed from, at least one fitted; how)
    derived: dict[str, tuple[tuple[str, ...], str]] = field(default_factory=dict)
    #: record id -> why the simulation satisfies it whatever its parameters
    by_construction: dict[str, str] = field(default_factory=dict)

    def role(self, record_id: str) -> str:
        """The calibration role: 'built-from', 'fitted' or 'held-out'."""
        if any(record_id in m.values() for m in self.built_from.values()):
            return "built-from"
        if any(record_id in f.records for f in self.fits):
            return "fitted"
        return "held-out"

    def fitted_ids(self) -> list[str]:
        """Every record some fit uses, in plan order, once."""
        return list(dict.fromkeys(rid for f in self.fits for rid in f.records))

    def built_from_parameters(self, record_id: str) -> list[str]:
        return [f"{preset} {path}" for preset, m in self.built_from.items() for path, rid in m.items()
                if rid == record_id]

    def fitted_parameters(self) -> dict[str, list[str]]:
        """preset -> the parameter paths some fit sets."""
        out: dict[str, list[str]] = {}
        for f in self.fits:
            for presets, path in f.parameters:
                for preset in presets:
                    out.setdefault(preset, []).append(path)
        return out


class _AnyKey(tuple):
    """An 'allowed keys' sequence that allows every key (free-form mappings)."""

    def __contains__(self, item: object) -> bool:
        return True

    def __iter__(self):
        return iter(("any key",))


def _presets() -> tuple[str, ...]:
    from tsa_bench.reproduce.experiments import PRESETS

    return PRESETS + (MANIPULATOR,)


def _record_id(reader: Reader, sink: ErrorSink, node: Node, where: str, ids: set[str]) -> str | None:
    rid = reader.string(node, where)
    if rid is not None and rid not in ids:
        sink.add(node, where, f"no record with id {rid!r}")
        return None
    return rid


def _texts(reader: Reader, sink: ErrorSink, top: dict[str, Node], section: str, ids: set[str]) -> dict[str, str]:
    """A ``{<record id>: <text>}`` section of the plan (absent: empty), each id checked."""
    out: dict[str, str] = {}
    for rid, vnode in (reader.mapping(top[section], section, _AnyKey()) or {}).items() if section in top else []:
        text = reader.string(vnode, f"{section}.{rid}")
        if rid not in ids:
            sink.add(vnode, f"{section}.{rid}", f"no record with id {rid!r}")
        elif text is not None:
            out[rid] = " ".join(text.split())
    return out


def load_held_out(path: Path, ids: set[str]) -> dict[str, int]:
    """The held-out file's ids -> their line (module contract); RecordsError on any problem."""
    sink = ErrorSink(str(path))
    reader = Reader(sink)
    root = read_document(path, "held-out records", sink)
    out: dict[str, int] = {}
    if root is None:
        if not sink.errors:
            sink.add(None, "", "the held-out file is empty")
        raise RecordsError(sink.errors)
    top = reader.mapping(root, "", ("held_out",), ("held_out",)) or {}
    for j, node in enumerate(reader.sequence(top["held_out"], "held_out", "record ids") or []
                             if "held_out" in top else []):
        rid = _record_id(reader, sink, node, f"held_out[{j}]", ids)
        if rid is not None and rid in out:
            sink.add(node, f"held_out[{j}]", f"{rid!r} is listed twice")
        elif rid is not None:
            out[rid] = node.start_mark.line + 1
    if sink.errors:
        raise RecordsError(sink.errors)
    return out


def load_plan(records: list[Record], path: str | Path | None = None,
              held_out_path: str | Path | None = None) -> CalibrationPlan:
    """Read and check the calibration plan (and the held-out file beside it, or
    ``held_out_path``) against ``records`` (module contract)."""
    p = Path(path) if path is not None else PLAN_FILE
    hp = Path(held_out_path) if held_out_path is not None else p.with_name(HELD_OUT_NAME)
    held = load_held_out(hp, {r.id for r in records}) if hp.exists() else None
    sink = ErrorSink(str(p))
    reader = Reader(sink)
    ids = {r.id for r in records}
    presets = _presets()
    root = read_document(p, "calibration plan", sink)
    if root is None:
        if not sink.errors:
            sink.add(None, "", "the plan is empty")
        raise RecordsError(sink.errors)
    top = reader.mapping(root, "", ("built_from", "fits", "reasons", "derived", "by_construction"), ("fits",)) or {}
    built: dict[str, dict[str, str]] = {}
    if "built_from" in top:
        for preset, node in (reader.mapping(top["built_from"], "built_from", presets) or {}).items():
            for key, vnode in (reader.mapping(node, f"built_from.{preset}", _AnyKey()) or {}).items():
                rid = _record_id(reader, sink, vnode, f"built_from.{preset}.{key}", ids)
                if rid is not None:
                    built.setdefault(preset, {})[key] = rid
    fits: list[Fit] = []
    for i, fnode in enumerate(reader.sequence(top["fits"], "fits", "fits") or [] if "fits" in top else []):
        where = f"fits[{i}]"
        fm = reader.mapping(fnode, where, ("name", "parameters", "records", "extension", "maxfev"),
                            ("name", "parameters", "records")) or {}
        fit = Fit(reader.string(fm["name"], f"{where}.name") or where if "name" in fm else where)
        for key, vnode in (reader.mapping(fm["parameters"], f"{where}.parameters", _AnyKey()) or {}).items() \
                if "parameters" in fm else []:
            names, sep, ppath = key.partition(":")
            targets = tuple(n.strip() for n in names.split(","))
            bounds = reader.plain_data(vnode, f"{where}.parameters.{key}")
            if not sep or not ppath or any(t not in presets for t in targets):
                sink.add(vnode, f"{where}.parameters.{key}", "expected <preset>[,<preset>...]:<parameter path>",
                         ", ".join(presets))
            elif (not isinstance(bounds, list) or len(bounds) != 2
                  or not all(isinstance(b, (int, float)) and not isinstance(b, bool) for b in bounds)
                  or not bounds[0] < bounds[1]):
                sink.add(vnode, f"{where}.parameters.{key}", f"expected [low, high] bounds, got {bounds!r}")
            else:
                fit.parameters[(targets, ppath)] = (float(bounds[0]), float(bounds[1]))
        for j, rnode in enumerate(reader.sequence(fm["records"], f"{where}.records", "record ids") or []
                                  if "records" in fm else []):
            rid = _record_id(reader, sink, rnode, f"{where}.records[{j}]", ids)
            if rid is not None and held is not None and rid in held:
                sink.add(rnode, f"{where}.records[{j}]", f"{rid!r} is declared held out ({hp.name}:{held[rid]}); "
                         "a held-out record cannot be fitted")
            elif rid is not None:
                fit.records.append(rid)
        if "maxfev" in fm:
            fit.maxfev = reader.integer(fm["maxfev"], f"{where}.maxfev", ge=5)
        if "extension" in fm:
            em = reader.mapping(fm["extension"], f"{where}.extension", ("effect", "parameters"),
                                ("effect", "parameters")) or {}
            effect = reader.string(em["effect"], f"{where}.extension.effect") if "effect" in em else None
            keys = []
            for j, knode in enumerate(reader.sequence(em["parameters"], f"{where}.extension.parameters",
                                                      "parameters") or [] if "parameters" in em else []):
                key = reader.string(knode, f"{where}.extension.parameters[{j}]")
                names, _, ppath = (key or "").partition(":")
                pkey = (tuple(n.strip() for n in names.split(",")), ppath)
                if key is not None and pkey not in fit.parameters:
                    sink.add(knode, f"{where}.extension.parameters[{j}]", f"{key!r} is not among the fit's parameters")
                elif key is not None:
                    keys.append(pkey)
            if effect is not None and keys:
                fit.extension = (effect, keys)
        fits.append(fit)
    reasons = _texts(reader, sink, top, "reasons", ids)
    fitted = {rid for f in fits for rid in f.records}
    derived: dict[str, tuple[tuple[str, ...], str]] = {}
    if "derived" in top:
        for rid, vnode in (reader.mapping(top["derived"], "derived", _AnyKey()) or {}).items():
            where = f"derived.{rid}"
            dm = reader.mapping(vnode, where, ("from", "how"), ("from", "how")) or {}
            srcs = [_record_id(reader, sink, n, f"{where}.from[{j}]", ids)
                    for j, n in enumerate(reader.sequence(dm["from"], f"{where}.from", "record ids") or []
                                          if "from" in dm else [])]
            how = reader.string(dm["how"], f"{where}.how") if "how" in dm else None
            if rid not in ids:
                sink.add(vnode, where, f"no record with id {rid!r}")
            elif rid in fitted:
                sink.add(vnode, where, f"{rid!r} is itself fitted")
            elif srcs and None not in srcs and not fitted.intersection(srcs):
                sink.add(dm.get("from", vnode), f"{where}.from", "names no fitted record: a record computed only "
                         "from held-out ones stays held out")
            elif how is not None and srcs and None not in srcs:
                derived[rid] = (tuple(s for s in srcs if s is not None), " ".join(how.split()))
    by_construction = _texts(reader, sink, top, "by_construction", ids)
    if held is not None:
        built_ids = {rid for m in built.values() for rid in m.values()}
        for rec in records:
            if rec.measure is None or rec.id in fitted or rec.id in built_ids:
                continue
            if rec.id not in held:
                sink.errors.append(PlanError(rec.file, rec.line, None, rec.id, "a simulated record neither "
                                             f"built-from, fitted nor declared held out (add it to {hp})"))
    if sink.errors:
        raise RecordsError(sink.errors)
    return CalibrationPlan(built, fits, reasons, str(p), frozenset(held) if held is not None else None,
                           str(hp) if held is not None else "", derived, by_construction)


def plan_or_empty(records: list[Record], path: str | Path | None = None) -> CalibrationPlan:
    """The plan, or an empty one when the file does not exist."""
    p = Path(path) if path is not None else PLAN_FILE
    return load_plan(records, p) if p.exists() else CalibrationPlan({}, [], {}, "")


__all__ = ["CalibrationPlan", "Fit", "load_held_out", "load_plan", "plan_or_empty", "PLAN_FILE", "HELD_OUT_FILE",
           "MANIPULATOR"]
