"""Figures of one run, like those of the thesis (chapter 2), one function per kind.

Contract: each ``fig_*`` function takes a :class:`~tsa_bench.rundata.RunData` and an output
path, draws one PNG (Agg backend, axes in the contract's physical units) and returns a
caption, or returns None without writing anything when the run lacks what the figure
needs (the selector in :mod:`tsa_bench.report.run_report` asks first, so this is a
second guard against empty panels). NaN values are skipped, never drawn as zero.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tsa_bench.report.fig_common import (
    DPI, HEAT_COLOR, MAX_BOUNDARIES, TWIST_COLOR, UNTWIST_COLOR, broken_line, direction, draw_series, envelope,
    finite_any_col, grams, mark_segments, pyplot, save, stride, time_scale, title,
)
from tsa_bench.report.run_analysis import (
    cycle_table, motor_stops, plateaus, sample_cycles, span, stiffness_points,
)
from tsa_bench.rundata import RunData

_SERIES = (("turns", "twist", "turn"), ("length", "length", "mm"), ("resistance", "resistance", "ohm"),
           ("heater_voltage", "heater voltage", "V"), ("load", "load", "N"))


def zoom_window(run: RunData) -> tuple[float, float] | None:
    """(start, end) in s of a stretch worth a zoomed inset, or None when the whole run reads
    well at full width: its first two repeat cycles, else its first 2 % (long runs only)."""
    t = np.asarray(run.samples["t"], float)
    seg = run.segments
    many = seg is not None and len(seg) > MAX_BOUNDARIES
    if len(t) < 2 or not (many or envelope(t, t) is not None):
        return None
    if seg is not None and len(seg) and "cycle" in (seg.dtype.names or ()):
        cyc = np.asarray(seg["cycle"])
        inside = np.flatnonzero(cyc >= 0)
        if len(inside):
            first = inside[0]
            block_end = first
            while block_end + 1 < len(cyc) and cyc[block_end + 1] >= 0 and cyc[block_end + 1] <= 1:
                block_end += 1
            a, b = float(seg["t_start"][first]), float(seg["t_end"][block_end])
            if b > a and b - a < 0.5 * (t[-1] - t[0]):
                return a, b
    span = t[-1] - t[0]
    return float(t[0]), float(t[0] + 0.02 * span)


def fig_timeseries(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    """Turns, length, resistance, heater voltage and load against time, segments marked;
    a long run gets a zoomed inset in each panel."""
    s = run.samples
    shown = [c for c in _SERIES if finite_any_col(s[c[0]]) and (c[0] in ("turns", "length", "resistance")
                                                              or span(s[c[0]]) > 0)]
    if not shown or len(run) == 0:
        return None
    notes = []
    for name, label, unit in _SERIES:
        if (name, label, unit) in shown:
            continue
        a = np.asarray(s[name], float)
        fin = a[np.isfinite(a)]
        notes.append(f"{label} not measured" if not len(fin) else f"{label} {fin[0]:.4g} {unit} throughout")
    plt = pyplot()
    fig, axes = plt.subplots(len(shown), 1, figsize=(11, 1.9 * len(shown) + 1.2), sharex=True, squeeze=False)
    scale, xlabel = time_scale(s["t"])
    t = np.asarray(s["t"], float) / scale
    zoom = zoom_window(run)
    marks = ""
    for i, (ax, (name, label, unit)) in enumerate(zip(axes[:, 0], shown)):
        y = np.asarray(s[name], float)
        draw_series(ax, t, y)
        ax.set_ylabel(f"{label}\n({unit})")
        marks = mark_segments(ax, run, scale, label=(i == 0)) or marks
        if name == "resistance" and not np.isfinite(s[name]).all():
            ax.text(0.01, 0.95, "gaps: not measured (heater on)", transform=ax.transAxes, ha="left", va="top",
                    fontsize=8, color="0.4")
        ax.grid(alpha=0.3)
        if zoom is not None:
            sel = (t >= zoom[0] / scale) & (t <= zoom[1] / scale)
            if sel.sum() >= 2 and np.isfinite(y[sel]).any():
                inset = ax.inset_axes([0.68, 0.52, 0.31, 0.44])
                draw_series(inset, t[sel], y[sel], lw=0.7)
                inset.tick_params(labelsize=6)
                inset.set_facecolor("white")
                ax.indicate_inset_zoom(inset, edgecolor="0.4")
    if axes[0, 0].get_legend_handles_labels()[0]:
        axes[0, 0].legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, frameon=False)
    axes[-1, 0].set_xlabel(xlabel)
    title(fig, "Time series", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    parts = ["Inputs and outputs against device time"]
    if marks:
        parts.append(marks)
    if envelope(t, t) is not None:
        parts.append("long series drawn as their min..max band per pixel with the median line")
    if zoom is not None:
        parts.append(f"insets zoom into {zoom[0]:.4g}..{zoom[1]:.4g} s")
    return "; ".join(parts + notes) + "."


def _loads(run: RunData) -> list[float]:
    load = np.asarray(run.samples["load"], float)
    levels = np.unique(np.round(load[np.isfinite(load)], 6))
    return [float(v) for v in levels] if len(levels) else [float("nan")]


def fig_loops(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    """Length against twist, coloured by direction, one panel per load (Fig. 2.5)."""
    s = run.samples
    if span(s["turns"]) <= 0 or not finite_any_col(s["length"]):
        return None
    loads = _loads(run)[:4]
    plt = pyplot()
    fig, axes = plt.subplots(1, len(loads), figsize=(4.6 * len(loads) + 1, 4.6), sharey=True, squeeze=False)
    turns, length = np.asarray(s["turns"], float), np.asarray(s["length"], float)
    heat = np.asarray(s["heater_voltage"], float) > 0
    dirn = direction(turns)
    cyc = sample_cycles(run)
    ids = np.unique(cyc[cyc >= 0])
    few = np.ones(len(run), dtype=bool)
    if len(ids) > 2:  # hundreds of overlaid loops hide each other: first and last cycle only
        few = np.isin(cyc, [-1, ids[0], ids[-1]])
    for ax, level in zip(axes[0], loads):
        sel = few & (np.isclose(s["load"], level) if np.isfinite(level) else ~np.isfinite(s["load"]))
        broken_line(ax, turns, length, sel & (dirn > 0) & ~heat, color=TWIST_COLOR, lw=0.9, label="twisting")
        broken_line(ax, turns, length, sel & (dirn < 0) & ~heat, color=UNTWIST_COLOR, lw=0.9, label="untwisting")
        if (sel & heat).any():
            broken_line(ax, turns, length, sel & heat, color=HEAT_COLOR, lw=1.2, label="heater on")
        rests = [p for p in plateaus(run) if few[p.start] and p.heater_voltage == 0
                 and (np.isclose(p.load, level) if np.isfinite(level) else not np.isfinite(p.load))]
        if len(rests) <= 400:
            ax.plot([p.turns for p in rests], [p.length for p in rests], "o", ms=3, color="k",
                    label="steady state (rest)")
        ax.set_title(grams(level), fontsize=10)
        ax.set_xlabel("twist (turn)")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("length (mm)")
    axes[0, -1].legend(fontsize=8, loc="best")
    title(fig, "Length vs twist (hysteresis loops)", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    more = f" (first 4 of {len(_loads(run))} loads)" if len(_loads(run)) > 4 else ""
    if len(ids) > 2:
        more += f"; of {len(ids)} cycles only the first ({ids[0]}) and last ({ids[-1]}) are drawn"
    return f"Length against motor twist, blue twisting, red untwisting{more}; dots are rest medians."


def fig_voltage(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    """Voltage steps and length over time; steady length (and resistance) vs voltage (Fig. 2.6)."""
    s = run.samples
    v = np.asarray(s["heater_voltage"], float)
    rests = [p for p in plateaus(run) if np.isfinite(p.heater_voltage)]
    heated = {round(p.turns, 6) for p in rests if p.heater_voltage > 0}
    if len(heated) == 1:  # steady states at the twist level that was heated, not the untwisted ones
        rests = [p for p in rests if round(p.turns, 6) in heated]
    levels = {round(p.heater_voltage, 6) for p in rests}
    if len(levels) < 2 or not finite_any_col(s["length"]):
        return None
    r_levels = {round(p.heater_voltage, 6) for p in rests if np.isfinite(p.resistance)}
    with_r = len(r_levels) >= 2
    plt = pyplot()
    fig, axes = plt.subplots(1, 3 if with_r else 2, figsize=(15 if with_r else 11, 4.4), squeeze=False)
    ax = axes[0, 0]
    on = np.flatnonzero(np.isfinite(v) & (v > 0))
    t = np.asarray(s["t"], float)
    lo, hi = (t[on[0]], t[on[-1]]) if len(on) else (t[0], t[-1])
    pad = 0.1 * (hi - lo)
    sel = (t >= lo - pad) & (t <= hi + pad)
    scale, xlabel = time_scale(t[sel])
    ax.plot(t[sel] / scale, v[sel], color=HEAT_COLOR, lw=1.2)
    ax.set_ylabel("heater voltage (V)", color=HEAT_COLOR)
    ax.set_xlabel(xlabel)
    ax2 = ax.twinx()
    draw_series(ax2, t[sel] / scale, np.asarray(s["length"], float)[sel])
    ax2.set_ylabel("length (mm)")
    ax.set_title("(a) voltage input and length", fontsize=10)
    rising = _voltage_direction(rests)
    for col, (name, unit, label) in enumerate((("length", "mm", "(b) steady length"),
                                               ("resistance", "ohm", "(c) steady resistance"))[: 2 if with_r else 1]):
        ax = axes[0, col + 1]
        for flag, color, lab in ((True, TWIST_COLOR, "voltage rising"), (False, UNTWIST_COLOR, "voltage falling")):
            pts = [(p.heater_voltage, getattr(p, name)) for p, r in zip(rests, rising) if r == flag]
            pts = [q for q in pts if np.isfinite(q[1])]
            if pts:
                ax.plot(*zip(*pts), "o-", ms=4, lw=0.8, color=color, label=lab)
        ax.set_xlabel("heater voltage (V)")
        ax.set_ylabel(f"{name} ({unit})")
        ax.set_title(f"{label} vs voltage", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    title(fig, "Heating: length and resistance vs voltage", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    note = "" if with_r else " Resistance is not measured while the heater is on, so it has no panel."
    return "Heater voltage steps and the resulting length; rest medians against voltage." + note


def _voltage_direction(rests: list) -> list[bool]:
    out, prev, up = [], None, True
    for p in rests:
        if prev is not None and p.heater_voltage != prev:
            up = p.heater_voltage > prev
        out.append(up)
        prev = p.heater_voltage
    return out


def fig_resistance_length(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    """Steady resistance against steady length, coloured by load or time (Fig. 2.7)."""
    rests = [p for p in plateaus(run) if np.isfinite(p.resistance) and np.isfinite(p.length)]
    if len({round(p.turns, 6) for p in rests}) < 3:
        return None
    s = run.samples
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    st = stride(len(run), 20000)
    ax.plot(np.asarray(s["length"], float)[st], np.asarray(s["resistance"], float)[st], ".", ms=1,
            color="0.8", label="all samples", zorder=0)
    loads = sorted({round(p.load, 6) for p in rests if np.isfinite(p.load)})
    if 1 < len(loads) <= 8:
        for i, level in enumerate(loads):
            pts = [(p.length, p.resistance) for p in rests if np.isclose(p.load, level)]
            ax.plot(*zip(*pts), "o", ms=4, color=f"C{i}", label=f"rests at {grams(level)}")
        how = "colour = load"
    else:
        scale, tlabel = time_scale([p.t_end for p in rests])
        sc = ax.scatter([p.length for p in rests], [p.resistance for p in rests], s=10,
                        c=[p.t_end / scale for p in rests], cmap="viridis", label="rests")
        fig.colorbar(sc, ax=ax, label=tlabel)
        how = "colour = time (creep)"
    ax.set_xlabel("length (mm)")
    ax.set_ylabel("resistance (ohm)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best", markerscale=2)
    title(fig, "Resistance vs length (self-sensing)", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    return f"Rest medians of resistance against length ({how}); grey dots are all samples."


def fig_transient(run: RunData, path: Path, max_groups: int = 5, max_curves: int = 30, dpi: int = DPI) -> str | None:
    """Resistance and length after each motor stop on a log time axis (Fig. 2.8(a)-(b))."""
    stops = [p for p in motor_stops(run) if np.isfinite(run.samples["resistance"][p.start:p.stop]).sum() >= 3]
    if len(stops) < 3:
        return None
    groups: dict[float, list] = {}
    for p in stops:
        groups.setdefault(float(f"{p.duration:.2g}"), []).append(p)
    keys = sorted(groups, key=lambda k: (-len(groups[k]), k))[:max_groups]
    keys.sort()
    s = run.samples
    t = np.asarray(s["t"], float)
    turns_all = [p.turns for p in stops]
    norm_lo, norm_hi = min(turns_all), max(turns_all)
    plt = pyplot()
    cmap = plt.get_cmap("viridis")
    fig, axes = plt.subplots(2, len(keys), figsize=(3.6 * len(keys) + 1.6, 6.4), squeeze=False, sharex="col")
    for col, k in enumerate(keys):
        chosen = groups[k]
        if len(chosen) > max_curves:
            chosen = [chosen[i] for i in np.linspace(0, len(chosen) - 1, max_curves).astype(int)]
        for p in chosen:
            t_stop = t[p.start - 1] if p.start > 0 else t[p.start]
            dt = t[p.start:p.stop] - t_stop
            frac = 0.5 if norm_hi == norm_lo else (p.turns - norm_lo) / (norm_hi - norm_lo)
            for row, name in enumerate(("resistance", "length")):
                y = np.asarray(s[name], float)[p.start:p.stop]
                ok = np.isfinite(y) & (dt > 0)
                axes[row, col].plot(dt[ok], y[ok], lw=0.8, color=cmap(frac))
        axes[0, col].set_title(f"rests of ~{k:g} s ({len(groups[k])})", fontsize=10)
        for row, (name, unit) in enumerate((("resistance", "ohm"), ("length", "mm"))):
            ax = axes[row, col]
            ax.set_xscale("log")
            ax.grid(alpha=0.3, which="both")
            if col == 0:
                ax.set_ylabel(f"{name} ({unit})")
        axes[1, col].set_xlabel("time since motor stop (s)")
    sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(norm_lo, norm_hi))
    fig.colorbar(sm, ax=axes.ravel().tolist(), label="twist at rest (turn)", fraction=0.03, pad=0.02)
    title(fig, "Transient after motor stops (log time)", run)
    save(fig, path, dpi, bbox_inches="tight")
    plt.close(fig)
    return (f"Resistance and length during the {len(stops)} rests after a move, against time since the motor "
            f"stopped (log axis), grouped by rest duration, coloured by twist.")


def fig_drift(run: RunData, path: Path, min_cycles: int = 5, dpi: int = DPI) -> str | None:
    """Resistance and length per cycle of a repeat block (lifetime drift, Fig. 2.8(d))."""
    table = cycle_table(run)
    if table is None or len(table.cycle) < min_cycles:
        return None
    plt = pyplot()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6.2), sharex=True)
    parts = []
    for ax, (key, name, unit) in zip(axes, (("resistance", "resistance", "ohm"), ("length", "length", "mm"))):
        mean, lo, hi = (getattr(table, f"{key}_{x}") for x in ("mean", "min", "max"))
        if not np.isfinite(mean).any():
            ax.text(0.5, 0.5, f"{name} not measured", transform=ax.transAxes, ha="center")
        else:
            ax.fill_between(table.cycle, lo, hi, color="0.85", lw=0, label="min - max in cycle")
            ax.plot(table.cycle, mean, color="k", lw=1, label="cycle mean")
            first, last = mean[np.isfinite(mean)][[0, -1]]
            parts.append(f"{name} mean {first:.4g} -> {last:.4g} {unit} ({100 * (last - first) / first:+.2f} %)")
        ax.set_ylabel(f"{name} ({unit})")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("cycle")
    title(fig, f"Drift over {len(table.cycle)} cycles", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    return "Per-cycle mean and range; first to last cycle: " + "; ".join(parts) + "."


def fig_stiffness(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    """Length vs load, linear-model error and normalized stiffness K = F L0/(L-L0) (Fig. 2.4)."""
    pts = stiffness_points(run)
    if len(pts) < 2:
        return None
    F = np.array([p.load for p in pts])
    L = np.array([p.length for p in pts])
    l0 = pts[0].l0
    slope, icpt = np.polyfit(np.concatenate([[0.0], F]), np.concatenate([[l0], L]), 1)  # mm/N, mm
    k_fit = icpt / slope if slope else float("nan")
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    rising = np.array([p.rising for p in pts])
    for flag, color, lab in ((True, TWIST_COLOR, "load increasing"), (False, UNTWIST_COLOR, "load decreasing")):
        if (rising == flag).any():
            axes[0].plot(F[rising == flag], L[rising == flag], "o", color=color, label=lab)
            axes[2].plot(F[rising == flag], [p.k for p, r in zip(pts, rising) if r == flag], "o", color=color,
                         label=lab)
    ff = np.linspace(0, F.max(), 50)
    axes[0].plot(ff, icpt + slope * ff, "k--", lw=0.8, label=f"linear fit, K = {k_fit:.3g} N")
    axes[0].plot([0], [l0], "ks", label=f"unloaded L0 = {l0:.4g} mm")
    axes[0].set(xlabel="load (N)", ylabel="length (mm)", title="(a) steady length vs load")
    err = L - (icpt + slope * F)
    axes[1].bar(np.arange(1, len(pts) + 1), err, color=np.where(rising, TWIST_COLOR, UNTWIST_COLOR))
    axes[1].axhline(0, color="k", lw=0.6)
    axes[1].set(xlabel="point index", ylabel="length - linear model (mm)", title="(b) linear model error")
    axes[2].axhline(k_fit, color="k", ls="--", lw=0.8, label="from linear fit")
    axes[2].set(xlabel="load (N)", ylabel="normalized stiffness K (N)", title="(c) K = F L0 / (L - L0)")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[2].legend(fontsize=8)
    title(fig, "Stiffness from load steps", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    return (f"Normalized stiffness from {len(pts)} loaded rests at one twist level: linear fit K = {k_fit:.3g} N, "
            f"L0 = {l0:.4g} mm, mean absolute model error {np.mean(np.abs(err)):.3g} mm.")
