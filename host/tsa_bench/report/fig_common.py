"""Shared pieces of the run figures: figure setup, titles, time axis, segment marks.

Contract: figures use matplotlib's Agg backend (never a window) through
:func:`tsa_bench.report.diagnose_report._pyplot`-style setup; every figure carries a
title naming the run (plan name and file) and, for a run that did not end in
"success", its exit status, so a figure copied out of its report still says where it
came from.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tsa_bench.outputs import save_figure
from tsa_bench.rundata import RunData

DPI = 150
#: File formats a figure may be written in (matplotlib picks the backend from the suffix).
FORMATS = ("png", "pdf", "svg")
#: More boundaries than this and lines would hide the data; repeat blocks are shaded instead.
MAX_BOUNDARIES = 60
#: More samples than this per panel and a line is drawn as a band (min..max per pixel column).
ENVELOPE_BINS = 1500
TWIST_COLOR, UNTWIST_COLOR, HEAT_COLOR = "tab:blue", "tab:red", "tab:orange"
G0 = 9.80665  # m/s^2, loads in N shown as grams (the thesis quotes masses)


@dataclass(frozen=True)
class Figure:
    """One written figure: its file, a one-line caption, the thesis figure it mirrors."""

    name: str
    path: Path
    caption: str
    thesis: str = ""


def pyplot():
    import matplotlib
    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    return plt


def run_label(run: RunData) -> str:
    """'plan (file)' plus the exit status when it is not success."""
    name = str(run.attrs.get("plan_name") or "") or Path(run.path).stem
    label = f"{name}  ({Path(run.path).name})"
    status = run.exit_status
    if status == "running":
        label += "  [killed: exit_status still 'running']"
    elif status and status != "success":
        label += f"  [{status}]"
    return label


def title(fig, what: str, run: RunData) -> None:
    # parse_math=False: a plan or file name is text, even with a '$' in it (no mathtext)
    fig.suptitle(f"{what}\n{run_label(run)}", fontsize=11, parse_math=False)


def time_scale(t: np.ndarray) -> tuple[float, str]:
    """Divisor and axis label for device time t (s): s, min or h by span."""
    t = np.asarray(t, dtype=float)
    span = float(np.nanmax(t) - np.nanmin(t)) if len(t) else 0.0
    if span >= 3 * 3600:
        return 3600.0, "time (h)"
    if span >= 600:
        return 60.0, "time (min)"
    return 1.0, "time (s)"


def finite_any_col(a) -> bool:
    return bool(np.isfinite(np.asarray(a, dtype=float)).any())


def grams(load_n: float) -> str:
    """A load as every figure labels it: the hanging mass and its weight, ``450 g (4.41 N)``."""
    return "load undeclared" if not np.isfinite(load_n) else f"{load_n / G0 * 1000:.0f} g ({load_n:.3g} N)"


def save(fig, path: Path, dpi: int = DPI, **kw) -> None:
    """Write ``fig`` in the format of ``path``'s suffix (png, pdf, svg) at ``dpi`` (raster parts),
    as a new file (:func:`tsa_bench.outputs.save_figure`: an existing one only with --force)."""
    save_figure(fig, path, dpi=dpi, **kw)


def envelope(x: np.ndarray, y: np.ndarray, bins: int = ENVELOPE_BINS):
    """``None`` when ``y`` is short enough to draw as a line; else per-bin
    ``(x_mid, y_min, y_max, y_median)`` (NaN where a bin has no finite value), so a long or
    quantised noisy signal is drawn as a band with its median, not as solid vertical bars."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(y)
    if n <= 2 * bins:
        return None
    per = int(np.ceil(n / bins))
    m = int(np.ceil(n / per))
    pad = m * per - n
    yp = np.concatenate([y, np.full(pad, np.nan)]).reshape(m, per)
    xp = np.concatenate([x, np.full(pad, np.nan)]).reshape(m, per)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN bins stay NaN (not measured)
        return np.nanmean(xp, axis=1), np.nanmin(yp, axis=1), np.nanmax(yp, axis=1), np.nanmedian(yp, axis=1)


def draw_series(ax, x: np.ndarray, y: np.ndarray, color: str = "k", lw: float = 0.8) -> None:
    """A time series as a line, or as a min..max band with its median line when it is long."""
    env = envelope(x, y)
    if env is None:
        ax.plot(x, y, lw=lw, color=color)
        return
    xm, lo, hi, med = env
    ax.fill_between(xm, lo, hi, color=color, alpha=0.25, lw=0, step="mid")
    ax.plot(xm, med, lw=lw, color=color)


def segment_starts(run: RunData) -> tuple[np.ndarray, list[tuple[float, float]]]:
    """Boundary times (s) to draw, and (start, end) spans of repeat blocks to shade.

    Boundaries are the starts of segments that last > 0 s. When there are more than
    MAX_BOUNDARIES, segments inside repeat blocks are summarised as one shaded span per
    block and only the others get lines; if still too many, none are drawn.
    """
    seg = run.segments
    if seg is not None and len(seg) and "t_start" in (seg.dtype.names or ()):
        t0, t1 = np.asarray(seg["t_start"], float), np.asarray(seg["t_end"], float)
        cyc = np.asarray(seg["cycle"]) if "cycle" in seg.dtype.names else np.full(len(seg), -1)
    else:  # imported runs: the segment column alone
        sc = np.asarray(run.samples["segment"])
        t = run.samples["t"]
        if len(sc) < 2:
            return np.array([]), []
        idx = np.flatnonzero(np.diff(sc) != 0) + 1
        return (t[idx] if len(idx) <= MAX_BOUNDARIES else np.array([])), []
    keep = t1 > t0
    if keep.sum() <= MAX_BOUNDARIES:
        return t0[keep], []
    inside = cyc >= 0
    spans: list[tuple[float, float]] = []
    if inside.any():
        d = np.diff(np.concatenate([[0], inside.astype(np.int8), [0]]))
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1):
            spans.append((float(t0[a]), float(t1[b])))
    lines = t0[keep & ~inside]
    return (lines if len(lines) <= MAX_BOUNDARIES else np.array([])), spans


def mark_segments(ax, run: RunData, scale: float, label: bool) -> str:
    """Draw segment starts (and repeat blocks); return what was drawn, for the caption
    ("" when nothing: a caption never promises marks that are not there)."""
    lines, spans = segment_starts(run)
    for i, x in enumerate(lines):
        ax.axvline(x / scale, color="0.6", lw=0.6, ls=":", zorder=0,
                   label="segment start" if (label and i == 0) else None)
    for i, (a, b) in enumerate(spans):
        ax.axvspan(a / scale, b / scale, color="tab:green", alpha=0.08, lw=0, zorder=0,
                   label="repeat block" if (label and i == 0) else None)
    parts = []
    if len(lines):
        parts.append("dotted lines mark segment starts")
    if spans:
        parts.append("green bands mark repeat blocks")
    return " and ".join(parts)


def direction(turns: np.ndarray) -> np.ndarray:
    """+1 twisting, -1 untwisting per sample; rests inherit the last move's direction."""
    d = np.sign(np.diff(np.asarray(turns, dtype=float), prepend=np.nan))
    d[~np.isfinite(d)] = 0
    idx = np.where(d != 0, np.arange(len(d)), 0)
    np.maximum.accumulate(idx, out=idx)
    out = d[idx]
    out[out == 0] = 1
    return out


def broken_line(ax, x: np.ndarray, y: np.ndarray, mask: np.ndarray, **kw) -> None:
    """Plot x, y only where mask holds, breaking the line where it does not."""
    yy = np.where(mask, y, np.nan)
    ax.plot(x, yy, **kw)


def stride(n: int, limit: int) -> slice:
    return slice(None, None, max(1, int(np.ceil(n / limit))))
