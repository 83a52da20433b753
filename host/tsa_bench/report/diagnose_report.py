"""The `tsa-bench diagnose` report: a text summary read in a minute, PNG figures, JSON.

Contract: :func:`write_report` takes a ``DiagnoseResult`` (tsa_bench.analysis) and the
runs it was computed from and writes, into ``out_dir``:

* ``report.txt`` - :func:`format_report`: which outputs show residual structure
  (Ljung-Box p, cross-correlations beyond their bounds) before and after, the ranked
  candidate table, the named cause(s) with physical meaning and thesis source (from
  ``describe_effects()``), held-out RMSE before/after per output with units and
  relative gain, calibrated parameters with units, or a plain statement that no
  significant unmodelled effect was found;
* ``fit.png`` - measured vs simulated, before and after, both outputs, held-out part shaded;
* ``residuals.png`` - residual vs time, before and after, both outputs;
* ``cause.png`` - residual against the named cause's signal (only when a cause is
  named and ``series["cause_signal"]`` is present).

It returns ``{"report": path, "fit": path, ...}``. The result is read by attribute
only (duck typing), so any object with the DiagnoseResult fields works. Figures use the
Agg backend and never open a window; long series (100k samples and more) are
decimated for plotting (min/max envelope per bin for lines, a strided subset for
scatter), so a figure costs well under a second. :func:`write_json` writes
``result.to_json()`` as strict JSON (NaN/inf -> null, numpy scalars -> numbers).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["format_report", "write_figures", "write_json", "write_report", "OUTPUT_UNITS"]

OUTPUTS = ("length", "resistance")
#: Units of the judged outputs (run-file contract, docs/run-format.md).
OUTPUT_UNITS = {"length": "mm", "resistance": "ohm"}
#: Units of plant-level parameters (tsa_bench.sim.plant PLANT_KEYS).
_PLANT_UNITS = {"untwisted_length_mm": "mm", "radius_mm": "mm", "resistance_ohm": "ohm", "ambient_C": "degC",
                "initial_load_g": "g"}
#: Evidence keys shown first in the candidate table, when present.
_EVIDENCE_FIRST = ("output", "delta_bic", "err", "error_reduction", "explained", "heldout_gain", "r", "xcorr",
                   "p", "p_value")
_MAX_PLOT_BINS = 2000
_MAX_SCATTER = 6000
_MAX_SPANS = 60


# --------------------------------------------------------------------------- helpers

def _effects_by_name() -> dict[str, dict]:
    try:
        from tsa_bench.sim.effects import describe_effects
        return {e["name"]: e for e in describe_effects()}
    except Exception:  # the report must still come out if the library changes
        return {}


def _num(x: Any, digits: int = 4) -> str:
    """A compact number: 4 significant digits, exponent for very small/large values."""
    if x is None:
        return "-"
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
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


def _p(x: Any) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "-"
    if math.isnan(v):
        return "nan"
    return "<1e-16" if v < 1e-16 else _num(v, 3)


def _pct(x: Any) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "-"
    return "nan" if math.isnan(v) else f"{100 * v:+.1f} %"


def _evidence_text(evidence: Mapping | None, limit: int = 3) -> str:
    if not evidence:
        return ""
    keys = [k for k in _EVIDENCE_FIRST if k in evidence]
    keys += [k for k in evidence if k not in keys]
    parts = []
    for k in keys:
        v = evidence[k]
        if isinstance(v, Mapping):
            continue
        if isinstance(v, (list, tuple, np.ndarray)):
            if len(v) > 3:
                continue
            v = "(" + ", ".join(_num(e, 3) for e in v) + ")"
        elif not isinstance(v, str):
            v = _num(v)
        parts.append(f"{k}={v}")
        if len(parts) >= limit:
            break
    return ", ".join(parts)


def _xcorr_beyond(xcorr: Mapping | None) -> list[tuple[str, float, float]]:
    """Signals whose |r| exceeds their bound, strongest first."""
    out = []
    for sig, rb in (xcorr or {}).items():
        try:
            r, bound = float(rb[0]), float(rb[1])
        except (TypeError, ValueError, IndexError, KeyError):
            continue
        if abs(r) > bound:
            out.append((str(sig), r, bound))
    return sorted(out, key=lambda item: -abs(item[1]) / max(item[2], 1e-300))


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, Mapping) and not ({"value"} <= set(value) and not any(isinstance(v, Mapping)
                                                                                for v in value.values())):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else str(k), v, out)
    else:
        out[prefix] = value


def _param_units(key: str, effects: Mapping[str, dict]) -> str:
    parts = key.split(".")
    if len(parts) >= 2 and parts[-2] in effects:
        for p in effects[parts[-2]].get("params", []):
            if p["name"] == parts[-1]:
                return p["units"]
    if parts[-1] in _PLANT_UNITS:
        return _PLANT_UNITS[parts[-1]]
    return ""


def _calibrated_lines(calibrated: Mapping | None, effects: Mapping[str, dict]) -> list[str]:
    cal = calibrated or {}
    if cal and set(cal) <= {"before", "after"} and all(isinstance(v, Mapping) for v in cal.values()):
        return _calibrated_before_after(cal, effects)
    flat: dict[str, Any] = {}
    _flatten("", calibrated or {}, flat)
    flat = {k: v for k, v in flat.items() if k.split(".")[-1] != "enabled"}
    if not flat:
        return ["  (none: the model has no free parameters, or none were calibrated)"]
    width = max(len(k) for k in flat)
    lines = []
    for key, v in flat.items():
        units = ""
        if isinstance(v, Mapping):  # {"value": x, "units": u, ...}
            units = str(v.get("units", ""))
            extra = {k: w for k, w in v.items() if k not in ("value", "units")}
            v = v.get("value")
            tail = ("  " + ", ".join(f"{k} {_num(w, 3)}" for k, w in extra.items())) if extra else ""
        else:
            tail = ""
        units = units or _param_units(key, effects)
        lines.append(f"  {key:<{width}}  {_num(v, 5)} {units}".rstrip() + tail)
    return lines


def _plain_value(v: Any) -> tuple[Any, str]:
    if isinstance(v, Mapping):
        return v.get("value"), str(v.get("units", ""))
    return v, ""


def _calibrated_before_after(cal: Mapping, effects: Mapping[str, dict]) -> list[str]:
    """Side-by-side table: judged model's calibration vs the extended model's."""
    flat = {}
    for stage in ("before", "after"):
        f: dict[str, Any] = {}
        _flatten("", cal.get(stage) or {}, f)
        flat[stage] = {k: v for k, v in f.items() if k.split(".")[-1] != "enabled"}
    keys = list(flat["before"]) + [k for k in flat["after"] if k not in flat["before"]]
    if not keys:
        return ["  (none: the model has no free parameters, or none were calibrated)"]
    width = max(len(k) for k in keys)
    lines = [f"  {'parameter':<{width}}  {'judged model':>14}  {'extended model':>14}  units"]
    for k in keys:
        vb, ub = _plain_value(flat["before"].get(k))
        va, ua = _plain_value(flat["after"].get(k))
        units = ub or ua or _param_units(k, effects)
        lines.append(f"  {k:<{width}}  {_num(vb, 5) if k in flat['before'] else '-':>14}  "
                     f"{_num(va, 5) if k in flat['after'] else '-':>14}  {units}".rstrip())
    return lines


def _run_line(run: Any) -> str:
    try:
        t = np.asarray(run.samples["t"], dtype=float)
        span = float(t[-1] - t[0]) if len(t) else 0.0
        n = len(t)
    except Exception:
        return f"  {getattr(run, 'path', run)}"
    dur = f"{span / 3600:.2f} h" if span >= 3600 else (f"{span / 60:.1f} min" if span >= 60 else f"{span:.1f} s")
    status = getattr(run, "exit_status", "") or "?"
    return f"  {Path(str(run.path)).name}: {n} samples, {dur}, exit {status}"


# --------------------------------------------------------------------------- text

def format_report(result: Any, runs: Sequence[Any] = ()) -> str:
    """The report text (see the module docstring)."""
    effects = _effects_by_name()
    causes = list(getattr(result, "causes", None) or ([result.cause] if getattr(result, "cause", None) else []))
    tests = getattr(result, "residual_tests", None) or {}
    lines: list[str] = ["tsa-bench diagnose: where the simulation disagrees with the data, and why", ""]

    if runs:
        lines.append(f"Data ({len(runs)} run{'s' if len(runs) != 1 else ''}):")
        lines += [_run_line(r) for r in runs]
    before_fx = list(getattr(result, "model_effects_before", []) or [])
    after_fx = list(getattr(result, "model_effects_after", []) or [])
    lines.append(f"Judged model: {len(before_fx)} effects on ({', '.join(before_fx) or 'none'})")
    added = [e for e in after_fx if e not in before_fx]
    if added:
        lines.append(f"Extended model adds: {', '.join(added)}")
    series = getattr(result, "series", None) or {}
    held = series.get("heldout") if isinstance(series, Mapping) else None
    if held is not None and len(held):
        frac = float(np.mean(np.asarray(held, dtype=bool)))
        lines.append(f"Held-out part: {100 * frac:.0f} % of the samples (scores and gains are on it)")
    lines.append("")

    # --- verdict first: what a scientist wants to know
    if causes:
        lines.append("VERDICT: unmodelled effect" + ("s" if len(causes) > 1 else "") + " found: "
                     + ", ".join(causes))
    else:
        left = [o for o, t in ((tests.get("after") or tests.get("before") or {}).items())
                if isinstance(t, Mapping) and t.get("structured")]
        if left:
            lines.append("VERDICT: no significant unmodelled effect was found among the candidates, but the "
                         f"residual of {', '.join(left)} still shows structure (see below).")
        else:
            lines.append("VERDICT: no significant unmodelled effect was found; the calibrated model explains "
                         "the data to within its residual tests.")
    lines.append("")

    # --- residual structure
    lines.append("Residual structure (Ljung-Box whiteness; cross-correlations beyond their bounds):")
    any_tests = False
    for stage in ("before", "after"):
        per_out = tests.get(stage) or {}
        if not per_out:
            continue
        any_tests = True
        for out in OUTPUTS if any(o in per_out for o in OUTPUTS) else list(per_out):
            t = per_out.get(out)
            if t is None:
                continue
            structured = t.get("structured")
            beyond = _xcorr_beyond(t.get("xcorr"))
            xc = ", ".join(f"{s} r={r:+.2f} (bound {b:.2f})" for s, r, b in beyond[:4])
            if len(beyond) > 4:
                xc += f", +{len(beyond) - 4} more"
            lines.append(f"  {stage:<6} {out:<10}  LB p={_p(t.get('ljung_box_p')):<8} "
                         f"{'STRUCTURED' if structured else 'white     '}  "
                         f"xcorr beyond bound: {xc or 'none'}")
    if not any_tests:
        lines.append("  (no residual tests in the result)")
    lines.append("")

    # --- candidates: library effects, then generic signals, each by score
    cands = list(getattr(result, "candidates", None) or [])
    lines.append("Candidate causes by score (fraction of the training residual explained; higher = more):")
    if cands:
        wname = max(12, max(len(str(c.name)) for c in cands))
        lines.append(f"  {'#':>2}  {'name':<{wname}}  {'kind':<6}  {'score':>10}  key evidence")
        groups = [[c for c in cands if c.kind == "effect"], [c for c in cands if c.kind != "effect"]]
        for g, group in enumerate(groups):
            if g == 1 and group:
                lines.append("      generic signals (interpret the residual; never named as a cause):")
            group.sort(key=lambda c: -float(c.score) if np.isfinite(float(c.score)) else math.inf)
            for i, c in enumerate(group, 1):
                mark = " *" if c.name in causes else ""
                lines.append(f"  {i:>2}  {str(c.name):<{wname}}  {str(c.kind):<6}  {_num(c.score):>10}  "
                             f"{_evidence_text(getattr(c, 'evidence', None))}{mark}")
        if causes:
            lines.append("  (* = named cause)")
    else:
        lines.append("  (no candidates were scored)")
    lines.append("")

    # --- named causes with physical meaning
    if causes:
        lines.append("Named cause" + ("s" if len(causes) > 1 else "") + " (in the order found):")
        for i, name in enumerate(causes, 1):
            e = effects.get(name)
            if e:
                lines.append(f"  {i}. {name}  [{e['stage']} stage]")
                lines.append(f"     meaning: {e['doc'].replace('``', '')}")
                lines.append(f"     source:  {e['source']}")
            else:
                lines.append(f"  {i}. {name}  (not an effect of the plant's library; a generic signal)")
        lines.append("")

    # --- gain
    gains = list(getattr(result, "gain", None) or [])
    lines.append("Held-out RMSE, judged model -> extended model (gain = (before - after) / before):")
    if gains:
        lines.append(f"  {'output':<10}  {'before':>14}  {'after':>14}  {'gain':>9}")
        for g in gains:
            u = OUTPUT_UNITS.get(g.output, "")
            lines.append(f"  {g.output:<10}  {_num(g.heldout_rmse_before) + ' ' + u:>14}  "
                         f"{_num(g.heldout_rmse_after) + ' ' + u:>14}  {_pct(g.relative):>9}")
    else:
        lines.append("  (no held-out comparison)")
    lines.append("")

    # --- calibrated parameters
    lines.append("Calibrated parameters (fitted to the training part):")
    lines += _calibrated_lines(getattr(result, "calibrated", None), effects)

    notes = list(getattr(result, "notes", None) or [])
    if notes:
        lines.append("")
        lines.append("Notes:")
        lines += [f"  - {n}" for n in notes]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- figures

def _time_axis(t: np.ndarray) -> tuple[np.ndarray, str]:
    """Monotonic time (runs concatenated end to end when t restarts) in s, min or h."""
    t = np.asarray(t, dtype=float)
    if len(t) > 1:
        d = np.diff(t)
        if np.any(d < 0):
            step = np.median(d[d > 0]) if np.any(d > 0) else 1.0
            jumps = np.where(d < 0, -d + step, 0.0)
            t = t + np.concatenate([[0.0], np.cumsum(jumps)])
    span = float(t[-1] - t[0]) if len(t) else 0.0
    if span >= 3 * 3600:
        return t / 3600.0, "time (h)"
    if span >= 300:
        return t / 60.0, "time (min)"
    return t, "time (s)"


def decimate_minmax(x: np.ndarray, y: np.ndarray, bins: int = _MAX_PLOT_BINS) -> tuple[np.ndarray, np.ndarray]:
    """At most 2*bins points keeping each bin's min and max of y (spikes stay visible)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(y)
    if n <= 2 * bins:
        return x, y
    per = int(math.ceil(n / bins))
    m = int(math.ceil(n / per))
    pad = m * per - n
    yp = np.concatenate([y, np.full(pad, np.nan)]).reshape(m, per)
    finite = np.isfinite(yp)
    imin = np.argmin(np.where(finite, yp, np.inf), axis=1)
    imax = np.argmax(np.where(finite, yp, -np.inf), axis=1)
    base = np.arange(m) * per
    lo = np.minimum(imin, imax) + base
    hi = np.maximum(imin, imax) + base
    idx = np.clip(np.column_stack([lo, hi]).ravel(), 0, n - 1)
    xs, ys = x[idx], y[idx]
    empty = np.repeat(~finite.any(axis=1), 2)
    ys = np.where(empty, np.nan, ys)
    return xs, ys


def _spans(x: np.ndarray, mask: np.ndarray | None) -> list[tuple[float, float]]:
    if mask is None or not len(mask):
        return []
    m = np.asarray(mask, dtype=bool)
    if not m.any():
        return []
    d = np.diff(np.concatenate([[0], m.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    if len(starts) > _MAX_SPANS:  # merge into the covering range rather than draw thousands of patches
        return [(float(x[starts[0]]), float(x[ends[-1]]))]
    return [(float(x[s]), float(x[e])) for s, e in zip(starts, ends)]


def _shade(ax, spans: Iterable[tuple[float, float]], label: bool = True) -> None:
    for i, (a, b) in enumerate(spans):
        ax.axvspan(a, b, color="tab:orange", alpha=0.12, lw=0,
                   label="held out" if (label and i == 0) else None)


def _series(series: Mapping, key: str, n: int) -> np.ndarray | None:
    v = series.get(key)
    if v is None:
        return None
    v = np.asarray(v, dtype=float)
    return v if len(v) == n else None


def _pyplot():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def write_figures(result: Any, out_dir: str | Path) -> dict[str, Path]:
    """Write fit.png, residuals.png and (with a cause) cause.png; return their paths."""
    plt = _pyplot()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    series = getattr(result, "series", None) or {}
    if "t" not in series:
        return {}
    t_raw = np.asarray(series["t"], dtype=float)
    n = len(t_raw)
    x, xlabel = _time_axis(t_raw)
    held = series.get("heldout")
    held = np.asarray(held, dtype=bool) if held is not None and len(held) == n else None
    spans = _spans(x, held)
    outs = [o for o in OUTPUTS if _series(series, f"{o}_measured", n) is not None]
    paths: dict[str, Path] = {}
    if not outs:
        return paths

    # fit.png: rows = outputs, columns = before / after
    fig, axes = plt.subplots(len(outs), 2, figsize=(12, 3.2 * len(outs)), sharex=True, squeeze=False)
    for r, o in enumerate(outs):
        meas = _series(series, f"{o}_measured", n)
        for c, stage in enumerate(("before", "after")):
            ax = axes[r][c]
            _shade(ax, spans)
            ax.plot(*decimate_minmax(x, meas), color="0.45", lw=0.6, label="measured")
            sim = _series(series, f"{o}_{stage}", n)
            if sim is not None:
                ax.plot(*decimate_minmax(x, sim), color="tab:blue" if stage == "before" else "tab:green",
                        lw=0.8, label=f"simulated ({stage})")
            title = "judged model" if stage == "before" else "extended model"
            ax.set_title(f"{o}: measured vs {title}", fontsize=10)
            ax.set_ylabel(f"{o} ({OUTPUT_UNITS[o]})")
            ax.legend(loc="best", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel(xlabel)
    fig.tight_layout()
    paths["fit"] = out / "fit.png"
    fig.savefig(paths["fit"], dpi=100)
    plt.close(fig)

    # residuals.png: residual (measured - simulated) before and after
    fig, axes = plt.subplots(len(outs), 1, figsize=(12, 3.0 * len(outs)), sharex=True, squeeze=False)
    for r, o in enumerate(outs):
        ax = axes[r][0]
        meas = _series(series, f"{o}_measured", n)
        _shade(ax, spans)
        for stage, color in (("before", "tab:blue"), ("after", "tab:green")):
            sim = _series(series, f"{o}_{stage}", n)
            if sim is not None:
                ax.plot(*decimate_minmax(x, meas - sim), color=color, lw=0.6, alpha=0.85,
                        label=f"residual {stage}")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{o} residual ({OUTPUT_UNITS[o]})")
        ax.set_title(f"{o}: measured - simulated", fontsize=10)
        ax.legend(loc="best", fontsize=7)
    axes[-1][0].set_xlabel(xlabel)
    fig.tight_layout()
    paths["residuals"] = out / "residuals.png"
    fig.savefig(paths["residuals"], dpi=100)
    plt.close(fig)

    # cause.png: residual before (and after) against the named cause's signal
    cause = getattr(result, "cause", None)
    sig = _series(series, "cause_signal", n)
    if cause and sig is not None:
        fig, axes = plt.subplots(1, len(outs), figsize=(6 * len(outs), 4), squeeze=False)
        rng = np.random.default_rng(0)
        sel = np.arange(n) if n <= _MAX_SCATTER else np.sort(rng.choice(n, _MAX_SCATTER, replace=False))
        for c, o in enumerate(outs):
            ax = axes[0][c]
            meas = _series(series, f"{o}_measured", n)
            for stage, color in (("before", "tab:blue"), ("after", "tab:green")):
                sim = _series(series, f"{o}_{stage}", n)
                if sim is None:
                    continue
                res = meas - sim
                ax.scatter(sig[sel], res[sel], s=3, alpha=0.3, color=color, label=f"residual {stage}",
                           rasterized=True)
                _binned_mean(ax, sig, res, color)
            ax.axhline(0.0, color="k", lw=0.5)
            ax.set_xlabel(f"{cause} signal")
            ax.set_ylabel(f"{o} residual ({OUTPUT_UNITS[o]})")
            ax.set_title(f"{o} residual vs {cause}", fontsize=10)
            ax.legend(loc="best", fontsize=7, markerscale=3)
        fig.tight_layout()
        paths["cause"] = out / "cause.png"
        fig.savefig(paths["cause"], dpi=100)
        plt.close(fig)
    return paths


def _binned_mean(ax, sig: np.ndarray, res: np.ndarray, color: str, bins: int = 30) -> None:
    ok = np.isfinite(sig) & np.isfinite(res)
    if ok.sum() < 2 * bins:
        return
    s, r = sig[ok], res[ok]
    lo, hi = float(np.min(s)), float(np.max(s))
    if not hi > lo:
        return
    edges = np.linspace(lo, hi, bins + 1)
    k = np.clip(np.digitize(s, edges) - 1, 0, bins - 1)
    cnt = np.bincount(k, minlength=bins)
    mean = np.bincount(k, weights=r, minlength=bins) / np.maximum(cnt, 1)
    centre = 0.5 * (edges[1:] + edges[:-1])
    keep = cnt > 0
    ax.plot(centre[keep], mean[keep], color=color, lw=1.8)


# --------------------------------------------------------------------------- json + all

def _jsonable(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {str(k): _jsonable(w) for k, w in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(w) for w in v]
    if isinstance(v, np.ndarray):
        return [_jsonable(w) for w in v.tolist()]
    if isinstance(v, (np.bool_, bool)):
        return bool(v)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, (float, np.floating)):
        f = float(v)
        return f if math.isfinite(f) else None
    if isinstance(v, Path):
        return str(v)
    return v


def write_json(result: Any, path: str | Path) -> Path:
    """``result.to_json()`` as strict JSON (non-finite numbers -> null)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    data = result.to_json() if hasattr(result, "to_json") else dict(vars(result))
    p.write_text(json.dumps(_jsonable(data), indent=2, allow_nan=False) + "\n")
    return p


def write_report(result: Any, runs: Sequence[Any], out_dir: str | Path) -> dict[str, Path]:
    """Write report.txt and the figures into ``out_dir``; return ``{"report": ..., "fit": ..., ...}``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"report": out / "report.txt"}
    paths["report"].write_text(format_report(result, runs))
    paths.update(write_figures(result, out))
    return paths
