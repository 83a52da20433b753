"""The text of the `tsa-bench diagnose` report: one screen, the verdict first.

Contract: :func:`format_report` takes a diagnose result (read by attribute, so any
object with the :class:`tsa_bench.analysis.DiagnoseResult` fields works) and the runs
and returns the report: the verdict line (``VERDICT: <verdict>: ...``) and what to do
about it, then the data and judged model, the noise model, the named causes (dominant
first, with form, confidence, own held-out improvement and its interval, meaning,
source and caveats), what is left unexplained and what the residual follows, the reasons
of a model mismatch with their remedies, the held-out RMSE before and after with units,
the residual structure before and after, the best form of each candidate effect, and the
calibration (parameters at a bound or not determined by the data first). Lines are never
wrapped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

OUTPUT_UNITS = {"length": "mm", "resistance": "ohm"}
_PLANT_UNITS = {"untwisted_length_mm": "mm", "radius_mm": "mm", "resistance_ohm": "ohm"}
_ADVICE = {
    "explained": "The judged model, calibrated to these data, leaves only what the sensors' noise explains.",
    "named": "Add the named effect(s) to the model (their fitted parameters are below) and diagnose again.",
    "unexplained": "None of the candidate effects explains the structure left; look at residuals.png and the "
                   "signals it follows.",
    "model_mismatch": "The judged model cannot represent these data; fix what is listed below before reading "
                      "anything else.",
}


def _num(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    try:
        v = float(x)
    except (TypeError, ValueError):
        return str(x)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if v == 0:
        return "0"
    if 1e-3 <= abs(v) < 1e5:
        return f"{v:.{digits}g}"
    return f"{v:.{max(digits - 2, 1)}e}"


def _pct(x: Any) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "-"
    return "-" if math.isnan(v) else f"{100 * v:+.1f} %"


def _effects() -> dict[str, dict]:
    try:
        from tsa_bench.sim.effects import describe_effects, describe_forms
        return {e["name"]: e for e in describe_effects() + describe_forms()}
    except Exception:  # the report must still come out if the library changes
        return {}


def _units(key: str, effects: Mapping[str, dict]) -> str:
    head, _, name = key.partition(".")
    if head == "geometry":
        return _PLANT_UNITS.get(name, "")
    for p in effects.get(head, {}).get("params", []):
        if p["name"] == name:
            return p["units"]
    return ""


def _run_line(run: Any) -> str:
    try:
        t = np.asarray(run.samples["t"], dtype=float)
        span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
        rate = 1.0 / float(np.median(np.diff(t))) if len(t) > 1 and np.median(np.diff(t)) > 0 else float("nan")
    except Exception:
        return f"  {getattr(run, 'path', run)}"
    dur = f"{span / 3600:.2f} h" if span >= 3600 else (f"{span / 60:.1f} min" if span >= 60 else f"{span:.1f} s")
    return (f"  {Path(str(run.path)).name}: {len(t)} samples, {dur}, {_num(rate, 3)} Hz, "
            f"exit {getattr(run, 'exit_status', '') or '?'}")


def _structure_cell(t: Mapping | None, units: str) -> str:
    if not t:
        return "-"
    if not t.get("testable", True):
        return "not testable"
    if t.get("structured"):
        return f"STRUCTURED {_num(t.get('structured_rms'), 3)} {units}"
    return f"noise (RMS {_num(t.get('rms'), 3)} {units})"


def _follows(t: Mapping | None) -> str:
    fl = (t or {}).get("follows") or []
    return ", ".join(f"{f['signal']} {100 * f['share']:.0f} %" for f in fl[:3])


def format_report(result: Any, runs: Sequence[Any] = ()) -> str:
    """The report text (see the module docstring)."""
    effects = _effects()
    verdict = getattr(result, "verdict", "?")
    outputs = list(getattr(result, "outputs", ("length", "resistance")))
    lines = [f"VERDICT: {getattr(result, 'summary', verdict)}", f"  {_ADVICE.get(verdict, '')}", ""]

    if runs:
        lines.append("Data:")
        lines += [_run_line(r) for r in runs]
    before = list(getattr(result, "model_effects_before", []) or [])
    prov = getattr(result, "provenance", {}) or {}
    model = (prov.get("model") or {}).get("path") or "the given plant"
    lines.append(f"Judged model: {model}: {', '.join(before) or 'no effects'}")
    hold = getattr(result, "holdout", {}) or {}
    series = getattr(result, "series", {}) or {}
    held = series.get("heldout") if isinstance(series, Mapping) else None
    frac = f"{100 * float(np.mean(np.asarray(held, bool))):.0f} % of the samples: " if held is not None and len(held) \
        else ""
    if hold:
        lines.append(f"Held out: {frac}{hold.get('description', '')}")
    noise = getattr(result, "noise", {}) or {}
    if noise:
        parts = []
        for o, nz in noise.items():
            u = OUTPUT_UNITS.get(o, "")
            step = f", step {_num(nz.get('quantisation_step'), 3)} {u}" if nz.get("quantisation_step") else ""
            parts.append(f"{o} {_num(nz.get('rms'), 3)} {u}{step}")
        lines.append("Noise (from the data): " + "; ".join(parts) + "; structure below half of it is not called "
                     "structure")
    lines.append("")

    for m in getattr(result, "mismatch", []) or []:
        lines.append(f"MISMATCH: {m['reason']}")
        lines.append(f"  what to do: {m['remedy']}")
    if getattr(result, "mismatch", None):
        lines.append("")

    named = list(getattr(result, "named", []) or [])
    if named:
        lines.append("Named causes (dominant first):")
        for i, c in enumerate(named, 1):
            e = effects.get(c.variant) or effects.get(c.effect) or {}
            lines.append(f"  {i}. {c.effect} ({c.form})  confidence {c.confidence:.2f}, form {c.form_confidence:.2f}"
                         f"; acts on {c.output}")
            if getattr(c, "kind", "effect") == "variance component":
                lines.append(f"     offsets' variance {_num(c.own_improvement, 3)} noise variances (95 % "
                             f"{_num(c.ci95[0], 3)} to {_num(c.ci95[1], 3)}); not a gain: no model predicts it")
            else:
                lines.append(f"     own held-out improvement on the {c.output} {_num(c.own_improvement, 3)} noise "
                             f"variances per sample (95 % {_num(c.ci95[0], 3)} to {_num(c.ci95[1], 3)})")
            for a in getattr(c, "alternatives", []) or []:
                lines.append(f"     or: {a['effect']} ({a['form']}), held-out improvement "
                             f"{_num(a['improvement_noise_var'], 3)} (95 % {_num(a['ci95'][0], 3)} to "
                             f"{_num(a['ci95'][1], 3)}): the data cannot tell them apart")
            if e:
                lines.append(f"     meaning: {e.get('doc', '').replace('``', '')}")
                lines.append(f"     source: {e.get('source', '')}")
            for cav in c.caveats:
                lines.append(f"     caveat: {cav}")
        lines.append("")
    for u in getattr(result, "unexplained", []) or []:
        lines.append(f"Unexplained: {u['text']} (structured RMS {_num(u.get('structured_rms'), 3)} "
                     f"{u.get('units', '')})")
    for p in getattr(result, "partial", []) or []:
        lines.append(f"Not named: {p['effect']} ({p['form']}): {p.get('why', '')}")
    if getattr(result, "unexplained", None) or getattr(result, "partial", None):
        lines.append("")

    gains = list(getattr(result, "gain", []) or [])
    if gains:
        lines += _gain_lines(gains)
    lines += _validation_lines(getattr(result, "validation", []) or [])
    tests = getattr(result, "residual_tests", {}) or {}
    if tests:
        lines.append("Residual structure, judged -> final model (structured RMS; follows: share of it):")
        for o in outputs:
            b, a = (tests.get("before") or {}).get(o), (tests.get("after") or {}).get(o)
            u = OUTPUT_UNITS.get(o, "")
            fb, fa = _follows(b), _follows(a)
            cell_b = _structure_cell(b, u) + (f" (follows {fb})" if fb and fb != fa else "")
            lines.append((f"  {o:<10}  {cell_b} -> {_structure_cell(a, u)}" + (f" (follows {fa})" if fa else "")
                          ).rstrip())
    lines.append("")

    cands = list(getattr(result, "candidates", []) or [])
    if cands:
        best: dict[str, Any] = {}
        named_variants = {c.variant for c in named}
        for c in cands:
            fam = (c.evidence or {}).get("family", c.name)
            refit = (c.evidence or {}).get("refit")
            key = (c.name in named_variants, refit is not None and bool(refit.get("passed")), refit is not None, c.score)
            if fam not in best or key > best[fam][0]:
                best[fam] = (key, c)
        lines.append("Candidate effects (best form; screen = share of the residual its signature explains):")
        for fam, (_, c) in sorted(best.items(), key=lambda kv: tuple(-float(k) for k in kv[1][0])):
            ev = c.evidence or {}
            refit = ev.get("refit")
            tail = ""
            if refit:
                imp = refit["heldout"]["improvement_noise_var"]["pooled"]
                tail = f"  refit: {_num(imp, 3)} noise var, {'named' if refit['passed'] else refit['reason']}"
            lines.append(f"  {fam:<27} {ev.get('form', ''):<27} screen {c.score:5.3f}{tail}")
        lines.append("")

    cal = getattr(result, "calibration", {}) or {}
    calibrated = getattr(result, "calibrated", {}) or {}
    final = cal.get("final") or {}
    flagged = [b["key"] for b in final.get("at_bound", [])]
    lines.append("Calibration (training part), judged -> final model:")
    if final.get("at_bound"):
        lines.append("  at a bound: " + ", ".join(f"{b['key']} = {_num(b['value'])} ({b['side']} bound)"
                                                  for b in final["at_bound"]))
    if final.get("undetermined"):
        lines.append("  not determined by these data (kept near the model's value): " + ", ".join(final["undetermined"]))
    b, a = calibrated.get("before") or {}, calibrated.get("after") or {}
    keys = list(b) + [k for k in a if k not in b]
    width = max((len(k) for k in keys), default=10)
    for k in keys:
        mark = "  (at bound)" if k in flagged else ""
        lines.append(f"  {k:<{width}}  {_num(b.get(k), 5) if k in b else '-':>11} -> {_num(a.get(k), 5):>11} "
                     f"{_units(k, effects)}{mark}".rstrip())
    notes = list(getattr(result, "notes", []) or [])
    if notes:
        lines.append("")
        lines.append("Notes:")
        lines += [f"  - {n}" for n in notes]
    return "\n".join(lines) + "\n"


def _ci(ci: Any) -> str:
    try:
        lo, hi = ci
    except (TypeError, ValueError):
        return ""
    if lo is None or hi is None or not (math.isfinite(float(lo)) and math.isfinite(float(hi))):
        return ""
    return f" (95 % {_num(lo, 3)} to {_num(hi, 3)})"


def _times(x: float, of: float) -> str:
    return f"{x / of:.2f}x" if of and math.isfinite(of) and of > 0 and math.isfinite(x) else "-"


def _gain_lines(gains: list) -> list[str]:
    """Held-out RMSE per output, judged -> final, with intervals and as multiples of the noise RMS."""
    out = ["Held-out RMSE, judged -> final model (95 % block-bootstrap intervals; final / noise RMS):"]
    for g in gains:
        u = OUTPUT_UNITS.get(g.output, "")
        noise = getattr(g, "noise_rms", float("nan"))
        settle = getattr(g, "settling_sd", 0.0)
        tail = f"{_times(g.heldout_rmse_after, noise)} the noise"
        if settle:
            tail += f", {_times(g.heldout_rmse_after, math.hypot(noise, settle))} noise and hold-to-hold offsets"
        out.append(f"  {g.output:<10}  {_num(g.heldout_rmse_before)} {u}{_ci(getattr(g, 'before_ci95', None))} -> "
                   f"{_num(g.heldout_rmse_after)} {u}{_ci(getattr(g, 'after_ci95', None))}  {_pct(g.relative)}; "
                   f"reduction{_ci(getattr(g, 'reduction_ci95', None))} {u}; {tail}")
    return out


def _validation_lines(rows: list[dict]) -> list[str]:
    """Prospective validation: runs never used to calibrate or select."""
    if not rows:
        return []
    out = ["Prospective validation (runs never used to calibrate or select), judged -> extended model:"]
    for v in rows:
        u = OUTPUT_UNITS.get(v["output"], "")
        out.append(f"  {Path(v['run']).name} {v['output']:<10}  whole run {_num(v['rmse_judged'])} {u} -> "
                   f"{_num(v['rmse'])} {u}{_ci(v.get('rmse_ci95'))} = {_times(v['rmse'], v['noise_rms'])} its noise; "
                   f"the part diagnose would hold out {_num(v.get('rmse_heldout_part'))} {u}; mean offset "
                   f"{_num(v['offset'], 3)} {u}{_ci(v.get('offset_ci95'))}, without it {_num(v['rmse_offset_removed'])} {u}")
    return out
