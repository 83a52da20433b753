"""The standard figures of a study: each figure of merit against each varied parameter.

Contract of :func:`write_report`: for every figure of merit (a numeric or true/false
column of the results, the points that failed left out) and every varied parameter with
more than one value (seeds are replicates, pooled: never an axis), one PNG ``<figure>__vs__<parameter>.png``: true/false figures as
rates with 95 % Wilson intervals (power curves; a detection rate at magnitude 0 is the
false-alarm rate), numbers as means with 95 % t intervals, one line per value of the
study's ``report.lines`` parameters (default: the varied text parameters, e.g.
``effect.name``), pooled over the other parameters (seeds, draws, the rest). ``summary.md`` holds the same numbers as tables. Returns the paths
written (none when the table has no rows).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from tsa_bench.outputs import save_figure, write_text
from tsa_bench.sweep.stats import mean_interval, wilson
from tsa_bench.sweep.study import Study
from tsa_bench.sweep.table import ResultsTable, unit_of

_NOT_FIGURES = {"point", "key", "status", "error", "work_s", "worker", "finished", "version", "config"}


def _kind(values: list[Any]) -> str | None:
    vals = [v for v in values if v is not None]
    if not vals:
        return None
    if all(isinstance(v, bool) for v in vals):
        return "rate"
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
        return "mean"
    return None


def _order(v: Any) -> tuple:
    """Sort key: numbers by value, then text, then missing values."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return (0, float(v), "")
    return (1, 0.0, str(v)) if v is not None else (2, 0.0, "")


def _label(name: str) -> str:
    u = unit_of(name)
    return name if u == "1" else f"{name} [{u}]"


def groups(rows: list[dict[str, Any]], x: str, series: list[str], figure: str, kind: str
           ) -> dict[tuple, list[tuple[Any, float, float, float, int]]]:
    """series values -> [(x, value, low, high, n)] sorted by x: a rate with its Wilson interval
    or a mean with its t interval, over the rows of each (series, x) cell."""
    cells: dict[tuple, dict[Any, list[Any]]] = {}
    for r in rows:
        v = r.get(figure)
        if v is None or (isinstance(v, float) and not math.isfinite(v)):
            continue
        cells.setdefault(tuple(r.get(s) for s in series), {}).setdefault(r.get(x), []).append(v)
    out: dict[tuple, list] = {}
    for s, by_x in cells.items():
        line = []
        for xv in sorted(by_x, key=_order):
            vals = by_x[xv]
            if kind == "rate":
                k, n = sum(bool(v) for v in vals), len(vals)
                lo, hi = wilson(k, n)
                line.append((xv, k / n, lo, hi, n))
            else:
                m, lo, hi = mean_interval([float(v) for v in vals])
                line.append((xv, m, lo, hi, len(vals)))
        out[s] = line
    return out


def _is_seed(param: str) -> bool:
    return param.split(".")[-1] == "seed"


def _is_series(param: str, rows: list[dict[str, Any]], study: Study) -> bool:
    """A parameter drawn as separate lines: the study's ``report.lines``, else one that takes text."""
    if study.lines is not None:
        return param in study.lines
    return any(isinstance(r.get(param), str) for r in rows)


def write_report(study: Study, table: ResultsTable, out_dir: str | Path) -> list[Path]:
    """Draw the figures and summary.md (module contract)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = table.read()
    if data is None:
        return []
    keys = {p.key for p in study.points}
    rows = [r for r in data.to_pylist() if r["key"] in keys and r["status"] == "done"]
    if not rows:
        return []
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    params = [a.path for a in study.axes if len({r.get(a.path) for r in rows}) > 1]
    xs = [p for p in params if not _is_seed(p)]
    figures = [(c, k) for c in data.column_names if c not in _NOT_FIGURES and c not in params
               and (k := _kind([r.get(c) for r in rows])) is not None]
    paths: list[Path] = []
    lines = [f"# {study.name}: {len(rows)} points done", ""]
    for x in xs:
        series = [p for p in params if p != x and _is_series(p, rows, study)]
        for fig, kind in figures:
            g = groups(rows, x, series, fig, kind)
            if not g:
                continue
            what = "rate (95 % Wilson interval)" if kind == "rate" else "mean (95 % t interval)"
            lines += [f"## {fig} vs {x}: {what}", "", f"| {' | '.join(series + [x])} | {fig} | 95 % interval | n |",
                      "|" + "---|" * (len(series) + 4)]
            fig_obj, ax = plt.subplots(figsize=(6.4, 4.0))
            ordered = sorted(g.items(), key=lambda kv: [_order(v) for v in kv[0]])
            numeric = [p[0] for _, line in ordered for p in line if not isinstance(p[0], str)]
            span = (max(numeric) - min(numeric)) if numeric else 0.0
            for i, (s, line) in enumerate(ordered):
                dodge = (i - (len(ordered) - 1) / 2) * 0.008 * (span or 1.0)   # lines side by side, not hidden
                xs = list(range(len(line))) if isinstance(line[0][0], str) else [p[0] + dodge for p in line]
                ys = [p[1] for p in line]
                err = [[max(p[1] - p[2], 0) if math.isfinite(p[2]) else 0 for p in line],
                       [max(p[3] - p[1], 0) if math.isfinite(p[3]) else 0 for p in line]]
                name = ", ".join(f"{v}" for v in s) or None
                ax.errorbar(xs, ys, yerr=err, marker="o", capsize=3, label=name)
                if isinstance(line[0][0], str):
                    ax.set_xticks(xs, [p[0] for p in line])
                for p in line:
                    lines.append(f"| {' | '.join(str(v) for v in s)}{' | ' if s else ''}{p[0]} | {p[1]:.4g} | "
                                 f"[{p[2]:.4g}, {p[3]:.4g}] | {p[4]} |")
            lines.append("")
            ax.set_xlabel(_label(x))
            ax.set_ylabel(_label(fig) + (" (rate)" if kind == "rate" else ""))
            if kind == "rate":
                ax.set_ylim(-0.03, 1.03)
            ax.set_title(f"{study.name}: {fig} vs {x}", fontsize=9)
            if any(s for s in g):
                ax.legend(fontsize=7)
            ax.grid(alpha=0.3)
            fig_obj.tight_layout()
            path = out / f"{fig}__vs__{x}.png"
            save_figure(fig_obj, path, dpi=100)
            plt.close(fig_obj)
            paths.append(path)
    summary = out / "summary.md"
    write_text(summary, "\n".join(lines) + "\n")
    paths.append(summary)
    return paths
