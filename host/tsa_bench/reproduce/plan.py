"""The calibration plan (``configs/thesis/calibration.yaml``): which records build, fit or check each preset.

Units: parameter bounds in the units of the parameter (the suffix of its name, as in
the bench files: ``_mm``, ``_N``, ``_ohm``, ...).

Contract: :func:`load_plan` reads the plan and checks it against the records::

    presets:
      <preset>:                       # configs/bench/<preset>.yaml, or 'manipulator'
        built_from: {<parameter path>: <record id>, ...}   # typed in from a record
        fit:                          # optional
          parameters: {<parameter path>: [low, high], ...}
          records: [<record id>, ...] # the records the parameters are fitted to
    reasons: {<record id>: <why the simulation cannot match it>, ...}

A parameter path is a dotted path in the preset's ``plant`` mapping
(``radius_mm``, ``effects.string_compliance.stiffness_N``) or, for ``manipulator``, in
configs/manipulator/thesis.yaml (``control.motor_rev_per_s_per_V``). A record is
*built-from* when some preset's parameter was typed in from it (the reproduction then
only checks consistency and never counts it as agreement), *fitted* when a preset was
fitted to it, and *held-out* otherwise. Every id must exist among the records; every
problem raises :class:`~tsa_bench.reproduce.records.RecordsError` with file:line:col.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import yaml

from tsa_bench.plan.errors import ErrorSink
from tsa_bench.plan.yamlnodes import Reader
from tsa_bench.reproduce.records import RECORDS_DIR, Record, RecordsError

PLAN_FILE = RECORDS_DIR / "calibration.yaml"


@dataclass
class PresetPlan:
    """What one preset is built from and fitted to."""

    name: str
    built_from: dict[str, str] = field(default_factory=dict)
    parameters: dict[str, tuple[float, float]] = field(default_factory=dict)
    fitted_records: list[str] = field(default_factory=list)


@dataclass
class CalibrationPlan:
    presets: dict[str, PresetPlan]
    reasons: dict[str, str]
    path: str = ""

    def role(self, record_id: str) -> str:
        """'built-from', 'fitted' or 'held-out'."""
        if any(record_id in p.built_from.values() for p in self.presets.values()):
            return "built-from"
        if any(record_id in p.fitted_records for p in self.presets.values()):
            return "fitted"
        return "held-out"

    def built_from_parameters(self, record_id: str) -> list[str]:
        return [f"{p.name}: {path}" for p in self.presets.values() for path, rid in p.built_from.items()
                if rid == record_id]


def load_plan(records: list[Record], path: str | Path | None = None) -> CalibrationPlan:
    """Read and check the calibration plan against ``records`` (module contract)."""
    p = Path(path) if path is not None else PLAN_FILE
    sink = ErrorSink(str(p))
    reader = Reader(sink)
    ids = {r.id for r in records}
    try:
        root = yaml.compose(p.read_text(encoding="utf-8"), Loader=yaml.SafeLoader)
    except OSError as exc:
        sink.add(None, "", f"cannot read ({exc})")
        raise RecordsError(sink.errors) from None
    except yaml.MarkedYAMLError as exc:
        sink.add(exc.problem_mark, "", f"YAML syntax error: {exc.problem}")
        raise RecordsError(sink.errors) from None
    if root is None:
        sink.add(None, "", "the plan is empty")
        raise RecordsError(sink.errors)
    top = reader.mapping(root, "", ("presets", "reasons"), ("presets",)) or {}
    presets: dict[str, PresetPlan] = {}
    pm = reader.mapping(top["presets"], "presets", _preset_names()) if "presets" in top else None
    for name, node in (pm or {}).items():
        where = f"presets.{name}"
        m = reader.mapping(node, where, ("built_from", "fit")) or {}
        plan = PresetPlan(name)
        if "built_from" in m:
            bf = reader.mapping(m["built_from"], f"{where}.built_from", _AnyKey()) or {}
            for key, vnode in bf.items():
                rid = reader.string(vnode, f"{where}.built_from.{key}")
                if rid is not None and rid not in ids:
                    sink.add(vnode, f"{where}.built_from.{key}", f"no record with id {rid!r}")
                elif rid is not None:
                    plan.built_from[key] = rid
        if "fit" in m:
            fm = reader.mapping(m["fit"], f"{where}.fit", ("parameters", "records"), ("parameters", "records")) or {}
            if "parameters" in fm:
                pmap = reader.mapping(fm["parameters"], f"{where}.fit.parameters", _AnyKey()) or {}
                for key, vnode in pmap.items():
                    bounds = reader.plain_data(vnode, f"{where}.fit.parameters.{key}")
                    if (not isinstance(bounds, list) or len(bounds) != 2
                            or not all(isinstance(b, (int, float)) and not isinstance(b, bool) for b in bounds)
                            or not bounds[0] < bounds[1]):
                        sink.add(vnode, f"{where}.fit.parameters.{key}", f"expected [low, high] bounds, got {bounds!r}")
                    else:
                        plan.parameters[key] = (float(bounds[0]), float(bounds[1]))
            if "records" in fm:
                for i, rnode in enumerate(reader.sequence(fm["records"], f"{where}.fit.records", "record ids") or []):
                    rid = reader.string(rnode, f"{where}.fit.records[{i}]")
                    if rid is not None and rid not in ids:
                        sink.add(rnode, f"{where}.fit.records[{i}]", f"no record with id {rid!r}")
                    elif rid is not None:
                        plan.fitted_records.append(rid)
        presets[name] = plan
    reasons: dict[str, str] = {}
    if "reasons" in top:
        rm = reader.mapping(top["reasons"], "reasons", _AnyKey()) or {}
        for rid, vnode in rm.items():
            text = reader.string(vnode, f"reasons.{rid}")
            if rid not in ids:
                sink.add(vnode, f"reasons.{rid}", f"no record with id {rid!r}")
            elif text is not None:
                reasons[rid] = " ".join(text.split())
    if sink.errors:
        raise RecordsError(sink.errors)
    return CalibrationPlan(presets, reasons, str(p))


def _preset_names() -> tuple[str, ...]:
    from tsa_bench.reproduce.experiments import PRESETS

    return PRESETS + ("manipulator",)


class _AnyKey(tuple):
    """An 'allowed keys' sequence that allows every key (free-form mappings)."""

    def __contains__(self, item: object) -> bool:
        return True

    def __iter__(self):
        return iter(("any key",))


def plan_or_empty(records: list[Record], path: str | Path | None = None) -> CalibrationPlan:
    """The plan, or an empty one when the file does not exist."""
    p = Path(path) if path is not None else PLAN_FILE
    return load_plan(records, p) if p.exists() else CalibrationPlan({}, {}, "")


__all__ = ["CalibrationPlan", "PresetPlan", "load_plan", "plan_or_empty", "PLAN_FILE"]
