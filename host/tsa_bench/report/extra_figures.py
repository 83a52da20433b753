"""Figures of a run's extra columns: channels beyond the contract (temperature, force, stress, ...).

Contract: :func:`extra_columns` names the float ``/samples`` columns a run holds beyond
the contract columns (docs/run-format.md) that have finite values, in file order.
:func:`fig_extras` draws each against time (units from the column's ``units``);
:func:`fig_extras_xy` draws up to three pairs of them against each other (e.g. strain
against temperature, a hysteresis loop), the sample order shown by colour. Both return
a caption, or None without writing when the run has too few extra columns.
"""

from __future__ import annotations

from itertools import combinations
from pathlib import Path

import numpy as np

from tsa_bench.report.diagnose_report import decimate_minmax
from tsa_bench.report.fig_common import DPI, pyplot, save, time_scale, title
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.rundata import RunData

MAX_PANELS = 6
MAX_PAIRS = 3


def extra_columns(run: RunData) -> list[str]:
    """Float columns beyond the contract with at least one finite value."""
    out = []
    for name, a in run.samples.items():
        if name in SAMPLE_COLUMNS or a.dtype.kind != "f":
            continue
        if np.isfinite(a).any():
            out.append(name)
    return out


def _label(run: RunData, name: str) -> str:
    unit = run.units.get(name, "")
    return f"{name} ({unit})" if unit else name


def fig_extras(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    """Every extra column against device time."""
    names = extra_columns(run)[:MAX_PANELS]
    if not names or len(run) == 0:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(len(names), 1, figsize=(11, 1.9 * len(names) + 1.2), sharex=True, squeeze=False)
    scale, xlabel = time_scale(run.samples["t"])
    t = np.asarray(run.samples["t"], float) / scale
    for ax, name in zip(axes[:, 0], names):
        x, y = decimate_minmax(t, np.asarray(run.samples[name], float))
        ax.plot(x, y, lw=0.8, color="k")
        ax.set_ylabel(_label(run, name).replace(" (", "\n("))
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel(xlabel)
    title(fig, "Extra channels", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    more = len(extra_columns(run)) - len(names)
    return ("Columns beyond the contract, with their units: " + ", ".join(_label(run, n) for n in names)
            + (f" (and {more} more, not drawn)" if more > 0 else "") + ".")


def fig_extras_xy(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    """Pairs of extra columns against each other, coloured by sample order."""
    names = extra_columns(run)
    pairs = list(combinations(names, 2))[:MAX_PAIRS]
    if not pairs:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, len(pairs), figsize=(4.6 * len(pairs) + 1.0, 4.4), squeeze=False)
    order = np.arange(len(run))
    for ax, (a, b) in zip(axes[0], pairs):
        x, y = np.asarray(run.samples[a], float), np.asarray(run.samples[b], float)
        ok = np.isfinite(x) & np.isfinite(y)
        sc = ax.scatter(x[ok], y[ok], c=order[ok], s=4, cmap="viridis")
        ax.set_xlabel(_label(run, a))
        ax.set_ylabel(_label(run, b))
        ax.grid(alpha=0.3)
    fig.colorbar(sc, ax=axes[0, -1], label="sample index")
    title(fig, "Extra channels against each other", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    return ("Pairs of extra columns, colour = sample order (a loop shows hysteresis): "
            + "; ".join(f"{b} vs {a}" for a, b in pairs) + ".")
