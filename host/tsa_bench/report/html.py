"""index.html of a run report: metadata, exit status, the figures with captions.

Contract: :func:`write_index` writes one self-contained HTML page (figures linked by
relative file name, no scripts, no external resources) next to the figures. Every text
that comes from the run file (attributes, metadata, reasons, protocol text) is escaped
with :func:`html.escape`, so a protocol or metadata value can never inject markup.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.outputs import write_text
from tsa_bench.rundocs import SAMPLE_COLUMNS

#: Root attributes shown first, in this order (docs/run-format.md).
_FIRST = ("plan_name", "exit_status", "reason", "created", "backend", "firmware", "software", "duration_s",
          "wall_time_s", "samples_lost", "port")
#: How the page names an attribute (others: the name with '_' as spaces, a unit suffix as "(unit)").
LABELS = {
    "plan_name": "Plan", "exit_status": "Exit status", "reason": "Reason", "created": "Created",
    "backend": "Bench", "firmware": "Firmware", "software": "Software", "duration_s": "Duration (device time)",
    "wall_time_s": "Wall time", "samples_lost": "Samples lost (counter gaps)", "port": "Port",
    "estimated_duration_s": "Estimated duration", "format": "File format", "format_version": "Format version",
    "n_segments": "Segments in the plan", "resumed_from": "Resumes", "continued_in": "Continued in",
    "first_segment": "First segment", "samples_not_stored": "Samples not stored", "derived_from": "Derived from",
    "recovered_samples": "Samples recovered from the live sidecar",
}
_UNIT_SUFFIX = {"_s": "s", "_V": "V", "_mm": "mm", "_ohm": "ohm", "_g": "g", "_N": "N"}


def label(key: str) -> str:
    """A readable name for an attribute key (``duration_s`` -> ``Duration (device time)``)."""
    if key in LABELS:
        return LABELS[key]
    for suffix, unit in _UNIT_SUFFIX.items():
        if key.endswith(suffix) and len(key) > len(suffix):
            return f"{key[: -len(suffix)].replace('_', ' ').capitalize()} ({unit})"
    return key.replace("_", " ").capitalize()


def value_text(key: str, v: Any) -> str:
    """Numbers rounded for reading: durations as h:mm:ss, others to 4 significant digits."""
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return f"{int(v):,}"
    if isinstance(v, (float, np.floating)):
        x = float(v)
        if key.endswith("duration_s") or key == "wall_time_s":
            total = int(round(x))
            return f"{total // 3600}:{total // 60 % 60:02d}:{total % 60:02d}" + (f" ({x:.1f} s)" if x < 600 else "")
        return f"{x:.4g}"
    return str(v)
_STYLE = ("body{font-family:sans-serif;max-width:1200px;margin:1em auto;padding:0 1em}"
          "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left;"
          "vertical-align:top}img{max-width:100%;border:1px solid #ddd}.bad{color:#a00;font-weight:bold}"
          "figure{margin:1.5em 0}figcaption{color:#333}pre{background:#f6f6f6;padding:.5em;overflow:auto}")


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _attr_rows(attrs: dict[str, Any]) -> list[tuple[str, str]]:
    keys = [k for k in _FIRST if k in attrs] + sorted(k for k in attrs if k not in _FIRST
                                                      and k not in ("metadata", "device_identity"))
    rows = [(label(k), value_text(k, attrs[k])) for k in keys]
    meta = attrs.get("metadata")
    if meta:
        try:
            for k, v in json.loads(meta).items():
                shown = value_text(k, v) if isinstance(v, (int, float)) else (
                    v if isinstance(v, str) else json.dumps(v))
                rows.append((f"Metadata: {k}", shown))
        except (ValueError, AttributeError, TypeError):  # not the JSON object the contract says
            rows.append(("metadata", str(meta)))
    return rows


def _status_line(run) -> str:
    status = run.exit_status
    if status == "success":
        return ""
    if status == "running":
        text = ("This run was killed (exit_status is still 'running'): the figures show the data up to "
                "the writer's last flush.")
    else:
        text = f"This run ended with status '{status}': {run.attrs.get('reason', '')}. The figures show what it recorded."
    return f'<p class="bad">{_e(text)}</p>'


def write_index(report) -> Path:
    """Write ``index.html`` for a :class:`~tsa_bench.report.run_report.Report`; return its path."""
    run = report.run
    name = run.attrs.get("plan_name") or Path(run.path).stem
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{_e(name)} - tsa-bench report</title>",
             f"<style>{_STYLE}</style></head><body>",
             f"<h1>{_e(name)}</h1><p>Run file: <code>{_e(run.path)}</code></p>", _status_line(run)]
    n, t = len(run), run.samples["t"]
    span_s = float(t[-1] - t[0]) if n > 1 else 0.0
    parts.append(f"<p>{n} samples over {span_s:.1f} s of device time; "
                 f"{0 if run.segments is None else len(run.segments)} segments; "
                 f"{0 if run.events is None else len(run.events)} events.</p>")
    parts.append("<h2>Run</h2><table>")
    parts += [f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in _attr_rows(run.attrs)]
    parts.append("</table>")
    extra = [k for k in run.samples if k not in SAMPLE_COLUMNS]
    if extra:
        parts.append("<h2>Extra columns</h2><p>Columns beyond the run-file contract:</p><table>"
                     "<tr><th>column</th><th>units</th><th>finite samples</th><th>min</th><th>max</th></tr>")
        for k in extra:
            a = np.asarray(run.samples[k], float) if run.samples[k].dtype.kind in "fiu" else np.array([np.nan])
            ok = a[np.isfinite(a)]
            lo, hi = (f"{ok.min():.6g}", f"{ok.max():.6g}") if len(ok) else ("-", "-")
            parts.append(f"<tr><td>{_e(k)}</td><td>{_e(run.units.get(k, ''))}</td><td>{len(ok)}</td>"
                         f"<td>{lo}</td><td>{hi}</td></tr>")
        parts.append("</table>")
    parts.append("<h2>Figures</h2>")
    if not report.figures:
        parts.append("<p>No figures: the run has no samples.</p>")
    for fig in report.figures:
        src = _e(fig.path.name)
        shown = (f"<object data='{src}' type='application/pdf' width='100%' height='600'>"
                 f"<a href='{src}'>{src}</a></object>" if fig.path.suffix == ".pdf"
                 else f"<img src='{src}' alt='{_e(fig.name)}'>")
        parts.append(f"<figure id='{_e(fig.name)}'>{shown}"
                     f"<figcaption><b>{_e(fig.name)}</b> (like thesis {_e(fig.thesis)}): {_e(fig.caption)}"
                     "</figcaption></figure>")
    if report.skipped:
        parts.append("<h2>Figures not drawn</h2><ul>")
        parts += [f"<li><b>{_e(k)}</b>: {_e(v)}</li>" for k, v in report.skipped.items()]
        parts.append("</ul>")
    if run.protocol_text:
        parts.append(f"<h2>Protocol</h2><pre>{_e(run.protocol_text)}</pre>")
    parts.append("</body></html>\n")
    path = report.out_dir / "index.html"
    write_text(path, "\n".join(parts))
    return path
