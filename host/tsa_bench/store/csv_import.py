"""`tsa-bench import`: a CSV from another rig -> a run file meeting the contract.

Contract of :func:`import_csv`:

* the first line that is not blank and does not start with ``#`` is the header; a header
  cell ``name [unit]`` or ``name (unit)`` gives the column's unit (so files written by
  ``tsa-bench export`` import without options); delimiter ``,`` (``;`` or tab when the
  header has no comma; runs of blanks when it has none of these but spaces);
* ``mapping`` {target: CSV column} chooses the columns (CSV column by full header text or
  by name without the unit). A target is a contract sample column of docs/run-format.md,
  a named channel of :data:`tsa_bench.units.CHANNELS` (temperature, force, pressure,
  stress, strain, current, voltage, angle) or any other name of letters, digits and
  ``_`` (an extra column). Without a mapping, CSV columns named like a contract column
  or a channel are taken, and every column whose header declares a unit. ``t`` is
  required unless ``sample_period_s`` is given (a file without time: ``t`` = row index
  x period, rows in file order, said so in the metadata);
* ``units`` {target or CSV column: unit} overrides header units. Contract columns and
  channels are converted to the unit they are stored in (:mod:`tsa_bench.units`; a load
  given as a mass in g or kg becomes N with g0 = 9.80665 m/s^2; K and degF become
  degC); a unit of another dimension is an error naming the allowed units. Any other
  extra column keeps the unit it came with, which must be given. A column's unit comes
  from ``units``, else its header (``name [unit]``), else a unit at the end of its name
  (``time_ms``, ``len_cm``, ``R_kohm``). Every chosen column measured in a physical unit
  must have one: a column without is refused (all such columns named at once), never
  taken silently in the stored unit (a time in ms read as s). Dimensionless and count
  columns (segment, motor_moving, counter, raw counts, flags, strain) need none;
* every cell must parse: an empty or ``nan`` cell is NaN (not measured) in float
  columns, but an error in ``t`` and in integer columns; integers must fit their
  column's type (``position_raw`` is int16: 40000 is refused, never wrapped); no value
  may be infinite or larger than the run reader accepts (1e15 in magnitude);
  ``t`` must strictly increase;
* contract columns not given are filled: float columns NaN (not measured / undeclared),
  ``segment`` -1 (no segments), ``motor_moving`` 1 where ``turns`` differs from the
  previous row (0 without turns), ``counter`` the row number 0, 1, ... (no device
  counter, so no gaps), ``step_position``, ``position_raw``, ``resistance_raw`` 0,
  ``adc_flags`` bit 2 where resistance is NaN and bit 3 where length is NaN; extra
  columns are stored as further ``/samples`` columns (float64, chunked, resizable, with
  ``units``);
* the run file is written by :class:`~tsa_bench.store.RunWriter` with ``backend``
  "import", ``exit_status`` "success", ``metadata`` = ``meta`` plus the source file,
  the column map, the source units and the extra columns' units, empty ``/segments``,
  ``/events`` and ``/config`` texts; it is written to a temporary name and renamed, and
  an existing file is never replaced.

Every problem raises :class:`CsvImportError` naming the file, the line and the column;
up to 20 cell errors are reported at once.
"""

from __future__ import annotations

import csv
import difflib
import math
import os
import re
from pathlib import Path

import h5py
import numpy as np

from tsa_bench.documents import DocumentError, read_text_file
from tsa_bench.runner.documents import SAMPLE_COLUMNS, RunStart, RunStop, SampleBlock
from tsa_bench.store.hdf5 import CHUNK, RunWriter
from tsa_bench.store.reader import MAX_ABS_VALUE
from tsa_bench.units import CHANNELS, UnitError, channel_conversion, units_of

_HEADER_UNIT = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")
_EXTRA_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,63}$")
MAX_ERRORS = 20
MAX_CSV_BYTES = 1 << 30


class CsvImportError(ValueError):
    """A CSV that cannot become a run file; the message says where and what."""


def _split_header(cell: str) -> tuple[str, str]:
    m = _HEADER_UNIT.match(cell)
    return (m.group(1), m.group(2)) if m else (cell.strip(), "")


def _conversion(target: str, unit: str, where: str) -> tuple[float, float, str]:
    """(factor, offset, stored unit) taking ``target`` values in ``unit`` to the unit it is stored in.

    Contract columns and named channels (:data:`tsa_bench.units.CHANNELS`) convert to their
    stored unit and refuse a unit of another dimension, naming the allowed ones; raw and
    bookkeeping columns (segment, counter, ...) take only their contract unit; any other
    extra column keeps the unit it came with, which must be given.
    """
    if target in CHANNELS:
        try:
            f, o = channel_conversion(target, unit)
        except UnitError as exc:
            allowed = str(exc).split("use one of: ", 1)[-1]
            raise CsvImportError(f"{where}: unit '{unit}' is not known for {target} "
                                 f"({CHANNELS[target].dimension}); use one of: {allowed}") from None
        return f, o, CHANNELS[target].unit
    if target in SAMPLE_COLUMNS:
        contract = SAMPLE_COLUMNS[target][1]
        if unit not in ("", contract):
            raise CsvImportError(f"{where}: unit '{unit}' is not known for {target}; use one of: {contract}")
        return 1.0, 0.0, contract
    if not unit:
        raise CsvImportError(f"{where}: extra column {target} has no unit; give one in the header "
                             f"('{target} [unit]') or with --units {target}=UNIT (use 1 for a pure number)")
    return 1.0, 0.0, unit


def _name_unit(target: str, name: str) -> str:
    """The unit at the end of a column name (``time_ms`` -> ``ms``), if it is one for ``target``."""
    if "_" not in name or target not in CHANNELS:
        return ""
    suffix = name.rsplit("_", 1)[1]
    try:
        channel_conversion(target, suffix)
    except UnitError:
        return ""
    return suffix


def _needs_unit(target: str) -> bool:
    """Whether a column for ``target`` is measured in a physical unit (so it must say which)."""
    if target in CHANNELS:
        return CHANNELS[target].dimension != "dimensionless"
    return target not in SAMPLE_COLUMNS


def _read_header(path: Path) -> tuple[list[str], int, str, list[tuple[int, list[str]]]]:
    """(header cells, header line number, delimiter, [(line, cells) of data rows]).

    The delimiter is ``,`` (or ``;`` or tab when the header has no comma); a header with
    none of them but spaces is whitespace-separated (runs of blanks split cells).
    """
    try:
        text = read_text_file(path, "CSV file", MAX_CSV_BYTES)
    except DocumentError as exc:
        raise CsvImportError(str(exc)) from None
    lines = text.splitlines()
    for i, line in enumerate(lines):
        if line.strip() and not line.lstrip().startswith("#"):
            break
    else:
        raise CsvImportError(f"{path}: no header line (the file is empty or only comments)")
    head = lines[i]
    delim = next((d for d in (",", ";", "\t") if d in head), " " if " " in head.strip() else ",")
    if delim == " ":
        split = [(n, line.split()) for n, line in enumerate(lines[i:], start=i + 1)]
        header = split[0][1]
        body = split[1:]
    else:
        reader = csv.reader(lines[i:], delimiter=delim)
        body = []
        try:
            header = [c.strip() for c in next(reader)]
            for cells in reader:
                body.append((i + reader.line_num, cells))
        except csv.Error as exc:  # e.g. an unclosed quote swallowing the rest of the file
            raise CsvImportError(f"{path}:{i + reader.line_num}: not valid CSV ({exc})") from None
    rows = []
    for n, cells in body:
        if not cells or (len(cells) == 1 and not cells[0].strip()) or cells[0].lstrip().startswith("#"):
            continue
        rows.append((n, cells))
    return header, i + 1, delim, rows


def _auto_columns(header: list[str]) -> dict[str, int]:
    """Without --map: columns named like a contract column or a named channel, and any column
    whose header declares a unit (``name [unit]``, as `tsa-bench export` writes extra columns)."""
    out: dict[str, int] = {}
    for i, cell in enumerate(header):
        name, unit = _split_header(cell)
        if name in out:
            continue
        if name in SAMPLE_COLUMNS or name in CHANNELS or (unit and _EXTRA_NAME.match(name)):
            out[name] = i
    return out


def _resolve(path: Path, header: list[str], header_line: int, mapping: dict[str, str] | None,
             timed: bool) -> dict[str, int]:
    """{target column: header index}; ``timed`` False when t is synthesised from the row order."""
    names = [_split_header(c)[0] for c in header]
    if mapping is None:
        chosen = _auto_columns(header)
        if timed and "t" not in chosen:
            raise CsvImportError(f"{path}:{header_line}: no column named 't' in the header {header}; "
                                 "give --map t=YOUR_TIME_COLUMN,... (or --sample-period when the file has no time)")
        return chosen
    out: dict[str, int] = {}
    for target, col in mapping.items():
        known = list(SAMPLE_COLUMNS) + [c for c in CHANNELS if c not in SAMPLE_COLUMNS]
        if target not in known:
            close = difflib.get_close_matches(target, known, n=1, cutoff=0.8)
            if close or not _EXTRA_NAME.match(target):
                hint = f"did you mean '{close[0]}'? " if close else ""
                raise CsvImportError(f"--map: unknown target '{target}' ({hint}targets: {', '.join(SAMPLE_COLUMNS)}; "
                                     f"channels: {', '.join(known[len(SAMPLE_COLUMNS):])}; or an extra column "
                                     "named with letters, digits and _, unlike these)")
        idx = [i for i, c in enumerate(header) if c == col] or [i for i, n in enumerate(names) if n == col]
        if not idx:
            raise CsvImportError(f"{path}:{header_line}: column '{col}' (mapped to {target}) is not in the header; "
                                 f"columns are: {', '.join(header)}")
        out[target] = idx[0]
    if timed and "t" not in out:
        raise CsvImportError("--map: 't' (time) must be mapped, e.g. --map t=time_s,... "
                             "(or give --sample-period when the file has no time column)")
    if not timed and "t" in out:
        raise CsvImportError("--sample-period synthesises t from the row order; do not also map t")
    return out


def _parse(path: Path, header: list[str], rows: list, cols: dict[str, int],
           conversions: dict[str, tuple[float, float]]) -> dict[str, np.ndarray]:
    errors: list[str] = []
    n = len(rows)
    data = {k: np.empty(n, dtype=float) for k in cols}
    width = len(header)
    for r, (line, cells) in enumerate(rows):
        if len(cells) != width:
            errors.append(f"{path}:{line}: {len(cells)} cells, the header has {width}")
            continue
        for target, i in cols.items():
            cell = cells[i].strip()
            where = f"{path}:{line}: column '{header[i]}' ({target})"
            try:
                v = float(cell) if cell else float("nan")
            except ValueError:
                errors.append(f"{where}: cannot parse '{cell}' as a number")
                continue
            dtype = SAMPLE_COLUMNS[target][0] if target in SAMPLE_COLUMNS else "f8"
            integer = dtype[0] in "iu"
            if not math.isfinite(v) and (target == "t" or integer or not math.isnan(v)):
                errors.append(f"{where}: {'empty' if not cell else repr(cell)} where a finite value is required")
            elif integer and v != int(v):
                errors.append(f"{where}: '{cell}' is not a whole number")
            elif integer and not np.iinfo(dtype).min <= v <= np.iinfo(dtype).max:
                info = np.iinfo(dtype)
                errors.append(f"{where}: {cell} does not fit {target} ({info.min}..{info.max})")
            elif abs(v * conversions.get(target, (1.0, 0.0))[0] + conversions.get(target, (1.0, 0.0))[1]) \
                    > MAX_ABS_VALUE:
                errors.append(f"{where}: {cell} is too large (at most {MAX_ABS_VALUE:g} in magnitude)")
            data[target][r] = v
        if len(errors) >= MAX_ERRORS:
            break
    if errors:
        more = " (stopped after the first errors)" if len(errors) >= MAX_ERRORS else ""
        raise CsvImportError("\n".join(errors) + more)
    if n == 0:
        raise CsvImportError(f"{path}: no data rows after the header")
    for target, (f, o) in conversions.items():
        if f != 1.0 or o != 0.0:
            data[target] = data[target] * f + o
    if "t" in cols:
        t = data["t"]
        bad = np.flatnonzero(np.diff(t) <= 0)
        if len(bad):
            k = int(bad[0]) + 1
            raise CsvImportError(f"{path}:{rows[k][0]}: column '{header[cols['t']]}' (t): time {t[k]:g} s is not "
                                 f"after {t[k - 1]:g} s on line {rows[k - 1][0]}; time must strictly increase")
    return data


def _fill(data: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for name, (dtype, _) in SAMPLE_COLUMNS.items():
        if name in data:
            out[name] = data[name].astype(dtype)
        elif dtype == "f8":
            out[name] = np.full(n, np.nan)
        elif name == "segment":
            out[name] = np.full(n, -1, dtype=dtype)
        elif name == "counter":
            out[name] = np.arange(n, dtype=dtype)
        else:
            out[name] = np.zeros(n, dtype=dtype)
    if "motor_moving" not in data and "turns" in data:
        tr = out["turns"]
        out["motor_moving"][1:] = (tr[1:] != tr[:-1]) & np.isfinite(tr[1:])
    if "adc_flags" not in data:
        out["adc_flags"] = (np.isnan(out["resistance"]) * 4 + np.isnan(out["length"]) * 8).astype("u1")
    return out


def _write_extras(path: Path, extras: dict[str, tuple[np.ndarray, str]]) -> None:
    """Add the extra channels as /samples columns (chunked, resizable, with ``units``)."""
    with h5py.File(path, "a") as f:
        g = f["samples"]
        for name, (values, unit) in extras.items():
            ds = g.create_dataset(name, data=values.astype("f8"), maxshape=(None,), chunks=(CHUNK,),
                                  fillvalue=np.nan)
            ds.attrs["units"] = unit


def import_csv(csv_path: str | Path, out_path: str | Path, mapping: dict[str, str] | None = None,
               units: dict[str, str] | None = None, meta: dict[str, str] | None = None,
               sample_period_s: float | None = None) -> Path:
    """Convert one CSV into a run file; see the module contract. Returns ``out_path``."""
    src, out = Path(csv_path), Path(out_path)
    if out.exists():
        raise CsvImportError(f"{out} already exists; choose another --out (existing runs are never replaced)")
    if sample_period_s is not None and not (math.isfinite(sample_period_s) and sample_period_s > 0):
        raise CsvImportError(f"--sample-period must be a positive number of seconds, got {sample_period_s}")
    header, header_line, _, rows = _read_header(src)
    cols = _resolve(src, header, header_line, mapping, timed=sample_period_s is None)
    units = dict(units or {})
    for key in units:
        if key not in cols and key not in header and key not in [_split_header(c)[0] for c in header]:
            raise CsvImportError(f"--units: '{key}' is neither a mapped column nor a CSV column")
    conversions, used, stored, unitless = {}, {}, {}, []
    for target, i in cols.items():
        name, head_unit = _split_header(header[i])
        unit = units.get(target, units.get(header[i], units.get(name, head_unit or _name_unit(target, name))))
        if not unit and _needs_unit(target):
            where = f"{src}:{header_line}: column '{header[i]}' ({target})"
            if target in CHANNELS:
                accepted = units_of(CHANNELS[target].dimension) + (["g", "kg"] if target == "load" else [])
                unitless.append(f"{where} has no unit: give it in the header ('{name} [{CHANNELS[target].unit}]') "
                                f"or with --units {target}=UNIT ({', '.join(accepted)})")
            else:
                unitless.append(f"{where}: extra column {target} has no unit; give one in the header "
                                f"('{name} [unit]') or with --units {target}=UNIT (use 1 for a pure number)")
            continue
        f, o, stored[target] = _conversion(target, unit, f"{src}:{header_line}: column '{header[i]}' ({target})")
        conversions[target] = (f, o)
        used[target] = unit or stored[target]
    if unitless:
        raise CsvImportError("\n".join(unitless))
    data = _parse(src, header, rows, cols, conversions)
    if sample_period_s is not None:
        data["t"] = np.arange(len(rows), dtype=float) * sample_period_s
    n = len(data["t"])
    extras = {k: (data.pop(k), stored[k]) for k in list(data) if k not in SAMPLE_COLUMNS}
    samples = _fill(data, n)
    t0, t1 = float(samples["t"][0]), float(samples["t"][-1])
    metadata = {**(meta or {}), "imported_from": str(src),
                "column_map": {k: header[i] for k, i in cols.items()}, "source_units": used}
    if extras:
        metadata["extra_columns"] = {k: u for k, (_, u) in extras.items()}
    if sample_period_s is not None:
        metadata["time"] = f"no time column: t = row index x {sample_period_s:g} s (rows in file order)"
    start = RunStart(plan_name=(meta or {}).get("name", src.stem), protocol_text="", protocol_path=None,
                     bench_text="", bench_path=None, backend="import", port=str(src), firmware="",
                     identity={"source": str(src)}, n_segments=0, estimated_duration_s=t1 - t0, metadata=metadata)
    tmp = out.with_name(out.name + ".importing")
    writer = RunWriter(tmp)
    try:
        writer.on_start(start)
        writer.on_samples(SampleBlock(samples))
        writer.on_stop(RunStop("success", f"imported from {src.name}", t1, n, 0, 0, 0.0))
        if extras:
            _write_extras(tmp, extras)
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return out
