"""Figure of a length-tracking run (``track_length``): target, true length and estimate.

Contract: :func:`fig_tracking` draws, against device time, the target, the length the
controller estimated (from resistance, or resistance and twist) and the true length (the
position sensor, which the controller never reads), with the declared load on a second
axis, and below the true error (length - target) during tracking with the +-0.5 mm band.
Its caption gives the thesis-style figures of :mod:`tsa_bench.control.evaluation`: targets
reached, steady-state error of the true length (max and mean of |e|), rise time,
overshoot, and the recovery after each load change. None (nothing written) for a run
without a ``length_target`` column with finite values.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tsa_bench.report.fig_common import DPI, pyplot, save, time_scale, title
from tsa_bench.rundata import RunData

BAND_MM = 0.5


def has_tracking(run: RunData) -> bool:
    col = run.samples.get("length_target")
    return col is not None and bool(np.isfinite(np.asarray(col, float)).any())


def fig_tracking(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    from tsa_bench.control.evaluation import load_recoveries, target_figures
    from tsa_bench.units import G_N_PER_G

    if not has_tracking(run):
        return None
    s = run.samples
    scale, xlabel = time_scale(s["t"])
    t = np.asarray(s["t"], float) / scale
    target = np.asarray(s["length_target"], float)
    true = np.asarray(s["length"], float)
    est = np.asarray(s["length_estimate"], float)
    plt = pyplot()
    fig, (ax, ax_e) = plt.subplots(2, 1, figsize=(11, 6.4), sharex=True, gridspec_kw={"height_ratios": [2.2, 1]})
    ax.plot(t, true, lw=0.8, color="k", label="true length (position sensor, not used)")
    ax.plot(t, est, lw=0.8, color="tab:blue", label="estimate (controller)")
    ax.plot(t, target, lw=1.4, color="tab:red", label="target")
    ax.set_ylabel("length (mm)")
    ax.grid(alpha=0.3)
    if "load" in s and np.isfinite(np.asarray(s["load"], float)).any():
        ax_l = ax.twinx()
        ax_l.plot(t, np.asarray(s["load"], float) / G_N_PER_G, lw=0.8, color="tab:green", ls="--", label="load")
        ax_l.set_ylabel("load (g)", color="tab:green")
    ax.legend(loc="upper right", fontsize=8)
    err = np.where(np.isfinite(target), true - target, np.nan)
    ax_e.plot(t, err, lw=0.8, color="k")
    ax_e.axhspan(-BAND_MM, BAND_MM, color="tab:green", alpha=0.15, label=f"+-{BAND_MM:g} mm")
    ax_e.set_ylabel("true - target (mm)")
    ax_e.set_xlabel(xlabel)
    ax_e.grid(alpha=0.3)
    ax_e.legend(loc="upper right", fontsize=8)
    finite = err[np.isfinite(err)]
    if len(finite):
        lim = max(2.0, float(np.percentile(np.abs(finite), 95)) * 1.5)
        ax_e.set_ylim(-lim, lim)
    title(fig, "Length tracking from resistance", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    figs = target_figures(run)
    reached = [f for f in figs if f.rise_s is not None]
    parts = [f"{len(reached)} of {len(figs)} targets reached"]
    sse = np.array([abs(f.steady_error_mm) for f in reached if np.isfinite(f.steady_error_mm)])
    if len(sse):
        parts.append(f"steady-state error of the true length max {sse.max():.2f} mm, mean {sse.mean():.2f} mm")
        parts.append(f"rise time median {np.median([f.rise_s for f in reached]):.1f} s")
        parts.append(f"overshoot max {np.nanmax([f.overshoot_mm for f in reached]):.2f} mm")
    for r in load_recoveries(run, BAND_MM):
        rec = "not back within" if r.recovery_s is None else f"back within {r.recovery_s:.0f} s to"
        parts.append(f"load {r.load_from_g:.0f} -> {r.load_to_g:.0f} g: {rec} +-{BAND_MM:g} mm")
    return ("Target, estimate and true length (the controller never reads the position sensor); below, the "
            "true error during tracking. " + "; ".join(parts) + ".")
