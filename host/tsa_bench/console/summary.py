"""One-screen text summaries of a run file (after `run`, and for `tsa-bench info`)."""

from __future__ import annotations

from tsa_bench.console.progress import hms
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.store.inspect import ColumnStats, RunInfo

SHOWN = ("t", "turns", "length", "resistance", "heater_voltage", "load", "motor_moving")


def format_run_info(info: RunInfo, *, verbose: bool = True) -> str:
    a = info.attrs
    lines = [
        f"run file     {info.path}",
        f"plan         {a.get('plan_name', '?')}   backend {a.get('backend', '?')}   firmware {a.get('firmware', '?')}",
        f"created      {a.get('created', '?')}   format {a.get('format')} {a.get('format_version')}",
        f"exit status  {a.get('exit_status', '?')}: {a.get('reason', '')}",
        f"duration     {hms(info.t_range[1] - info.t_range[0]) if info.n_samples else '-'} device time"
        + (f", {a['wall_time_s']:.1f} s wall" if isinstance(a.get("wall_time_s"), (int, float)) else ""),
        f"samples      {info.n_samples}   lost (counter gaps) {info.counter_gaps}",
        f"segments     {info.n_segments} recorded, {info.segments_completed} completed   "
        + ", ".join(f"{k} {v}" for k, v in sorted(info.segment_kinds.items())),
        f"events       {info.n_events}   " + ", ".join(f"{k} {v}" for k, v in sorted(info.event_kinds.items())),
    ]
    if verbose and info.n_samples:
        lines.append("")
        lines.append(f"{'column':<16}{'units':<8}{'min':>12}{'mean':>12}{'max':>12}{'measured':>10}")
        for name in SHOWN:
            c = info.columns.get(name)
            if c is not None:
                lines.append(_column_line(name, c))
        extra = [n for n in info.columns if n not in SAMPLE_COLUMNS]
        if extra:
            lines.append(f"extra columns ({len(extra)}, beyond the contract):")
            lines += [_column_line(name, info.columns[name]) for name in extra]
    return "\n".join(lines)


def _column_line(name: str, c: ColumnStats) -> str:
    return f"{name + ' ':<16}{c.units:<8}{c.min:>12.4g}{c.mean:>12.4g}{c.max:>12.4g}{c.finite:>10d}"
