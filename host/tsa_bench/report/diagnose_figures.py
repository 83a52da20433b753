"""Figures of the `tsa-bench diagnose` report: fit.png, residuals.png, cause.png.

Contract: :func:`write_figures` reads a diagnose result's ``series`` (``t``, ``heldout``,
``<output>_measured|before|after``, optional ``cause_signal``) and writes, into
``out_dir``: ``fit.png`` (measured vs simulated, judged and final model, held-out part
shaded), ``residuals.png`` (measured - simulated, before and after) and, when a cause is
named, ``cause.png`` (residual against the cause's signal). Figures use the Agg backend
and never open a window; long series (100k samples and more) are decimated for plotting
(min/max envelope per bin for lines, a strided subset for scatter), so a figure costs
well under a second. Returns ``{"fit": path, ...}``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.outputs import save_figure

OUTPUTS = ("length", "resistance")
OUTPUT_UNITS = {"length": "mm", "resistance": "ohm"}
_MAX_PLOT_BINS = 2000
_MAX_SCATTER = 6000
_MAX_SPANS = 60


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
    outs = [o for o in getattr(result, "outputs", OUTPUTS) if _series(series, f"{o}_measured", n) is not None
            and np.isfinite(_series(series, f"{o}_measured", n)).any()]
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
            title = "judged model" if stage == "before" else "final model"
            ax.set_title(f"{o}: measured vs {title}", fontsize=10)
            ax.set_ylabel(f"{o} ({OUTPUT_UNITS[o]})")
            ax.legend(loc="best", fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel(xlabel)
    fig.tight_layout()
    paths["fit"] = out / "fit.png"
    save_figure(fig, paths["fit"], dpi=100)
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
    save_figure(fig, paths["residuals"], dpi=100)
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
        save_figure(fig, paths["cause"], dpi=100)
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
