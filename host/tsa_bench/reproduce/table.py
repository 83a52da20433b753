"""The side-by-side table: every thesis record against its simulated value, with gap and verdict.

Units: each row shows the thesis value and the simulated value in the record's own unit
(the simulated value converted from the measure's unit), the gap in that unit and in
percent of the thesis value.

Contract: :func:`evaluate` computes every record's measure on a
:class:`~tsa_bench.reproduce.experiments.Lab` and returns one :class:`Row` per record.
The verdict is

* ``agrees``: within the record's tolerance (or its uncertainty), inside its reported
  range, or on the right side of its bound;
* ``disagrees``: otherwise; the row carries the plan's named reason for it, or says
  that none is named;
* ``consistency-only``: the simulator was built from this very number (the plan's
  ``built_from``); its value is shown but never counted as agreement;
* ``not simulated``: the record says why (no thick-string preset, no robot body, ...);
* ``not computed``: the computation failed (the row says how).

Each row also has its role: ``built-from``, ``fitted`` (a preset was fitted to it) or
``held-out``. :func:`summary` counts verdicts by role; only held-out agreement is
evidence that the simulated bench behaves like the thesis's actuator.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from tsa_bench.reproduce.measures import MeasureError, measure_unit
from tsa_bench.reproduce.quantities import compute
from tsa_bench.reproduce.plan import CalibrationPlan
from tsa_bench.reproduce.records import Record
from tsa_bench.units import UnitError, convert

VERDICTS = ("agrees", "disagrees", "consistency-only", "not simulated", "not computed")
#: measures whose value is a fitted model's coefficient or parameter (Tables 3.1-3.3)
COEFFICIENT_MEASURES = ("poly_coefficient", "model_parameter")


@dataclass
class Row:
    """One line of the table (module contract)."""

    id: str
    chapter: int
    quantity: str
    thesis: str
    unit: str
    simulated: float | None
    gap: float | None
    gap_percent: float | None
    tolerance: str
    verdict: str
    role: str
    reason: str
    source: str
    reading: str
    kind: str = "quantity"

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        for k in ("simulated", "gap", "gap_percent"):
            if d[k] is not None and not math.isfinite(d[k]):
                d[k] = None
        return d


def tolerance_text(rec: Record) -> str:
    if rec.range is not None:
        return f"within {rec.range[0]:g}-{rec.range[1]:g} {rec.unit}"
    if rec.relation not in ("=", "~"):
        return f"{rec.relation} {rec.value:g} {rec.unit}"
    t = rec.tolerance
    if t:
        kind, v = t["kind"], t["value"]
        text = {"abs": f"+-{v:g} {rec.unit}", "rel": f"+-{100 * v:g} %", "factor": f"x/{v:g}",
                "sd": f"+-{v:g} {rec.unit} (sd)"}[kind]
        return text
    kind, v = next(iter(rec.uncertainty.items()))
    return f"+-{v:g} {rec.unit} ({kind})"


def judge(rec: Record, sim: float) -> bool:
    """Does the simulated value (in the record's unit) agree with the record?"""
    if not math.isfinite(sim):
        return False
    if rec.range is not None:
        return rec.range[0] <= sim <= rec.range[1]
    v = rec.value
    rel = rec.relation
    if rel == "<":
        return sim < v
    if rel == ">":
        return sim > v
    if rel == "<=":
        return sim <= v
    if rel == ">=":
        return sim >= v
    t = rec.tolerance
    if not t:
        return abs(sim - v) <= next(iter(rec.uncertainty.values()))
    kind, tol = t["kind"], t["value"]
    if kind in ("abs", "sd"):
        return abs(sim - v) <= tol
    if kind == "rel":
        return abs(sim - v) <= tol * abs(v)
    if v == 0 or sim == 0 or (sim > 0) != (v > 0):
        return False
    ratio = sim / v
    return 1.0 / tol <= ratio <= tol


def residual(rec: Record, sim: float) -> float:
    """How far ``sim`` (record unit) is from the record, in units of its tolerance; ``|r| <= 1`` agrees.

    ``gap / tolerance`` (abs, sd), ``gap / (rel |value|)``, ``log(sim / value) / log(factor)``;
    for bounds and ranges 0 inside and the distance outside in units of the bound's
    magnitude (plus 0.05, so a value on the wrong side never counts as agreeing).
    """
    if not math.isfinite(sim):
        return 1e3
    if rec.range is not None:
        lo, hi = rec.range
        return 0.0 if lo <= sim <= hi else (sim - (hi if sim > hi else lo)) / (hi - lo) + math.copysign(
            1.0, sim - hi if sim > hi else sim - lo)
    v = rec.value
    if rec.relation in ("<", "<=", ">", ">="):
        ok = {"<": sim < v, "<=": sim <= v, ">": sim > v, ">=": sim >= v}[rec.relation]
        scale = abs(v) if v else 1.0
        return 0.0 if ok else (sim - v) / scale + math.copysign(1.05, sim - v)
    t = rec.tolerance or {"kind": "abs", "value": next(iter(rec.uncertainty.values()))}
    kind, tol = t["kind"], t["value"]
    if kind in ("abs", "sd"):
        return (sim - v) / tol if tol > 0 else (0.0 if sim == v else 1e3)
    if kind == "rel":
        return (sim - v) / (tol * abs(v))
    if v == 0 or sim == 0 or (sim > 0) != (v > 0):
        return 0.0 if sim == v else 1e3
    ratio = sim / v
    if ratio == 0.0 or math.isinf(ratio):  # the quotient under- or overflowed (e.g. a subnormal sim)
        return (math.log(abs(sim)) - math.log(abs(v))) / math.log(tol)
    return math.log(ratio) / math.log(tol)


def evaluate(records: list[Record], lab: Any, plan: CalibrationPlan,
             progress: Any = None) -> list[Row]:
    """One row per record, in record order (module contract)."""
    rows = []
    for rec in records:
        role = plan.role(rec.id)
        kind = "coefficient" if rec.measure and rec.measure["name"] in COEFFICIENT_MEASURES else "quantity"
        base = dict(id=rec.id, chapter=rec.chapter, quantity=rec.quantity, thesis=rec.shown_value, unit=rec.unit,
                    source=rec.source_text, reading=rec.reading, role=role, kind=kind)
        if rec.measure is None:
            rows.append(Row(**base, simulated=None, gap=None, gap_percent=None, tolerance="",
                            verdict="not simulated", reason=rec.not_simulated or ""))
            continue
        if progress is not None:
            progress(rec)
        try:
            raw = compute(lab, rec.measure, rec.conditions)
            sim = convert(raw, measure_unit(rec.measure, rec.conditions), rec.unit) if math.isfinite(raw) else raw
        except (MeasureError, UnitError, ValueError, KeyError, IndexError, ZeroDivisionError) as exc:
            rows.append(Row(**base, simulated=None, gap=None, gap_percent=None, tolerance=tolerance_text(rec),
                            verdict="not computed", reason=f"{type(exc).__name__}: {exc}"))
            continue
        ref = rec.value if rec.value is not None else 0.5 * (rec.range[0] + rec.range[1])
        gap = sim - ref if math.isfinite(sim) else None
        gap_pct = 100.0 * gap / abs(ref) if gap is not None and ref != 0 else None
        ok = judge(rec, sim)
        if role == "built-from":
            verdict = "consistency-only"
            reason = ("the simulator was built from this number (" + "; ".join(plan.built_from_parameters(rec.id))
                      + "), so matching it shows consistency, not agreement")
            if not ok:
                reason += "; it does not even match it: " + plan.reasons.get(rec.id, "no reason named")
        elif ok:
            verdict, reason = "agrees", ""
        else:
            verdict = "disagrees"
            reason = plan.reasons.get(rec.id, "no reason named")
        rows.append(Row(**base, simulated=sim, gap=gap, gap_percent=gap_pct, tolerance=tolerance_text(rec),
                        verdict=verdict, reason=reason))
    return rows


def summary(rows: list[Row]) -> dict[str, Any]:
    """Counts by verdict and, for compared rows, by role, and for held-out rows by kind:
    ``quantity`` (a measured behaviour) or ``coefficient`` (a fitted model's coefficient or
    parameter, Tables 3.1-3.3: ill-conditioned, so reported apart)."""
    out: dict[str, Any] = {"records": len(rows), "by_verdict": {v: 0 for v in VERDICTS}, "by_role": {},
                           "held_out_by_kind": {}}
    for r in rows:
        out["by_verdict"][r.verdict] += 1
        if r.verdict in ("agrees", "disagrees"):
            role = out["by_role"].setdefault(r.role, {"agrees": 0, "disagrees": 0})
            role[r.verdict] += 1
            if r.role == "held-out":
                kind = out["held_out_by_kind"].setdefault(r.kind, {"agrees": 0, "disagrees": 0})
                kind[r.verdict] += 1
    out["unexplained_disagreements"] = [r.id for r in rows if r.verdict == "disagrees" and
                                        r.reason == "no reason named"]
    return out
