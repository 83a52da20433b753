"""The side-by-side table: every thesis record against its simulated value over several noise seeds.

Units: each row shows the thesis value and the simulated value in the record's own unit
(the simulated value converted from the measure's unit), the gap in that unit and in
percent of the thesis value.

Contract: :func:`evaluate` computes every record's measure on one
:class:`~tsa_bench.reproduce.experiments.Lab` per noise seed and returns one :class:`Row`
per record. Each seed's value is judged against the record's tolerance, widened where the
simulation's own seed-to-seed scatter is wider (:mod:`~tsa_bench.reproduce.agreement`).
The verdict is

* ``agrees``: at least 80 % of the seeds agree (within the tolerance, inside the range, on
  the right side of the bound); ``disagrees`` otherwise, with the plan's named reason (or
  "no reason named"); a row whose seeds do not all give the same answer is ``unstable``;
* ``consistency-only``: the simulator was built from this very number (the plan's
  ``built_from``); its value is shown but never counted as agreement;
* ``not simulated``: the record says why; ``not computed``: the computation failed.

Each row also has its role (:mod:`~tsa_bench.reproduce.roles`): fitted, held-out,
derived, duplicate, qualitative, uninformative or built-from. :func:`summary` counts
verdicts by role; only held-out agreement is evidence that the simulated bench behaves
like the thesis's actuator.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from tsa_bench.reproduce.agreement import (AGREE_FRACTION, effective_tolerance, fraction, judge as judge_at,
                                           stated_tolerance)
from tsa_bench.reproduce.measures import MeasureError, measure_unit
from tsa_bench.reproduce.quantities import compute
from tsa_bench.reproduce.plan import CalibrationPlan
from tsa_bench.reproduce.records import Record
from tsa_bench.reproduce.roles import NEVER_COUNTED, ROLES, assign_roles
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
    #: the calibration role (fitted, held-out, built-from) under the table role
    calibration: str = ""
    #: the simulated value on each seed (record unit; None where not finite)
    seeds: list[float | None] | None = None
    #: share of the seeds that agree, and the values' standard deviation over the seeds
    agree_fraction: float | None = None
    spread: float | None = None
    unstable: bool = False

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        for k in ("simulated", "gap", "gap_percent", "spread"):
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
    """Does one simulated value (in the record's unit) agree with the record's stated tolerance?"""
    return judge_at(rec, sim, stated_tolerance(rec))


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


MEASURE_ERRORS = (MeasureError, UnitError, ValueError, KeyError, IndexError, ZeroDivisionError)


def _values(rec: Record, labs: list[Any]) -> tuple[list[float], list[float]]:
    """(measure-unit values, record-unit values) of ``rec`` on every lab."""
    raw, sims = [], []
    for lab in labs:
        x = compute(lab, rec.measure, rec.conditions)
        raw.append(x)
        sims.append(convert(x, measure_unit(rec.measure, rec.conditions), rec.unit) if math.isfinite(x) else x)
    return raw, sims


def evaluate(records: list[Record], labs: Any, plan: CalibrationPlan, progress: Any = None) -> list[Row]:
    """One row per record, in record order (module contract); ``labs`` one Lab per seed (or a single Lab)."""
    labs = list(labs) if isinstance(labs, (list, tuple)) else [labs]
    raws: dict[str, list[float]] = {}
    sims: dict[str, list[float]] = {}
    failed: dict[str, str] = {}
    for rec in records:
        if rec.measure is None:
            continue
        if progress is not None:
            progress(rec)
        try:
            raws[rec.id], sims[rec.id] = _values(rec, labs)
        except MEASURE_ERRORS as exc:
            failed[rec.id] = f"{type(exc).__name__}: {exc}"
    tols = {rec.id: effective_tolerance(rec, sims[rec.id]) for rec in records if rec.id in sims}
    agree = {rec.id: [judge_at(rec, x, tols[rec.id]) for x in sims[rec.id]] for rec in records if rec.id in sims}
    roles = assign_roles([r for r in records if r.id not in failed], plan, raws, tols, labs[0])
    rows = []
    for rec in records:
        calib = plan.role(rec.id)
        kind = "coefficient" if rec.measure and rec.measure["name"] in COEFFICIENT_MEASURES else "quantity"
        base = dict(id=rec.id, chapter=rec.chapter, quantity=rec.quantity, thesis=rec.shown_value, unit=rec.unit,
                    source=rec.source_text, reading=rec.reading, kind=kind, calibration=calib)
        if rec.measure is None:
            rows.append(Row(**base, role=calib, simulated=None, gap=None, gap_percent=None, tolerance="",
                            verdict="not simulated", reason=rec.not_simulated or ""))
            continue
        if rec.id in failed:
            rows.append(Row(**base, role=calib, simulated=None, gap=None, gap_percent=None,
                            tolerance=tolerance_text(rec), verdict="not computed", reason=failed[rec.id]))
            continue
        role = roles[rec.id]
        vals = sims[rec.id]
        finite = [x for x in vals if math.isfinite(x)]
        sim = float(np.median(finite)) if finite else float("nan")
        members = [rec.id, *(j for j in role.joint if j in agree)]   # a duplicate pair agrees on a seed only together
        seed_ok = [all(agree[j][k] for j in members) for k in range(len(vals))]
        frac = fraction(seed_ok)
        ok = frac >= AGREE_FRACTION
        ref = rec.value if rec.value is not None else 0.5 * (rec.range[0] + rec.range[1])
        gap = sim - ref if math.isfinite(sim) else None
        gap_pct = 100.0 * gap / abs(ref) if gap is not None and ref != 0 else None
        tol = tols[rec.id]
        text = tol.text(rec.unit) if tol is not None else tolerance_text(rec)
        if calib == "built-from":
            verdict = "consistency-only"
            reason = ("the simulator was built from this number (" + "; ".join(plan.built_from_parameters(rec.id))
                      + "), so matching it shows consistency, not agreement")
            if not ok:
                reason += "; it does not even match it: " + plan.reasons.get(rec.id, "no reason named")
        else:
            verdict = "agrees" if ok else "disagrees"
            named = "" if ok else plan.reasons.get(rec.id, "no reason named")
            reason = "; ".join(x for x in (role.note, named) if x)
        rows.append(Row(**base, role=role.role, simulated=sim, gap=gap, gap_percent=gap_pct, tolerance=text,
                        verdict=verdict, reason=reason, seeds=[x if math.isfinite(x) else None for x in vals],
                        agree_fraction=frac, spread=float(np.std(finite, ddof=1)) if len(finite) > 1 else 0.0,
                        unstable=0.0 < frac < 1.0))
    return rows


def summary(rows: list[Row]) -> dict[str, Any]:
    """Counts by verdict and, for compared rows, by role (agrees / disagrees / unstable), and for
    held-out rows by kind: ``quantity`` (a measured behaviour) or ``coefficient`` (a fitted
    model's coefficient or parameter, Tables 3.1-3.3: ill-conditioned, so reported apart).
    Roles in :data:`~tsa_bench.reproduce.roles.NEVER_COUNTED` are listed with their counts
    but are no agreement."""
    out: dict[str, Any] = {"records": len(rows), "by_verdict": {v: 0 for v in VERDICTS}, "by_role": {},
                           "held_out_by_kind": {}, "never_counted": list(NEVER_COUNTED)}
    for r in rows:
        out["by_verdict"][r.verdict] += 1
        if r.verdict in ("agrees", "disagrees"):
            role = out["by_role"].setdefault(r.role, {"agrees": 0, "disagrees": 0, "unstable": 0})
            role[r.verdict] += 1
            role["unstable"] += r.unstable
            if r.role == "held-out":
                kind = out["held_out_by_kind"].setdefault(r.kind, {"agrees": 0, "disagrees": 0})
                kind[r.verdict] += 1
    out["by_role"] = {k: out["by_role"][k] for k in ROLES if k in out["by_role"]}
    out["unstable"] = [r.id for r in rows if r.unstable]
    out["unexplained_disagreements"] = [r.id for r in rows if r.verdict == "disagrees" and
                                        r.reason.endswith("no reason named")]
    return out
