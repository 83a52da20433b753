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

A preset is a bench file name (``sim-3ply`` = configs/bench/sim-3ply.yaml) or
``manipulator`` (configs/manipulator/thesis.yaml). A parameter path is a dotted path in
the preset's ``plant`` mapping (``radius_mm``, ``effects.string_compliance.stiffness_N``)
or in the manipulator file (``control.motor_rev_per_s_per_V``). A record is
*built-from* when a parameter was typed in from it (the reproduction then only checks
consistency and never counts it as agreement), *fitted* when a fit used it, and
*held-out* otherwise. Every id must exist among the records; every problem raises
:class:`~tsa_bench.reproduce.records.RecordsError` with file:line:col.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from yaml import Node

from tsa_bench.plan.errors import ErrorSink
from tsa_bench.plan.yamlnodes import Reader
from tsa_bench.reproduce.records import RECORDS_DIR, Record, RecordsError, read_document

PLAN_FILE = RECORDS_DIR / "calibration.yaml"
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

    def role(self, record_id: str) -> str:
        """'built-from', 'fitted' or 'held-out'."""
        if any(record_id in m.values() for m in self.built_from.values()):
            return "built-from"
        if any(record_id in f.records for f in self.fits):
            return "fitted"
        return "held-out"

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


def load_plan(records: list[Record], path: str | Path | None = None) -> CalibrationPlan:
    """Read and check the calibration plan against ``records`` (module contract)."""
    p = Path(path) if path is not None else PLAN_FILE
    sink = ErrorSink(str(p))
    reader = Reader(sink)
    ids = {r.id for r in records}
    presets = _presets()
    root = read_document(p, "calibration plan", sink)
    if root is None:
        if not sink.errors:
            sink.add(None, "", "the plan is empty")
        raise RecordsError(sink.errors)
    top = reader.mapping(root, "", ("built_from", "fits", "reasons"), ("fits",)) or {}
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
            if rid is not None:
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
    reasons: dict[str, str] = {}
    if "reasons" in top:
        for rid, vnode in (reader.mapping(top["reasons"], "reasons", _AnyKey()) or {}).items():
            text = reader.string(vnode, f"reasons.{rid}")
            if rid not in ids:
                sink.add(vnode, f"reasons.{rid}", f"no record with id {rid!r}")
            elif text is not None:
                reasons[rid] = " ".join(text.split())
    if sink.errors:
        raise RecordsError(sink.errors)
    return CalibrationPlan(built, fits, reasons, str(p))


def plan_or_empty(records: list[Record], path: str | Path | None = None) -> CalibrationPlan:
    """The plan, or an empty one when the file does not exist."""
    p = Path(path) if path is not None else PLAN_FILE
    return load_plan(records, p) if p.exists() else CalibrationPlan({}, [], {}, "")


__all__ = ["CalibrationPlan", "Fit", "load_plan", "plan_or_empty", "PLAN_FILE", "MANIPULATOR"]
