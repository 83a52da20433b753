"""Figure of a run that heats at more than one twist: length against twist and voltage together.

Contract: :func:`heated_twists` lists the twist levels (turns) at which the run rested with
the heater on; a run with two or more of them (heating not only after full twist, as the
thesis's section 2.4.3 did, but at several twists or while twisting: ``twist_heat`` steps)
gets :func:`fig_twist_heat`: (a) twist, heater voltage and length against time, (b) the
steady length of every rest against twist, coloured by voltage, and (c) the heat-induced
length change (steady length minus the unheated length at the same twist, where the run
rested there unheated) against voltage, one curve per twist: if heating and twisting
were additive (thesis eq. 3.3) the curves would coincide. A run with fewer than two such
curves (heated only at twists where it never rested unheated, as ``twist_heat`` runs are)
gets instead (c) steady length against voltage, coloured by twist. Units: turns, V, mm, s.
None (nothing written) for a run with fewer than two heated twists.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tsa_bench.report.fig_common import DPI, HEAT_COLOR, draw_series, pyplot, save, time_scale, title
from tsa_bench.report.run_analysis import plateaus
from tsa_bench.rundata import RunData


def _rests(run: RunData) -> list:
    return [p for p in plateaus(run) if np.isfinite(p.heater_voltage) and np.isfinite(p.length)
            and np.isfinite(p.turns)]


def heated_twists(run: RunData) -> list[float]:
    """The distinct twists (turns, to 1e-6) of rests with the heater above 0 V and a length."""
    return sorted({round(p.turns, 6) for p in _rests(run) if p.heater_voltage > 0})


def fig_twist_heat(run: RunData, path: Path, dpi: int = DPI) -> str | None:
    twists = heated_twists(run)
    if len(twists) < 2:
        return None
    s = run.samples
    rests = _rests(run)
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    t = np.asarray(s["t"], float)
    scale, xlabel = time_scale(t)
    ax = axes[0]
    ax.plot(t / scale, np.asarray(s["turns"], float), lw=1.0, color="tab:blue", label="twist (turns)")
    ax.plot(t / scale, np.asarray(s["heater_voltage"], float) * 10.0, lw=1.0, color=HEAT_COLOR,
            label="heater voltage x 10 (V)")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("twist (turns), voltage x 10 (V)")
    ax.legend(loc="upper left", fontsize=8)
    ax2 = ax.twinx()
    draw_series(ax2, t / scale, np.asarray(s["length"], float))
    ax2.set_ylabel("length (mm)")
    ax.set_title("(a) twist, voltage and length", fontsize=10)

    ax = axes[1]
    pts = np.array([(p.turns, p.heater_voltage, p.length) for p in rests])
    _steady_scatter(fig, ax, pts[:, 0], pts[:, 2], pts[:, 1], "inferno_r", "heater voltage (V)", "twist (turns)",
                    "(b) steady length vs twist and voltage")

    ax = axes[2]
    drawn = _heating_per_twist(ax, rests, twists, plt.get_cmap("viridis"))
    if len(drawn) < 2:  # heated at twists it never rested at unheated (twist_heat steps): both inputs at once
        ax.clear()
        _steady_scatter(fig, ax, pts[:, 1], pts[:, 2], pts[:, 0], "viridis", "twist (turns)", "heater voltage (V)",
                        "(c) steady length vs voltage and twist")
    title(fig, "Twisting and heating: length vs twist and voltage", run)
    fig.tight_layout()
    save(fig, path, dpi)
    plt.close(fig)
    parts = [f"{len(rests)} rests, heated at {len(twists)} twists ({twists[0]:g} .. {twists[-1]:g} turns), "
             f"{pts[:, 1].min():g} .. {pts[:, 1].max():g} V"]
    if len(drawn) >= 2:
        (t0, d0), (t1, d1) = drawn[0], drawn[-1]
        parts.append(f"largest heating contraction {-d0:.2f} mm at {t0:g} turns vs {-d1:.2f} mm at {t1:g} turns")
    third = "heating's effect per twist" if len(drawn) >= 2 else "steady length against voltage"
    return f"Twist, heater voltage and length; steady length against twist and voltage; {third}. " + \
        "; ".join(parts) + "."


def _heating_per_twist(ax, rests: list, twists: list[float], cmap) -> list[tuple[float, float]]:
    """Panel (c): steady length minus the unheated length at the same twist, against voltage,
    one curve per twist; returns [(twist, most negative change)] of the curves drawn."""
    cold: dict[float, list[float]] = {}
    for p in rests:
        if p.heater_voltage == 0:
            cold.setdefault(round(p.turns, 6), []).append(p.length)
    drawn = []
    for i, twist in enumerate(twists):
        if twist not in cold:
            continue
        base = float(np.median(cold[twist]))
        curve = sorted({(round(p.heater_voltage, 3), p.length - base) for p in rests
                        if round(p.turns, 6) == twist and p.heater_voltage > 0})
        if len(curve) >= 2:
            ax.plot(*zip(*curve), "o-", ms=4, lw=0.8, color=cmap(i / max(1, len(twists) - 1)),
                    label=f"{twist:g} turns")
            drawn.append((twist, min(c[1] for c in curve)))
    ax.set_xlabel("heater voltage (V)")
    ax.set_ylabel("length change from heating (mm)")
    ax.set_title("(c) heating's effect at each twist (equal if additive, eq. 3.3)", fontsize=10)
    ax.grid(alpha=0.3)
    if drawn:
        ax.legend(fontsize=8)
    return drawn


def _steady_scatter(fig, ax, x, length_mm, colour, cmap: str, colour_label: str, x_label: str, heading: str) -> None:
    """Steady lengths (mm) against ``x``, coloured by the other input."""
    sc = ax.scatter(x, length_mm, c=colour, cmap=cmap, s=22, edgecolors="k", linewidths=0.3)
    fig.colorbar(sc, ax=ax, label=colour_label)
    ax.set_xlabel(x_label)
    ax.set_ylabel("steady length (mm)")
    ax.set_title(heading, fontsize=10)
    ax.grid(alpha=0.3)
