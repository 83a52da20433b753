"""`tsa-bench export --csv`: a run's samples, segments and events as CSV files.

Contract: :func:`export_csv` reads the run with :func:`~tsa_bench.store.read_run` and
writes ``<stem>.samples.csv``, ``<stem>.segments.csv`` and ``<stem>.events.csv`` (the
last two only when the run has those tables) into ``out_dir`` (default: next to the run
file). Each is written under a random temporary name, flushed to the disk, then given its
name (:mod:`tsa_bench.outputs`): a full disk leaves no truncated CSV, only the error; an
existing file (an earlier export) is refused unless replacing is allowed (``--force``),
and a link planted at a name is never written through. Headers carry units as
``name [unit]`` (e.g. ``t [s]``, ``length [mm]``); floats are written in the shortest
form that reads back to the same float64 (NaN as ``nan``), so
``tsa-bench import`` of the samples file, which understands these headers without a
``--map``, gives back the same samples. Comma-separated, UTF-8, one header line.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from tsa_bench.outputs import allow_replace, open_output, refuse_existing
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.store.hdf5 import SEGMENT_UNITS
from tsa_bench.store.reader import read_run


def _text(a: np.ndarray) -> np.ndarray:
    """Column as strings: shortest round-trip repr for floats, bytes decoded."""
    if a.dtype.kind == "f":
        return np.asarray([repr(x) for x in a.astype(float).tolist()], dtype=object)
    if a.dtype.kind in "SO":
        return np.asarray([x.decode("utf-8", "replace") if isinstance(x, bytes) else str(x) for x in a], dtype=object)
    return a.astype(str)


def _write(path: Path, header: list[str], columns: list[np.ndarray]) -> Path:
    with open_output(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(zip(*[_text(c) for c in columns]) if columns and len(columns[0]) else [])
    return path


def export_csv(run_path: str | Path, out_dir: str | Path | None = None) -> list[Path]:
    """Write the CSV files of one run; return their paths. See the module contract."""
    run = read_run(run_path)
    p = Path(run_path)
    out = Path(out_dir) if out_dir is not None else p.parent
    out.mkdir(parents=True, exist_ok=True)
    tables = [(label, table) for table, label in ((run.segments, "segments"), (run.events, "events"))
              if table is not None and table.dtype.names is not None]
    for name in ["samples"] + [label for label, _ in tables]:   # refused before anything is written
        refuse_existing(out / f"{p.stem}.{name}.csv", allow_replace())
    names = [n for n in SAMPLE_COLUMNS if n in run.samples] + [n for n in run.samples if n not in SAMPLE_COLUMNS]
    header = [f"{n} [{run.units[n]}]" if run.units.get(n) else n for n in names]
    paths = [_write(out / f"{p.stem}.samples.csv", header, [run.samples[n] for n in names])]
    for table, label, units in ((run.segments, "segments", SEGMENT_UNITS), (run.events, "events", {"t": "s"})):
        if table is None or table.dtype.names is None:
            continue
        fields = list(table.dtype.names)
        head = [f"{n} [s]" if units.get(n) == "s" else n for n in fields]
        paths.append(_write(out / f"{p.stem}.{label}.csv", head, [table[n] for n in fields]))
    return paths
