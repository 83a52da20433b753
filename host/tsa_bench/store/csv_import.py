"""`tsa-bench import`: a CSV from another rig -> a run file meeting the contract.

Contract of :func:`import_csv`:

* the first line that is not blank and does not start with ``#`` is the header; a header
  cell ``name [unit]`` or ``name (unit)`` gives the column's unit (so files written by
  ``tsa-bench export`` import without options); delimiter ``,`` (``;`` or tab when the
  header has no comma);
* ``mapping`` {contract column: CSV column} chooses the columns (CSV column by full header
  text or by name without the unit); without it, CSV columns named like contract
  columns are taken. ``t`` is required; targets must be sample columns of
  docs/run-format.md;
* ``units`` {contract or CSV column: unit} overrides header units; values are converted
  to contract units (:data:`UNITS`; a load given as a mass in g or kg becomes N with
  g0 = 9.80665 m/s^2). A column's unit comes from ``units``, else its header
  (``name [unit]``), else a unit at the end of its name (``time_ms``, ``len_cm``,
  ``R_kohm``). Every chosen column measured in a physical unit must have one: a column
  without is refused (all such columns named at once), never taken silently in the
  contract unit (a time in ms read as s). Dimensionless and count columns (segment,
  motor_moving, counter, raw counts, flags) need none;
* every cell must parse: an empty or ``nan`` cell is NaN (not measured) in float
  columns, but an error in ``t`` and in integer columns; integers must fit their
  column's type (``position_raw`` is int16: 40000 is refused, never wrapped); no value
  may be infinite or larger than the run reader accepts (1e15 in magnitude);
  ``t`` must strictly increase;
* columns not given are filled: float columns NaN (not measured / undeclared),
  ``segment`` -1 (no segments), ``motor_moving`` 1 where ``turns`` differs from the
  previous row (0 without turns), ``counter`` the row number 0, 1, ... (no device
  counter, so no gaps), ``step_position``, ``position_raw``, ``resistance_raw`` 0,
  ``adc_flags`` bit 2 where resistance is NaN and bit 3 where length is NaN;
* the run file is written by :class:`~tsa_bench.store.RunWriter` with ``backend``
  "import", ``exit_status`` "success", ``metadata`` = ``meta`` plus the source file,
  the column map and the units, empty ``/segments``, ``/events`` and ``/config`` texts;
  it is written to a temporary name and renamed, and an existing file is never replaced.

Every problem raises :class:`CsvImportError` naming the file, the line and the column;
up to 20 cell errors are reported at once.
"""

from __future__ import annotations

import csv
import math
import os
import re
from pathlib import Path

import numpy as np

from tsa_bench.documents import DocumentError, read_text_file
from tsa_bench.runner.documents import SAMPLE_COLUMNS, RunStart, RunStop, SampleBlock
from tsa_bench.store.hdf5 import RunWriter
from tsa_bench.store.reader import MAX_ABS_VALUE

G0 = 9.80665
#: contract column -> {accepted unit: factor to the contract unit}
UNITS: dict[str, dict[str, float]] = {
    "t": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0},
    "turns": {"turn": 1.0, "turns": 1.0, "rev": 1.0, "deg": 1 / 360, "rad": 1 / (2 * math.pi)},
    "length": {"mm": 1.0, "um": 1e-3, "cm": 10.0, "m": 1000.0, "in": 25.4},
    "resistance": {"ohm": 1.0, "mohm": 1e-3, "kohm": 1e3, "Ω": 1.0},
    "heater_voltage": {"V": 1.0, "mV": 1e-3},
    "load": {"N": 1.0, "mN": 1e-3, "g": G0 * 1e-3, "kg": G0},
    "step_position": {"step": 1.0},
    "position_raw": {"count": 1.0},
    "resistance_raw": {"count": 1.0},
}
_HEADER_UNIT = re.compile(r"^\s*(.*?)\s*[\[(]\s*([^\])]*?)\s*[\])]\s*$")
MAX_ERRORS = 20
MAX_CSV_BYTES = 1 << 30


class CsvImportError(ValueError):
    """A CSV that cannot become a run file; the message says where and what."""


def _split_header(cell: str) -> tuple[str, str]:
    m = _HEADER_UNIT.match(cell)
    return (m.group(1), m.group(2)) if m else (cell.strip(), "")


def _name_unit(target: str, name: str) -> str:
    """The unit at the end of a column name (``time_ms`` -> ``ms``), if it is one for ``target``."""
    if "_" not in name:
        return ""
    suffix = name.rsplit("_", 1)[1]
    accepted = list(UNITS.get(target, {})) + [SAMPLE_COLUMNS[target][1]]
    return next((u for u in accepted if suffix == u or suffix.lower() == u.lower()), "")


def _factor(target: str, unit: str, where: str) -> float:
    contract = SAMPLE_COLUMNS[target][1]
    if unit in ("", contract):
        return 1.0
    table = UNITS.get(target, {})
    for name, f in table.items():
        if unit == name or unit.lower() == name.lower():
            return f
    known = ", ".join(table) or contract
    raise CsvImportError(f"{where}: unit '{unit}' is not known for {target}; use one of: {known}")


def _read_header(path: Path) -> tuple[list[str], int, str, list[tuple[int, list[str]]]]:
    """(header cells, header line number, delimiter, [(line, cells) of data rows])."""
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
    delim = "," if "," in lines[i] else (";" if ";" in lines[i] else ("\t" if "\t" in lines[i] else ","))
    rows = []
    reader = csv.reader(lines[i:], delimiter=delim)
    try:
        header = [c.strip() for c in next(reader)]
        for cells in reader:
            if not cells or (len(cells) == 1 and not cells[0].strip()) or cells[0].lstrip().startswith("#"):
                continue
            rows.append((i + reader.line_num, cells))
    except csv.Error as exc:  # e.g. an unclosed quote swallowing the rest of the file
        raise CsvImportError(f"{path}:{i + reader.line_num}: not valid CSV ({exc})") from None
    return header, i + 1, delim, rows


def _resolve(path: Path, header: list[str], header_line: int, mapping: dict[str, str] | None) -> dict[str, int]:
    """{contract column: header index}."""
    names = [_split_header(c)[0] for c in header]
    if mapping is None:
        chosen = {n: i for i, n in enumerate(names) if n in SAMPLE_COLUMNS}
        if "t" not in chosen:
            raise CsvImportError(f"{path}:{header_line}: no column named 't' in the header {header}; "
                                 "give --map t=YOUR_TIME_COLUMN,...")
        return chosen
    out: dict[str, int] = {}
    for target, col in mapping.items():
        if target not in SAMPLE_COLUMNS:
            raise CsvImportError(f"--map: unknown target '{target}' (targets: {', '.join(SAMPLE_COLUMNS)})")
        idx = [i for i, c in enumerate(header) if c == col] or [i for i, n in enumerate(names) if n == col]
        if not idx:
            raise CsvImportError(f"{path}:{header_line}: column '{col}' (mapped to {target}) is not in the header; "
                                 f"columns are: {', '.join(header)}")
        out[target] = idx[0]
    if "t" not in out:
        raise CsvImportError("--map: 't' (time) must be mapped, e.g. --map t=time_s,...")
    return out


def _parse(path: Path, header: list[str], rows: list, cols: dict[str, int],
           factors: dict[str, float]) -> dict[str, np.ndarray]:
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
            dtype = SAMPLE_COLUMNS[target][0]
            integer = dtype[0] in "iu"
            if not math.isfinite(v) and (target == "t" or integer or not math.isnan(v)):
                errors.append(f"{where}: {'empty' if not cell else repr(cell)} where a finite value is required")
            elif integer and v != int(v):
                errors.append(f"{where}: '{cell}' is not a whole number")
            elif integer and not np.iinfo(dtype).min <= v <= np.iinfo(dtype).max:
                info = np.iinfo(dtype)
                errors.append(f"{where}: {cell} does not fit {target} ({info.min}..{info.max})")
            elif abs(v) * factors.get(target, 1.0) > MAX_ABS_VALUE:
                errors.append(f"{where}: {cell} is too large (at most {MAX_ABS_VALUE:g} in magnitude)")
            data[target][r] = v
        if len(errors) >= MAX_ERRORS:
            break
    if errors:
        more = " (stopped after the first errors)" if len(errors) >= MAX_ERRORS else ""
        raise CsvImportError("\n".join(errors) + more)
    if n == 0:
        raise CsvImportError(f"{path}: no data rows after the header")
    for target, f in factors.items():
        if f != 1.0:
            data[target] = data[target] * f
    t = data["t"]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if len(bad):
        k = int(bad[0]) + 1
        raise CsvImportError(f"{path}:{rows[k][0]}: column '{header[cols['t']]}' (t): time {t[k]:g} s is not after "
                             f"{t[k - 1]:g} s on line {rows[k - 1][0]}; time must strictly increase")
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


def import_csv(csv_path: str | Path, out_path: str | Path, mapping: dict[str, str] | None = None,
               units: dict[str, str] | None = None, meta: dict[str, str] | None = None) -> Path:
    """Convert one CSV into a run file; see the module contract. Returns ``out_path``."""
    src, out = Path(csv_path), Path(out_path)
    if out.exists():
        raise CsvImportError(f"{out} already exists; choose another --out (existing runs are never replaced)")
    header, header_line, _, rows = _read_header(src)
    cols = _resolve(src, header, header_line, mapping)
    units = dict(units or {})
    for key in units:
        if key not in cols and key not in header and key not in [_split_header(c)[0] for c in header]:
            raise CsvImportError(f"--units: '{key}' is neither a mapped column nor a CSV column")
    factors, used, unitless = {}, {}, []
    for target, i in cols.items():
        name, head_unit = _split_header(header[i])
        unit = units.get(target, units.get(header[i], units.get(name, head_unit or _name_unit(target, name))))
        contract = SAMPLE_COLUMNS[target][1]
        if not unit and contract not in ("1", "count", "step"):
            accepted = ", ".join(UNITS.get(target, {contract: 1.0}))
            unitless.append(f"{src}:{header_line}: column '{header[i]}' ({target}) has no unit: give it in the "
                            f"header ('{name} [{contract}]') or with --units {target}=UNIT ({accepted})")
            continue
        factors[target] = _factor(target, unit, f"{src}:{header_line}: column '{header[i]}' ({target})")
        used[target] = unit or contract
    if unitless:
        raise CsvImportError("\n".join(unitless))
    data = _parse(src, header, rows, cols, factors)
    n = len(data["t"])
    samples = _fill(data, n)
    t0, t1 = float(samples["t"][0]), float(samples["t"][-1])
    metadata = {**(meta or {}), "imported_from": str(src),
                "column_map": {k: header[i] for k, i in cols.items()}, "source_units": used}
    start = RunStart(plan_name=(meta or {}).get("name", src.stem), protocol_text="", protocol_path=None,
                     bench_text="", bench_path=None, backend="import", port=str(src), firmware="",
                     identity={"source": str(src)}, n_segments=0, estimated_duration_s=t1 - t0, metadata=metadata)
    tmp = out.with_name(out.name + ".importing")
    writer = RunWriter(tmp)
    try:
        writer.on_start(start)
        writer.on_samples(SampleBlock(samples))
        writer.on_stop(RunStop("success", f"imported from {src.name}", t1, n, 0, 0, 0.0))
        os.replace(tmp, out)
    finally:
        if tmp.exists():
            tmp.unlink()
    return out
