"""Agreement over noise seeds: the tolerance a row is judged by and the fraction of seeds that agree.

Units: every value in the record's own unit; a ``factor`` tolerance is dimensionless.

Contract:

* :func:`stated_tolerance` is the tolerance the record states, as an absolute half-width
  (``abs``, ``sd``, ``rel`` times the value, or the record's uncertainty when it states no
  tolerance) or a ``factor``; ranges and bounds have none (None).
* :func:`effective_tolerance` is never narrower than the simulation's seed-to-seed
  scatter combined with the thesis's stated uncertainty: half-width
  ``max(stated, K_SD * sqrt(s**2 + u**2))`` with ``s`` the sample standard deviation of
  the simulated values over the seeds and ``u`` the record's ``rounding`` or ``read_off``
  uncertainty (an ``sd`` is the spread of the thesis's errors or cases, which a ``sd:
  true`` tolerance already is); for a factor, the same in log space. ``K_SD = 2``: a
  simulation whose mean sits on the thesis's value then agrees on about 95 % of the seeds,
  so the :data:`AGREE_FRACTION` rule can be met (at 1 sd it would be 68 %).
* :func:`judge` says whether one simulated value agrees (within the tolerance, inside
  the range, on the right side of the bound); :func:`fraction` is the share of seeds that
  agree. A row agrees when that share is at least :data:`AGREE_FRACTION`; a row whose
  seeds disagree among themselves (0 < share < 1) is *unstable*.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tsa_bench.reproduce.records import Record

#: a row agrees when at least this share of its seeds agree
AGREE_FRACTION = 0.8
#: the seed scatter enters the tolerance at this many standard deviations
K_SD = 2.0
#: uncertainty kinds that are an uncertainty of the printed value itself
VALUE_UNCERTAINTIES = ("rounding", "read_off")


@dataclass(frozen=True)
class Tolerance:
    """``kind`` 'abs' (half-width, record unit) or 'factor'; ``stated`` the record's own; ``widened``
    when the seed scatter made it wider."""

    kind: str
    value: float
    stated: float
    widened: bool = False

    def text(self, unit: str) -> str:
        core = f"+-{self.value:.3g} {unit}" if self.kind == "abs" else f"x/{self.value:.3g}"
        return core + (" (seeds)" if self.widened else "")

    def half_width(self, value: float) -> float:
        """The largest accepted distance above ``value`` (record unit)."""
        return self.value if self.kind == "abs" else abs(value) * (self.value - 1.0)


def stated_tolerance(rec: Record) -> Tolerance | None:
    """The record's own tolerance (module contract); None for ranges and bounds."""
    if rec.range is not None or rec.relation not in ("=", "~"):
        return None
    t = rec.tolerance
    if not t:
        u = next(iter(rec.uncertainty.values()))
        return Tolerance("abs", u, u)
    kind, v = t["kind"], float(t["value"])
    if kind in ("abs", "sd"):
        return Tolerance("abs", v, v)
    if kind == "rel":
        return Tolerance("abs", v * abs(rec.value), v * abs(rec.value))
    return Tolerance("factor", v, v)


def value_uncertainty(rec: Record) -> float:
    """The thesis's stated uncertainty of the printed value (record unit; 0 when none is stated)."""
    return math.sqrt(sum(rec.uncertainty.get(k, 0.0) ** 2 for k in VALUE_UNCERTAINTIES))


def effective_tolerance(rec: Record, sims: list[float]) -> Tolerance | None:
    """The tolerance a row is judged by over the seeds ``sims`` (module contract)."""
    base = stated_tolerance(rec)
    if base is None:
        return None
    finite = [x for x in sims if math.isfinite(x)]
    u = value_uncertainty(rec)
    if base.kind == "abs":
        s = float(np.std(finite, ddof=1)) if len(finite) > 1 else 0.0
        floor = K_SD * math.hypot(s, u)
        return Tolerance("abs", floor, base.stated, True) if floor > base.value else base
    same_sign = [x for x in finite if x != 0 and (x > 0) == (rec.value > 0)]
    s = float(np.std(np.log(np.abs(same_sign)), ddof=1)) if len(same_sign) > 1 else 0.0
    u_log = u / abs(rec.value) if rec.value else 0.0
    floor = math.exp(K_SD * math.hypot(s, u_log))
    return Tolerance("factor", floor, base.stated, True) if floor > base.value else base


def judge(rec: Record, sim: float, tol: Tolerance | None) -> bool:
    """Does one simulated value (record unit) agree with the record under ``tol``?"""
    if not math.isfinite(sim):
        return False
    if rec.range is not None:
        return rec.range[0] <= sim <= rec.range[1]
    v = rec.value
    bound = {"<": sim < v, ">": sim > v, "<=": sim <= v, ">=": sim >= v}.get(rec.relation)
    if bound is not None:
        return bound
    assert tol is not None
    if tol.kind == "abs":
        return abs(sim - v) <= tol.value
    if v == 0 or sim == 0 or (sim > 0) != (v > 0):
        return False
    return 1.0 / tol.value <= sim / v <= tol.value


def fraction(agree: list[bool]) -> float:
    """Share of seeds that agree (0 for none)."""
    return sum(agree) / len(agree) if agree else 0.0


__all__ = ["AGREE_FRACTION", "K_SD", "Tolerance", "effective_tolerance", "fraction", "judge", "stated_tolerance",
           "value_uncertainty"]
