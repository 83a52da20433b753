"""Confusable causes and parameters at the edge of their range: what caps a cause's confidence.

Units: confidences are fractions; parameters in their own units.

Contract: a named cause whose held-out improvement a cause of another family matches
within the bootstrap interval (:func:`tsa_bench.analysis.naming.rivals_within_interval`)
is named **with** that alternative: the data cannot tell them apart, so its confidence
is capped at ``1 / (1 + alternatives)`` (0.5 with one), and the report says which
experiment would separate them (:func:`experiment`). A form parameter that ended at a
soft bound of its plausible range (a time constant longer than any the run can show,
say) caps the confidence at :data:`EDGE_CAP`: the form describes the data only at the
edge of its physics, and something else (a sensor drift, for a creep whose time
constant runs off) may be what the data show. :func:`cap` applies both and returns the
caveats.
"""

from __future__ import annotations

#: confidence of a cause with a form parameter at a soft bound of its range, at most
EDGE_CAP = 0.5

#: what experiment tells two confusable families apart
_SEPARATE: dict[frozenset[str], str] = {
    frozenset({"resistance_creep", "resistance_sensor_drift"}):
        "a hold as long as the run with the motor still and the heater off, with a fixed reference resistor read "
        "through the same channel at its start and end (a sensor drift moves the reference too, creep does not), "
        "then fast twist cycles (creep with travel grows with the turns, a drift with the time)",
    frozenset({"length_creep", "length_sensor_drift"}):
        "a gauge block (or the unloaded string) read by the length sensor at the start and end of a long still "
        "hold: a sensor drift moves it, creep does not",
    frozenset({"resistance_transient_decay", "resistance_creep"}):
        "holds of several minutes after each stop, then long holds without motion: the transient settles within "
        "minutes after every stop, creep keeps growing with time or travel",
    frozenset({"resistance_transient_decay", "resistance_sensor_drift"}):
        "holds of several minutes after each stop: the transient restarts at every stop, a drift does not",
    frozenset({"twist_hysteresis", "load_dependence"}):
        "twist cycles at two loads: the load dependence scales the hysteresis loop with the load, a play of fixed "
        "width does not change",
    frozenset({"length_creep", "twist_hysteresis"}):
        "twist steps up and down with long holds: creep keeps moving during the hold, hysteresis only at reversals",
    frozenset({"thermal_dynamics", "length_creep"}):
        "heater steps at constant twist and load: thermal dynamics follow the heater, creep the load changes",
    frozenset({"missed_steps", "twist_hysteresis"}):
        "a return to zero twist after the cycles: missed steps leave a lasting offset, hysteresis does not",
}
#: what tells two forms of one family apart
_FORMS: dict[str, str] = {
    "resistance_transient_decay": "holds longer than the decay after each stop (the tails of the forms differ after "
                                  "minutes)",
    "resistance_creep": "a long hold without motion (time without travel), then fast cycles (travel without time)",
    "length_creep": "a load change at constant twist, and a twist step at constant load",
    "missed_steps": "moves at several speeds under the same load, to twists below and above the top of the run",
    "length_sensor_drift": "readings at two very different lengths at the start and at the end: a gain drift changes "
                           "with the length, an offset drift does not",
    "resistance_sensor_drift": "a reference resistor of a very different value read at the start and at the end: a "
                               "gain drift changes with the value, an offset drift does not",
}


def experiment(family: str, other: str) -> str:
    """The experiment that separates ``family`` from ``other`` (two families, or one family's forms)."""
    if family == other:
        return _FORMS.get(family, "a run whose excitation differs where the forms' signatures differ (cause.png)")
    return _SEPARATE.get(frozenset({family, other}),
                         "a run that excites one and not the other: vary what their signatures follow (cause.png) "
                         "independently")


def cap(confidence: float, family: str, alternatives: list[dict], at_bound: list[dict]) -> tuple[float, list[str]]:
    """(capped confidence, caveats) of a named cause with these alternatives and form parameters at a
    soft bound (module docstring)."""
    caveats = []
    if alternatives:
        confidence = min(confidence, 1.0 / (1 + len(alternatives)))
        for a in alternatives:
            caveats.append(f"confusable with {a['effect']} ({a['form']}): it explains the held-out data as well "
                           f"(within the bootstrap interval); to tell them apart: {experiment(family, a['effect'])}")
    for b in at_bound:
        confidence = min(confidence, EDGE_CAP)
        caveats.append(f"{b['key']} ended at the {b['side']} edge of its plausible range ({b['bound']:.4g}): the "
                       "form fits only at the edge of its physics (confidence capped at "
                       f"{EDGE_CAP:.1f})")
    return confidence, caveats

