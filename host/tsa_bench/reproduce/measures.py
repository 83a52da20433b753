"""How each thesis quantity is computed on the simulated experiments: the named measures.

Units: each measure returns its value in the unit :func:`measure_unit` gives (mm, ohm,
%, s, N, deg, ...); the table converts the record's value into it.

Contract: :data:`MEASURES` maps a measure name to a :class:`MeasureSpec` (its allowed
arguments and unit) and a function ``f(lab, args, conditions) -> float``. A record
names a measure and its arguments (``measure: {name: ..., ...}``); the record's
``conditions`` (ply, scheme, load_g, step_s, ...) select the simulated cases, so the
same measure serves every load and string. The quantities follow the thesis's own
definitions:

* actuation (3.1): Preisach (M = 20) and third-order polynomial fitted per string and
  load on the quasi-static samples of the twist sweep or the heating run (motor
  stopped, last third of each hold, as ``tsa-bench fit``); errors E_aver and sigma
  (eqs. 3.5-3.6) over the pooled absolute errors of the cases named;
* self-sensing (3.2.1): the quasi-static samples of the 180 s holds at 20-55 turns
  (the last third of each), resistance in, length out;
* strains: eq. 2.2, ``(x_l - x) / x`` with ``x_l`` the loaded untwisted length;
  thermal: ``(x_twisted - x_heated) / x_heated``;
* transient (3.2.2): ``tsa-bench fit`` identifies strain-resistance and self-sensing
  on the 6 s and 32 s runs and validates on 2.4, 17 and 98 s (eq. 3.21 errors).

:class:`MeasureError` is raised for bad arguments (at load time) and for a case the
simulation cannot compute.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


UNIT_OF_INPUT = {"sweep": "turn", "heat": "V", "scheme": "ohm"}


class MeasureError(ValueError):
    """A measure that cannot be computed as asked; the message says why."""


@dataclass(frozen=True)
class MeasureSpec:
    """Allowed arguments ``{name: allowed values or type}`` and the unit function."""

    args: dict[str, Any]
    unit: Callable[[dict[str, Any], dict[str, Any]], str]
    doc: str


def _fixed(u: str) -> Callable[[dict[str, Any], dict[str, Any]], str]:
    return lambda a, c: u


def _poly_unit(a: dict[str, Any], c: dict[str, Any]) -> str:
    i = int(a.get("index", 0))
    unit_in = UNIT_OF_INPUT[a["experiment"]]
    return "mm" if i == 0 else f"mm/{unit_in}" if i == 1 else f"mm/{unit_in}^{i}"


def _path_unit(a: dict[str, Any], c: dict[str, Any]) -> str:
    suffix = str(a.get("path", "")).rsplit("_", 1)[-1]
    return {"mm": "mm", "ohm": "ohm", "A": "A", "N": "N", "g": "g", "s": "s", "C": "degC"}.get(suffix, "1")


def _transient_unit(a: dict[str, Any], c: dict[str, Any]) -> str:
    if a.get("stat") in ("mean_percent", "max_percent"):
        return "%"
    return "ohm" if a.get("model") == "strain-resistance" else "mm"


_PARAM_UNITS = {"Lambda": "1/s", "c": "ohm/mm", "a": "ohm/mm", "b1": "ohm", "b2": "ohm", "rho0": "ohm", "rho1": "1/ohm",
                "rho2": "1", "rho3": "ohm", "phi0": "ohm", "phi1": "1/ohm", "phi2": "1", "phi3": "ohm"}
_MANIP_UNITS = {"L0": "m", "r": "m", "w0": "m", "angle_range": "deg", "speed_at_3V6": "rev/s", "velocity_span": "deg", "rise_time": "s",
                "sse_mean": "deg", "sse_max": "deg"}
EXPERIMENTS = ("sweep", "heat", "scheme")

MEASURES: dict[str, MeasureSpec] = {
    "poly_coefficient": MeasureSpec({"experiment": EXPERIMENTS, "index": (0, 1, 2, 3), "stat": ("max_abs",)},
                                    _poly_unit, "coefficient p_i of the cubic fitted to the case (eq. 3.4)"),
    "poly_curve_gap": MeasureSpec({"experiment": EXPERIMENTS, "coefficients": list, "rounding": list, "unit": str},
                                  _fixed("mm"),
                                  "how far the simulated cubic strays outside the band the thesis's printed "
                                  "coefficients allow (each +- its rounding), over the simulated input range"),
    "model_error": MeasureSpec({"experiment": EXPERIMENTS, "model": ("preisach", "polynomial"),
                                "stat": ("e_aver", "sigma", "worst_case")}, _fixed("mm"),
                               "pooled E_aver / sigma (eqs. 3.5-3.6) of the cases, or the worst case's E_aver"),
    "error_ratio": MeasureSpec({"experiment": EXPERIMENTS + ("heat_vs_sweep",)}, _fixed("1"),
                               "polynomial over Preisach E_aver (heat_vs_sweep: polynomial heating over twisting)"),
    "length_change": MeasureSpec({"experiment": EXPERIMENTS, "stat": ("mean", "sd")}, _fixed("mm"),
                                 "per case largest minus smallest quasi-static length; mean or sd over cases"),
    "strain": MeasureSpec({"kind": ("passive", "active", "thermal", "increase")}, _fixed("%"),
                          "eq. 2.2 contraction from the heating run, mean over the loads"),
    "scheme_length": MeasureSpec({"turns": float}, _fixed("mm"), "steady length at a twist level (first visit)"),
    "scheme_contraction": MeasureSpec({"from_turns": float, "to_turns": float}, _fixed("%"),
                                      "(L(from) - L(to)) / L(to) of the steady lengths"),
    "load_effect": MeasureSpec({"column": ("length", "resistance")}, lambda a, c: "mm" if a["column"] == "length"
                               else "ohm", "least difference heavier minus lighter load at equal twist"),
    "length_resistance_correlation": MeasureSpec({}, _fixed("1"), "correlation of steady R and L"),
    "loop_width_ratio": MeasureSpec({}, _fixed("1"), "R-L loop width over R span, Scheme 2 / Scheme 1"),
    "load_error_ratio": MeasureSpec({"experiment": EXPERIMENTS, "model": ("preisach", "polynomial")}, _fixed("1"),
                                    "E_aver at the lighter load over the heavier"),
    "scheme_error_ratio": MeasureSpec({"model": ("preisach", "polynomial")}, _fixed("1"),
                                      "Scheme 1 over Scheme 2 E_aver"),
    "p0_load_trend": MeasureSpec({}, _fixed("mm"), "least rise of the twisting p0 from one load to the next"),
    "stiffness": MeasureSpec({}, _fixed("N"), "K of eq. 2.1 from a linear fit of length against load, no twist"),
    "stiffness_fit_error": MeasureSpec({"stat": ("e_aver",)}, _fixed("mm"), "E_aver of that linear fit"),
    "plant_setting": MeasureSpec({"path": str, "preset": str, "preset_for": dict, "scale": float}, _path_unit,
                                 "a parameter of the preset's plant (dotted path), times scale"),
    "bench_setting": MeasureSpec({"path": ("sense_current_A",), "preset": str}, _path_unit,
                                 "a setting of the preset's bench file"),
    "thermal_time": MeasureSpec({"phase": ("heating", "cooling")}, _fixed("s"),
                                "time to 90 % of the thermal contraction (heating) or 95 % recovery (cooling)"),
    "decay_settle_time": MeasureSpec({}, _fixed("s"), "time after a stop until the resistance decay is within 5 %"),
    "hold_length_drift": MeasureSpec({}, _fixed("mm"), "length change over a 200 s hold (noise-free)"),
    "run_level": MeasureSpec({"column": ("length", "resistance")}, lambda a, c: "mm" if a["column"] == "length"
                             else "ohm", "mean over the step-duration runs' hold samples"),
    "transient_error": MeasureSpec({"model": ("strain-resistance", "self-sensing"), "step_s": object,
                                    "stat": ("mean_percent", "e_aver", "max_percent", "max_abs")}, _transient_unit,
                                   "eq. 3.21 / absolute error of the identified model on a step-duration run"),
    "model_parameter": MeasureSpec({"model": ("strain-resistance", "self-sensing"), "parameter": tuple(_PARAM_UNITS),
                                    "index": (0, 1)}, lambda a, c: _PARAM_UNITS[a["parameter"]],
                                   "identified parameter (Table 3.3)"),
    "lifetime": MeasureSpec({"quantity": ("duration", "length_creep_fraction", "resistance_creep")},
                            lambda a, c: {"duration": "h", "length_creep_fraction": "1",
                                          "resistance_creep": "ohm"}[a["quantity"]], "596-cycle lifetime run"),
    "manipulator": MeasureSpec({"quantity": tuple(_MANIP_UNITS), "setpoint_deg": float},
                               lambda a, c: _MANIP_UNITS[a["quantity"]], "soft manipulator model and P control"),
}


def measure_unit(measure: dict[str, Any], conditions: dict[str, Any]) -> str:
    """Check a record's measure arguments; return the unit the measure computes in."""
    spec = MEASURES[measure["name"]]
    for key, val in measure.items():
        if key == "name":
            continue
        if key not in spec.args:
            raise MeasureError(f"{measure['name']}: unknown argument {key!r} (allowed: {', '.join(spec.args) or 'none'})")
        allowed = spec.args[key]
        if isinstance(allowed, tuple) and val not in allowed:
            raise MeasureError(f"{measure['name']}: {key} must be one of {', '.join(map(str, allowed))}, got {val!r}")
        if allowed is float and (isinstance(val, bool) or not isinstance(val, (int, float))):
            raise MeasureError(f"{measure['name']}: {key} must be a number, got {val!r}")
        if allowed in (str, dict, list) and not isinstance(val, allowed):
            raise MeasureError(f"{measure['name']}: {key} must be a {allowed.__name__}, got {val!r}")
    if measure["name"] == "poly_curve_gap":
        coeffs, rounding, unit = measure.get("coefficients"), measure.get("rounding"), measure.get("unit")
        for what, vals in (("coefficients", coeffs), ("rounding", rounding)):
            if not (isinstance(vals, list) and 2 <= len(vals) <= 6
                    and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in vals)):
                raise MeasureError(f"poly_curve_gap: {what} must be a list of 2-6 numbers, lowest order first")
        if len(rounding) != len(coeffs) or min(rounding) < 0:
            raise MeasureError("poly_curve_gap: one rounding (>= 0) per coefficient")
        from tsa_bench.units import UnitError, parse_unit
        try:
            u = parse_unit(str(unit))
        except UnitError as exc:
            raise MeasureError(f"poly_curve_gap: {exc}") from None
        if dict(u.signature).get("length") != 1:
            raise MeasureError(f"poly_curve_gap: unit '{unit}' must be a length per input unit (e.g. cm/turn)")
    required = {"poly_coefficient": ("experiment", "index"),
                "poly_curve_gap": ("experiment", "coefficients", "rounding", "unit"), "model_error": ("experiment", "model", "stat"),
                "error_ratio": ("experiment",), "length_change": ("experiment", "stat"), "strain": ("kind",),
                "scheme_length": ("turns",), "scheme_contraction": ("from_turns", "to_turns"),
                "load_effect": ("column",), "plant_setting": ("path",), "bench_setting": ("path",),
                "thermal_time": ("phase",), "run_level": ("column",), "transient_error": ("model", "step_s", "stat"),
                "model_parameter": ("model", "parameter"), "lifetime": ("quantity",), "manipulator": ("quantity",),
                "load_error_ratio": ("experiment", "model"), "scheme_error_ratio": ("model",)}
    for key in required.get(measure["name"], ()):
        if key not in measure:
            raise MeasureError(f"{measure['name']}: missing argument {key!r}")
    return spec.unit(measure, conditions)

