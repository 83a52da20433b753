"""What a row of the table can show: its role.

Units: none (roles are labels); simulated values are compared in the measure's own unit.

Contract: :func:`assign_roles` gives every simulated record a :class:`Role`. Built-from
and fitted records keep their calibration role (``built-from``, ``fitted``). A record the
held-out file declares is, in this order of precedence:

* ``derived`` -- computed from a fitted record: the plan says so (``derived``), or its
  simulated number is a fitted record's on every seed (the same measure on the same runs),
  or it is the same eq. 3.21 error as a fitted record in the other form (percent against
  absolute, :data:`SAME_ERROR`). Shown, never counted.
* ``duplicate`` -- the same error as another held-out record in the other form: the pair is
  counted once, on the record that comes first (its verdict needs both to agree on a
  seed); the second is shown, never counted.
* ``qualitative`` -- a direction only (a bound at 0, or at 1 for a dimensionless ratio), or
  true by construction (the plan's ``by_construction``). Counted apart from agreement.
* ``uninformative`` -- its tolerance is wider than the quantity's range over the experiment
  (:func:`~tsa_bench.reproduce.spans.vacuity`, computed on the first seed's runs). Shown,
  never counted.
* ``held-out`` otherwise: only these rows are evidence that the simulation behaves like
  the thesis's actuators.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any

from tsa_bench.reproduce.agreement import Tolerance
from tsa_bench.reproduce.plan import CalibrationPlan
from tsa_bench.reproduce.records import Record
from tsa_bench.reproduce.spans import vacuity

ROLES = ("fitted", "held-out", "derived", "duplicate", "qualitative", "uninformative", "built-from")
#: roles whose agreement is never counted
NEVER_COUNTED = ("derived", "duplicate", "uninformative", "built-from")
#: the eq. 3.21 error in percent and in absolute terms is one error: stat -> its other form
SAME_ERROR = {"mean_percent": "e_aver", "e_aver": "mean_percent", "max_percent": "max_abs", "max_abs": "max_percent"}


@dataclass
class Role:
    """A record's role, why (empty for plain fitted / held-out / built-from), and the records
    whose seeds must also agree for this row to agree on a seed (duplicates counted once)."""

    role: str
    note: str = ""
    joint: list[str] = field(default_factory=list)


def _measure_key(rec: Record, drop: tuple[str, ...] = ()) -> str:
    m = {k: v for k, v in (rec.measure or {}).items() if k not in drop}
    return json.dumps(m, sort_keys=True, default=str)


def is_qualitative(rec: Record) -> bool:
    """A bound at the neutral value: 0, or 1 for a dimensionless ratio (a direction, not a size)."""
    return (rec.range is None and rec.relation in ("<", ">", "<=", ">=")
            and (rec.value == 0 or (rec.value == 1 and rec.unit == "1")))


def _same_number(rec: Record, raw: dict[str, list[float]], by_key: dict[str, list[Record]],
                 role: dict[str, str]) -> str | None:
    """A fitted record whose simulated number is ``rec``'s on every seed (same measure), or None."""
    mine = raw.get(rec.id)
    if not mine or not all(math.isfinite(x) for x in mine):
        return None
    for other in by_key[_measure_key(rec)]:
        if other.id != rec.id and role[other.id] == "fitted" and raw.get(other.id) == mine:
            return other.id
    return None


def _same_error(rec: Record, records: list[Record]) -> Record | None:
    """The record holding the same eq. 3.21 error in the other form (percent / absolute), or None."""
    m = rec.measure or {}
    if m.get("name") != "transient_error" or m.get("stat") not in SAME_ERROR:
        return None
    key = _measure_key(rec, ("stat",))
    for other in records:
        om = other.measure or {}
        if other.id != rec.id and om.get("stat") == SAME_ERROR[m["stat"]] and _measure_key(other, ("stat",)) == key:
            return other
    return None


def assign_roles(records: list[Record], plan: CalibrationPlan, raw: dict[str, list[float]],
                 tolerances: dict[str, Tolerance | None], lab: Any) -> dict[str, Role]:
    """Every simulated record's :class:`Role` (module contract); ``raw`` the measure-unit values per seed."""
    sim = [r for r in records if r.measure is not None]
    base = {r.id: plan.role(r.id) for r in sim}
    by_key: dict[str, list[Record]] = {}
    for r in sim:
        by_key.setdefault(_measure_key(r), []).append(r)
    order = {r.id: i for i, r in enumerate(records)}
    out: dict[str, Role] = {}
    for rec in sim:
        if base[rec.id] != "held-out":
            out[rec.id] = Role(base[rec.id])
            continue
        if rec.id in plan.derived:
            srcs, how = plan.derived[rec.id]
            out[rec.id] = Role("derived", f"derived from {', '.join(srcs)}: {how}")
            continue
        twin = _same_number(rec, raw, by_key, base)
        if twin is not None:
            out[rec.id] = Role("derived", f"derived: the same simulated number as the fitted {twin} on every seed")
            continue
        pair = _same_error(rec, sim)
        if pair is not None and base[pair.id] == "fitted":
            out[rec.id] = Role("derived", f"derived: the same error as the fitted {pair.id}, in the other form "
                                          "(percent / absolute)")
            continue
        if pair is not None and base[pair.id] == "held-out" and order[pair.id] < order[rec.id]:
            out[rec.id] = Role("duplicate", f"duplicate: the same error as {pair.id} in the other form (percent / "
                                            "absolute), counted once with it")
            continue
        joint = [pair.id] if pair is not None and base[pair.id] == "held-out" else []
        if rec.id in plan.by_construction:
            out[rec.id] = Role("qualitative", f"true by construction: {plan.by_construction[rec.id]}", joint)
            continue
        if is_qualitative(rec):
            out[rec.id] = Role("qualitative", f"qualitative: a direction only ({rec.relation} {rec.value:g})", joint)
            continue
        why = vacuity(lab, rec, tolerances.get(rec.id))
        out[rec.id] = Role("uninformative", why, joint) if why else Role("held-out", "", joint)
    return out


__all__ = ["ROLES", "NEVER_COUNTED", "SAME_ERROR", "Role", "assign_roles", "is_qualitative"]
