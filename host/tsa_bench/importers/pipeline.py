"""`tsa-bench import`: a measured data file from any lab -> a run file meeting the contract.

Contract of :func:`import_file`: the source's format is found (:mod:`.detect`), its
columns placed (:mod:`.columns`) and checked (:mod:`.values`), its clock put in order
(:mod:`.clock`), segments found (:mod:`.segments`) and the run file written
(:mod:`.writer`) with ``backend`` "import", ``exit_status`` "success" and in
``metadata``: the source file and format, the column map, the source units,
``extra_columns`` (name: unit), ``time_order`` (what was done to the clock), the
``sample_rate`` found, ``segments`` (how they were made, with the thresholds), the
``constants`` declared and the ``adjustments`` (negate, scale, offset) made, and a
``time`` note when t was made from the row order. An import that places no measured
column (only t) is refused. Every problem raises
:class:`ImportFileError` naming the file, the line (row) and the column, before anything
is written. The returned :class:`ImportSummary` lists every source column, where it went
and with which unit and factor, every column left out and why, and what was done; its
``warnings`` name impossible values (:func:`.adjust.impossible`) and the option that fixes each.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.importers import adjust, clock, segments as segs
from tsa_bench.importers.columns import Choice, resolve, units_for
from tsa_bench.importers.detect import read_source
from tsa_bench.importers.errors import ImportFileError
from tsa_bench.importers.headers import same_unit, split_header
from tsa_bench.importers.values import converted
from tsa_bench.importers.writer import fill, start_record, write_run
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.store.budget import OverBudget


@dataclass
class ImportOptions:
    """What the user said. ``mapping`` {target: source column (name or 1-based position)};
    ``units`` {target or column: unit}; ``segments`` "infer", "none" or "column=NAME";
    ``thresholds`` overrides of :data:`.segments.DEFAULTS`; ``constants`` {target: "VALUE[UNIT]"},
    ``scale`` {column: "F[UNIT]"}, ``offset`` {column: "X[UNIT]"}, ``negate`` columns
    (:mod:`.adjust`); reader options as named."""

    mapping: dict[str, str] | None = None
    units: dict[str, str] = field(default_factory=dict)
    meta: dict[str, str] = field(default_factory=dict)
    sample_period_s: float | None = None
    no_header: bool = False
    delimiter: str | None = None
    decimal: str | None = None
    sheet: str | None = None
    var: str | None = None
    group: str | None = None
    time_order: str = "error"
    segments: str = "none"
    thresholds: dict[str, float] = field(default_factory=dict)
    constants: dict[str, str] = field(default_factory=dict)
    scale: dict[str, str] = field(default_factory=dict)
    offset: dict[str, str] = field(default_factory=dict)
    negate: list[str] = field(default_factory=list)


@dataclass
class ImportSummary:
    """What the import did, for the user: one line each; ``warnings`` name impossible values."""

    path: Path
    fmt: str
    n_samples: int
    lines: list[str]
    warnings: list[str] = field(default_factory=list)


def _segment_spec(spec: str, table: Any) -> tuple[str, int | None]:
    if spec in ("infer", "none"):
        return spec, None
    key, sep, ref = spec.partition("=")
    if key != "column" or not sep or not ref:
        raise ImportFileError(f"--segments {spec!r}: give infer, none or column=NAME")
    from tsa_bench.importers.columns import _find
    i = _find(table, ref)
    if i is None:
        raise ImportFileError(f"--segments column={ref}: no such column (columns: {', '.join(table.names) or 'unnamed'})")
    return "column", i


def _describe(table: Any, chosen: list[Choice], left: dict[int, str]) -> list[str]:
    by_index = {c.index: c for c in chosen}
    out = []
    for i in range(len(table.columns)):
        label = f"column {table.label(i)}"
        if i in by_index:
            c = by_index[i]
            conv = f"{c.unit}" + (f" -> {c.stored}, x{c.factor:g}" + (f" {c.offset:+g}" if c.offset else "")
                                  if c.stored and not same_unit(c.stored, c.unit) else "")
            out.append(f"  {label} -> {c.target} ({c.kind}, {c.how}) [{conv or '1'}]")
        else:
            out.append(f"  {label} left out: {left.get(i, 'not used')}")
    return out


def _segments(seg_mode: str, seg_index: int | None, seg_values: Any, table: Any,
              data: dict[str, np.ndarray], samples: dict[str, np.ndarray], thr: dict[str, float]
              ) -> tuple[list, dict[str, Any], list[str]]:
    """(records, metadata, summary lines) of the segments (module contract); fills samples["segment"]."""
    records: list = []
    meta: dict[str, Any] = {"mode": seg_mode}
    if "segment" in data and seg_mode == "infer":
        meta["mode"] = "segment column (kept)"
        lines = ["segments: the file's segment column is kept (no /segments rows: their kinds are unknown)"]
    elif seg_mode == "column":
        samples["segment"], records = segs.from_column(samples["t"], seg_values, samples["motor_moving"])
        meta["column"] = table.label(seg_index)
        lines = [f"segments: {len(records)} from column {table.label(seg_index)}"]
    elif seg_mode == "infer":
        samples["segment"], records = segs.infer(samples, samples["motor_moving"], thr)
        meta["thresholds"] = thr
        th = f"thresholds: {segs.describe(thr)} (--segment-threshold)"
        if records:
            kinds = {k: sum(r.kind == k for r in records) for k in ("move", "hold", "heater")}
            lines = [f"segments inferred: {len(records)} ({', '.join(f'{v} {k}' for k, v in kinds.items())}); {th}"]
        else:
            lines = [f"segments: none inferred (no moves, heater or load changes; {th}): fit and diagnose will "
                     "use the whole run"]
    else:
        lines = ["segments: none (--segments none): fit and diagnose will use the whole run"]
    meta["n"] = len(records)
    return records, meta, lines


def _no_measured_column(table: Any, chosen: list[Choice], left: dict[int, str]) -> ImportFileError:
    why = "; ".join(f"column {table.label(i)}: {w}" for i, w in list(left.items())[:6])
    return ImportFileError(f"{table.where()}: no measured column placed, only "
                           f"{'t' if chosen else 'synthetic time'} ({why or 'the file has no other column'}); "
                           "map one, e.g. --map length=COLUMN (nothing written)")


def import_file(src_path: str | Path, out_path: str | Path, options: ImportOptions) -> ImportSummary:
    """Convert one source file into a run file; see the module contract.

    A file that needs more memory than the budget (:mod:`tsa_bench.store.budget`, reckoned
    from what it declares before its data is read), or more than the machine gives
    (MemoryError), is refused with an ImportFileError saying so; nothing is written."""
    try:
        return _import_file(src_path, out_path, options)
    except OverBudget as exc:
        raise ImportFileError(str(exc)) from None
    except MemoryError:
        raise ImportFileError(f"{src_path}: not enough memory to import it (the machine refused more); nothing was "
                              "written. Free memory, import a part of the file, or check that it is not damaged") \
            from None


def _import_file(src_path: str | Path, out_path: str | Path, options: ImportOptions) -> ImportSummary:
    src, out = Path(src_path), Path(out_path)
    o = options
    if os.path.lexists(out):   # a file, or a link (even a dangling one): never replaced, never written through
        raise ImportFileError(f"{out} already exists; choose another --out (existing runs are never replaced)")
    if o.sample_period_s is not None and not (math.isfinite(o.sample_period_s) and o.sample_period_s > 0):
        raise ImportFileError(f"--sample-period must be a positive number of seconds, got {o.sample_period_s}")
    if o.time_order not in clock.MODES:
        raise ImportFileError(f"--time-order {o.time_order!r}: give one of {', '.join(clock.MODES)}")
    unknown = set(o.thresholds) - set(segs.DEFAULTS)
    if unknown:
        raise ImportFileError(f"--segment-threshold: unknown {', '.join(sorted(unknown))} "
                              f"(known: {', '.join(segs.DEFAULTS)})")
    try:
        thr = segs.settings(o.thresholds)
    except ValueError as exc:
        raise ImportFileError(f"--segment-threshold: {exc}") from None
    adjust.scales(o.scale)   # a malformed --scale is named before the file is read
    table = read_source(src, o)
    if table.n_rows == 0:
        raise ImportFileError(f"{table.path}: no data rows" + (" after the header" if table.has_header else ""))
    seg_mode, seg_index = _segment_spec(o.segments, table)
    timed = o.sample_period_s is None
    chosen, left, guessed = resolve(table, o.mapping, timed, (seg_index,) if seg_index is not None else ())
    if not any(c.target != "t" for c in chosen):
        raise _no_measured_column(table, chosen, left)
    consts = adjust.constants(o.constants, {c.target for c in chosen})
    names = {n: c.target for c in chosen for n in (table.names[c.index], split_header(table.names[c.index])[0]) if n}
    factors, calibrations, offsets, negate = adjust.keyed(o.scale, o.offset, o.negate,
                                                          [c.target for c in chosen] + list(consts), names)
    units_for(table, chosen, o.units, {k: (factors[k], u) for k, u in calibrations.items()})
    data = converted(table, chosen)
    lines = [f"read {src} as {table.fmt}"] + [f"  {note}" for note in table.notes]
    lines.append(f"{len(table.columns)} source columns:")
    lines += _describe(table, chosen, left) + [f"  {g}" for g in guessed]
    n0 = table.n_rows
    for k, (value, unit, given) in consts.items():
        data[k] = np.full(n0, value)
        lines.append(f"  {k} = {given} for every row ({value:g} {unit}; --const)")
    units = {c.target: c.stored for c in chosen} | {k: u for k, (_, u, _) in consts.items()}
    lines += adjust.apply(data, units, factors, offsets, negate, calibrations)
    warnings = adjust.impossible(data)
    if not timed:
        data["t"] = np.arange(n0, dtype=float) * o.sample_period_s
        keep, order = np.arange(n0), {"mode": "row order", "rows_affected": 0}
    else:
        if "t" not in data:  # the format's own time (TDMS waveform)
            data["t"] = np.asarray(table.time_s, float)
            lines.append("  t from the file's waveform timing (wf_increment)")
        tcol = next((f"{table.label(c.index)}" for c in chosen if c.target == "t"), "'waveform time'")
        keep, order = clock.order_rows(data["t"], o.time_order, table.where, tcol)
    if order["rows_affected"]:  # sorted rows are stored sorted (not only counted): every column, in the order kept
        data = {k: v[keep] for k, v in data.items()}
    if order.get("said"):
        lines.append(f"time order: {order['said']}")
    seg_values = table.columns[seg_index].values[keep] if seg_index is not None else None
    n = len(data["t"])
    rate = clock.sample_rate(data["t"])
    if rate:
        lines.append(f"sample rate {rate['rate_hz']:.6g} Hz (median interval {rate['interval_s']:.6g} s, jitter "
                     f"{rate['jitter_rms_s']:.3g} s rms, largest interval {rate['largest_interval_s']:.6g} s)")
    if "load" in data and len(np.unique(data["load"][np.isfinite(data["load"])])) > 20:
        lines.append("note: the declared load takes more than 20 values: if it is a measured force (a load cell), "
                     "map it as force (--map force=COLUMN); fit counts every declared load")
    extras = {k: (data.pop(k), units[k]) for k in list(data) if k not in SAMPLE_COLUMNS}
    samples = fill(data, n)
    if "motor_moving" not in data and "turns" in data:
        samples["motor_moving"] = segs.moving_from_turns(samples["turns"], samples["t"], thr)
    records, seg_meta, seg_lines = _segments(seg_mode, seg_index, seg_values, table, data, samples, thr)
    lines += seg_lines
    t0, t1 = float(samples["t"][0]), float(samples["t"][-1])
    metadata: dict[str, Any] = {**o.meta, "imported_from": str(src), "source_format": table.fmt,
                                "column_map": {c.target: table.names[c.index] or table.label(c.index) for c in chosen},
                                "source_units": {c.target: c.unit for c in chosen},
                                "time_order": {k: v for k, v in order.items() if k != "said"}, "segments": seg_meta}
    if rate:
        metadata["sample_rate"] = rate
    if left:
        metadata["columns_left_out"] = {table.names[i] or table.label(i): why for i, why in left.items()}
    if extras:
        metadata["extra_columns"] = {k: u for k, (_, u) in extras.items()}
    if consts:
        metadata["constants"] = {k: given for k, (_, _, given) in consts.items()}
    if factors or offsets or negate or calibrations:
        metadata["adjustments"] = {"negate": sorted(negate),
                                   "scale": {k: f"{f:g}{calibrations.get(k, '')}" for k, f in factors.items()},
                                   "offset": {k: f"{x:g}{u}" for k, (x, u) in offsets.items()}}
    if warnings:
        metadata["import_warnings"] = warnings
    if not timed:
        metadata["time"] = f"no time column: t = row index x {o.sample_period_s:g} s (rows in file order)"
    start = start_record(o.meta.get("name", src.stem), src, t1 - t0, len(records), metadata)
    try:
        write_run(out, start, samples, extras, records, f"imported from {src.name}")
    except FileExistsError:
        raise ImportFileError(f"{out} already exists; choose another --out (existing runs are never replaced)") from None
    return ImportSummary(out, table.fmt, n, lines, warnings)
