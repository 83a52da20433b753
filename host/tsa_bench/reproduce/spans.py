"""Is a row's tolerance wider than the quantity's range over the experiment? (uninformative rows)

Units: lengths in mm, inputs in the experiment's unit (turn, V, ohm), resistance in ohm;
percent for the eq. 3.21 errors.

Contract: :func:`vacuity` returns why a record's tolerance cannot fail any plausible
simulation -- the text names the tolerance's effect and the range it is compared with --
or None. A tolerance is vacuous when its effect on the experiment's output is at least
the output's range over the experiment (the quasi-static samples of the cases the record
names, the mean range over those cases), on the first seed's runs:

* a polynomial coefficient p_i (Table 3.1, 3.2): the tolerance times the largest input
  to the power i, the length the tolerance moves the curve at the end of the input range;
* a polynomial curve (``poly_curve_gap``): the band the printed digits allow (each
  coefficient +- its rounding, at the largest input) plus the tolerance;
* a length (errors, length changes, steady lengths): the tolerance itself;
* an eq. 3.21 error: the tolerance against the run's resistance or length range (in
  percent of its mean for the percentage errors).

Other measures (strains, parameters, settings, ratios) have no range computed here and are
never called uninformative by this rule.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tsa_bench.reproduce.agreement import Tolerance
from tsa_bench.reproduce.measures import UNIT_OF_INPUT, measure_unit
from tsa_bench.reproduce.quantities import _cases, _list, case_fit
from tsa_bench.reproduce.records import Record
from tsa_bench.units import convert

LENGTH_MEASURES = {"model_error": None, "length_change": None, "scheme_length": "scheme"}


def _case_ranges(lab: Any, experiment: str, cond: dict[str, Any]) -> tuple[float, float]:
    """(mean output range mm, largest |input|) over the cases the conditions name."""
    spans, umax = [], 0.0
    for key, load in _cases(cond, experiment):
        cf = case_fit(lab, experiment, key, load)
        spans.append(float(np.ptp(cf.y)))
        umax = max(umax, abs(cf.u_min), abs(cf.u_max))
    return float(np.mean(spans)), umax


def _verdict(effect_mm: float, span_mm: float, what: str) -> str | None:
    if effect_mm < span_mm:
        return None
    return (f"uninformative: {what} {effect_mm:.3g} mm, at least the {span_mm:.3g} mm the output spans over "
            "the experiment")


def vacuity(lab: Any, rec: Record, tol: Tolerance | None) -> str | None:
    """Why ``rec``'s tolerance ``tol`` is vacuous on ``lab``'s runs, or None (module contract)."""
    m = rec.measure
    if tol is None or m is None:
        return None
    name = m["name"]
    mu = measure_unit(m, rec.conditions)
    half = convert(tol.half_width(rec.value), rec.unit, mu)
    if name == "poly_coefficient" and "stat" not in m:
        exp, i = m["experiment"], int(m["index"])
        span, umax = _case_ranges(lab, exp, rec.conditions)
        return _verdict(half * umax ** i, span, f"the tolerance moves p{i}'s term at {umax:.3g} "
                                                f"{UNIT_OF_INPUT[exp]} by")
    if name == "poly_curve_gap":
        exp = m["experiment"]
        span, umax = _case_ranges(lab, exp, rec.conditions)
        per = convert(1.0, m["unit"], f"mm/{UNIT_OF_INPUT[exp]}")
        band = per * sum(r * umax ** i for i, r in enumerate(m["rounding"]))
        return _verdict(band + half, span, f"the printed digits' band at {umax:.3g} {UNIT_OF_INPUT[exp]} "
                                           "plus the tolerance is")
    if name in LENGTH_MEASURES:
        exp = LENGTH_MEASURES[name] or m["experiment"]
        span, _ = _case_ranges(lab, exp, rec.conditions)
        return _verdict(half, span, "the tolerance is")
    if name == "transient_error":
        col = "resistance" if m["model"] == "strain-resistance" else "length"
        spans = []
        for d in _list(m["step_s"]):
            sim = lab.steps(float(d))
            y = (sim.resistance if col == "resistance" else sim.length)[sim.hist["motor_moving"] == 0]
            y = y[np.isfinite(y)]
            spans.append(100.0 * np.ptp(y) / np.mean(y) if mu == "%" else float(np.ptp(y)))
        span = float(np.mean(spans))
        if half < span:
            return None
        return f"uninformative: the tolerance {half:.3g} {mu} is at least the {span:.3g} {mu} the run's {col} spans"
    return None


__all__ = ["vacuity"]
