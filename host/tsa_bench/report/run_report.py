"""`tsa-bench report`: choose the figures a run supports, write them and an index.html.

Contract: :func:`select_figures` decides from the run's content alone (never from the
plan name, so imported runs get the same treatment) which figure kinds apply, and says
why each other kind does not; :func:`write_run_report` reads the run with
:func:`~tsa_bench.store.read_run` (contract checks, :class:`RunFileError` on a bad file),
writes ``<kind>.<fmt>`` (png, pdf or svg) for every applicable kind and ``index.html`` into ``out_dir``, and
returns a :class:`Report`. A run that failed, was aborted or killed is reported as far
as its data go, with the status in every title and at the top of the page; a run with
no samples gets a page saying so and no figures.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tsa_bench.report import run_figures as rf
from tsa_bench.report.control_figures import fig_tracking, has_tracking
from tsa_bench.report.extra_figures import extra_columns, fig_extras, fig_extras_xy
from tsa_bench.report.fig_common import DPI, FORMATS, Figure, finite_any_col
from tsa_bench.report.html import write_index
from tsa_bench.report.twist_heat_figures import fig_twist_heat, heated_twists
from tsa_bench.report.run_analysis import cycle_table, motor_stops, plateaus, span, stiffness_points
from tsa_bench.rundata import RunData
from tsa_bench.store import read_run

#: kind -> (drawing function, thesis figure, what it needs)
KINDS: dict[str, tuple[Callable[[RunData, Path], str | None], str]] = {
    "timeseries": (rf.fig_timeseries, "Figs. 2.5(a), 2.7(a), 2.8(a)"),
    "stiffness": (rf.fig_stiffness, "Fig. 2.4"),
    "loops": (rf.fig_loops, "Fig. 2.5(b)-(c)"),
    "voltage": (rf.fig_voltage, "Fig. 2.6(a)-(c)"),
    "twist_heat": (fig_twist_heat, "-- (thesis 5.2.2: twisting and heating together; Fig. 2.6 heated at one twist)"),
    "resistance_length": (rf.fig_resistance_length, "Fig. 2.7(c)-(f)"),
    "transient": (rf.fig_transient, "Fig. 2.8(a)-(b)"),
    "drift": (rf.fig_drift, "Fig. 2.8(d)"),
    "tracking": (fig_tracking, "-- (thesis 5.2: length control from resistance)"),
    "extras": (fig_extras, "-- (channels beyond the contract)"),
    "extras_xy": (fig_extras_xy, "-- (channels beyond the contract)"),
}


@dataclass
class Report:
    """What was written: figures in order, kinds left out with the reason, the page."""

    run: RunData
    out_dir: Path
    figures: list[Figure] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)
    index: Path | None = None


def select_figures(run: RunData) -> tuple[list[str], dict[str, str]]:
    """(applicable kinds in display order, {other kind: why not})."""
    s = run.samples
    if len(run) == 0:
        return [], {k: "the run has no samples" for k in KINDS}
    rests = plateaus(run)
    twisted = span(s["turns"]) > 0
    has_l, has_r = finite_any_col(s["length"]), finite_any_col(s["resistance"])
    volt_levels = {round(p.heater_voltage, 6) for p in rests if np.isfinite(p.heater_voltage)}
    table = cycle_table(run)
    n_cycles = 0 if table is None else len(table.cycle)
    extras = extra_columns(run)
    stops = [p for p in motor_stops(run) if np.isfinite(s["resistance"][p.start:p.stop]).sum() >= 3]
    rl_rests = [p for p in rests if np.isfinite(p.resistance) and np.isfinite(p.length)]
    checks = {
        "timeseries": (any(finite_any_col(s[c]) for c in ("turns", "length", "resistance")),
                       "turns, length and resistance are all unmeasured (see the extra channels)"),
        "stiffness": (len(stiffness_points(run)) >= 2,
                      "needs rests at one twist level under no load and at least two other loads"),
        "loops": (twisted and has_l, "needs the twist to change and length to be measured"),
        "voltage": (len(volt_levels) >= 2 and has_l, "needs rests at two or more heater voltages"),
        "twist_heat": (has_l and len(heated_twists(run)) >= 2, "needs rests with the heater on at two or more twists"),
        "resistance_length": (twisted and has_r and has_l and len({round(p.turns, 6) for p in rl_rests}) >= 3,
                              "needs rests at 3 or more twist levels with resistance and length measured"),
        "transient": (has_r and len(stops) >= 3, "needs at least 3 rests of 2 s or more after a move, "
                                                 "with resistance measured"),
        "drift": (n_cycles >= 5, f"needs a repeat block of at least 5 cycles (has {n_cycles})"),
        "tracking": (has_tracking(run), "the run has no track_length (length_target column)"),
        "extras": (len(extras) >= 1, "the run has no columns beyond the contract"),
        "extras_xy": (len(extras) >= 2, "needs two or more columns beyond the contract"),
    }
    chosen = [k for k in KINDS if checks[k][0]]
    return chosen, {k: checks[k][1] for k in KINDS if not checks[k][0]}


def write_run_report(run_path: str | Path, out_dir: str | Path | None = None, *, fmt: str = "png",
                     dpi: int = DPI) -> Report:
    """Write the figures and index.html of one run; see the module contract.

    ``out_dir`` defaults to ``<run file without .h5>_report`` next to the run file;
    figures are ``<kind>.<fmt>`` (png, pdf or svg) at ``dpi``.
    """
    if fmt not in FORMATS:
        raise ValueError(f"figure format {fmt!r} is not one of {', '.join(FORMATS)}")
    if not 20 <= dpi <= 1200:
        raise ValueError(f"dpi must be 20..1200, got {dpi}")
    run = read_run(run_path)
    p = Path(run_path)
    out = Path(out_dir) if out_dir is not None else p.with_name(p.stem + "_report")
    out.mkdir(parents=True, exist_ok=True)
    report = Report(run, out)
    chosen, report.skipped = select_figures(run)
    for kind in chosen:
        draw, thesis = KINDS[kind]
        path = out / f"{kind}.{fmt}"
        caption = draw(run, path, dpi=dpi)
        if caption is None:  # the drawing found less than the selector did
            report.skipped[kind] = "not enough data for this figure"
            continue
        report.figures.append(Figure(kind, path, caption, thesis))
    report.index = write_index(report)
    return report
