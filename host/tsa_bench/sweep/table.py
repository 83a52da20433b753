"""The results table of a study: tidy (one row per point), Parquet, written as points finish.

Layout of a study's results folder (``--out``, default ``sweeps/<study>/``)::

    parts/part-<time>-<id>.parquet  rows as they finished, in batches (never rewritten)
    results.parquet                 every row, by point index (rewritten when a sweep ends)

Columns: ``point`` (index in the study), ``key`` (hash of the point's configuration and
the software version), ``status`` (``done`` / ``failed``), ``error`` (the failure's
message), ``work_s`` (s the point's own work took on its worker), ``worker``,
``finished`` (UTC, ISO 8601), ``version``, ``config`` (the point's configuration as
JSON), then one column per varied parameter, named by its path (``protocol.cycles``),
then the figures of merit. Each column's unit is in its field metadata (``units``,
``"1"`` for counts, flags and text) and, where it has one, in its name.

Contract: :meth:`ResultsTable.add` buffers a row and :meth:`flush` writes the buffer
as a new part atomically (a temporary file created exclusively beside it, removed if the
write is interrupted, then renamed), so a killed sweep leaves whole parts only and loses at
most the rows of the last ``flush_s`` seconds;
:meth:`finished_keys` reads the keys of every part, which is how a re-run skips the
points already computed. Unreadable parts (an interrupted write of another tool) are
reported, never silently dropped.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import time
import uuid
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from tsa_bench import __version__
from tsa_bench.outputs import open_new, writing

#: unit of a column by the end of its name (the longest match wins)
_SUFFIX_UNITS = {"_s": "s", "_min": "min", "_mm": "mm", "_ohm": "ohm", "_ohm_per_h": "ohm/h", "_percent": "%",
                 "_g": "g", "_turns": "turn", "_ohm_per_turn": "ohm/turn", "_V": "V", "_N": "N", "_C": "degC"}


def unit_of(column: str) -> str:
    """The unit of a column: a plant parameter's documented unit, else the unit its name
    states (``"1"`` when it states none)."""
    parts = column.split(".")
    if len(parts) == 4 and parts[:2] == ["plant", "effects"]:
        from tsa_bench.sim.effects.base import effect_class

        cls = effect_class(parts[2])
        fields = {f.name: f for f in dataclasses.fields(cls.Params)} if cls is not None else {}
        if parts[3] in fields:
            return str(fields[parts[3]].metadata.get("units", "1"))
    name = "_" + column.replace(".", "_")
    best = ""
    for suffix in _SUFFIX_UNITS:
        if name.endswith(suffix) and len(suffix) > len(best):
            best = suffix
    return _SUFFIX_UNITS[best] if best else "1"


class ResultsTableError(Exception):
    """A results folder that cannot be read (names the file)."""


def _with_units(table: pa.Table) -> pa.Table:
    fields = [f.with_metadata({"units": unit_of(f.name)}) for f in table.schema]
    return pa.Table.from_arrays(table.columns, schema=pa.schema(fields))


class ResultsTable:
    """One study's results folder (module contract)."""

    def __init__(self, folder: str | Path, flush_s: float = 2.0, flush_rows: int = 200) -> None:
        self.folder = Path(folder)
        self.parts = self.folder / "parts"
        self.flush_s = flush_s
        self.flush_rows = flush_rows
        self._rows: list[dict[str, Any]] = []
        self._last = time.monotonic()
        self._written = 0

    # -- reading ---------------------------------------------------------------------
    def part_files(self) -> list[Path]:
        return sorted(self.parts.glob("part-*.parquet")) if self.parts.is_dir() else []

    def read(self) -> pa.Table | None:
        """Every row written so far (None when there is none); the latest row of a key wins."""
        tables = []
        for p in self.part_files():
            try:
                tables.append(pq.read_table(p))
            except Exception as exc:
                raise ResultsTableError(f"{p}: not a readable Parquet part ({exc}); move it away and re-run "
                                        "(its points run again)") from None
        if not tables:
            return None
        table = pa.concat_tables(tables, promote_options="permissive")
        keys = table.column("key").to_pylist()
        last = {k: i for i, k in enumerate(keys)}
        keep = sorted(last.values(), key=lambda i: table.column("point")[i].as_py())
        return _with_units(table.take(keep))

    def finished_keys(self, include_failed: bool = True) -> set[str]:
        """Keys of the points with a row (``include_failed=False``: of the points that succeeded)."""
        table = self.read()
        if table is None:
            return set()
        keys, status = table.column("key").to_pylist(), table.column("status").to_pylist()
        return {k for k, s in zip(keys, status) if include_failed or s == "done"}

    # -- writing ---------------------------------------------------------------------
    def add(self, point: int, config: dict[str, Any], varied: dict[str, Any], result: dict[str, Any],
            keep: list[str] | None = None) -> None:
        """Buffer the row of a finished point (``result`` as :func:`tsa_bench.sweep.points.run_point`
        returns it); flush when the buffer is old or large enough."""
        figures = result.get("figures") or {}
        if keep is not None:
            figures = {k: v for k, v in figures.items() if k in keep}
        row = {"point": point, "key": result["key"], "status": result["status"], "error": result.get("error", ""),
               "work_s": float(result.get("work_s", float("nan"))), "worker": result.get("worker", ""),
               "finished": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"), "version": __version__,
               "config": json.dumps(config, sort_keys=True)}
        row.update(varied)
        row.update(figures)
        self._rows.append(row)
        if len(self._rows) >= self.flush_rows or time.monotonic() - self._last >= self.flush_s:
            self.flush()

    def flush(self) -> Path | None:
        """Write the buffered rows as a new part (atomic); the part's path, or None when nothing was buffered."""
        self._last = time.monotonic()
        if not self._rows:
            return None
        self.parts.mkdir(parents=True, exist_ok=True)
        columns: dict[str, list[Any]] = {}
        for r in self._rows:
            for k in r:
                columns.setdefault(k, [])
        for k in columns:
            columns[k] = [r.get(k) for r in self._rows]
        table = _with_units(pa.table({k: _column(v) for k, v in columns.items()}))
        stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y%m%dT%H%M%S")
        self._written += 1
        path = self.parts / f"part-{stamp}-{uuid.uuid4().hex[:12]}-{self._written:05d}.parquet"  # never reused
        with writing(path, tag="tmp") as tmp, open_new(tmp) as f:
            pq.write_table(table, f)
        self._rows = []
        return path

    def consolidate(self, index: dict[str, int] | None = None) -> Path | None:
        """Write ``results.parquet`` (every row, by point); its path, or None when there are no rows.

        ``index`` (key -> point index of the study as it is now) keeps only the study's
        points and numbers them as the study does (a study file edited since an earlier
        sweep keeps its old rows in the parts)."""
        table = self.read()
        if table is None:
            return None
        if index is not None:
            keys = table.column("key").to_pylist()
            rows = sorted((index[k], i) for i, k in enumerate(keys) if k in index)
            table = table.take([i for _, i in rows])
            table = table.set_column(table.schema.get_field_index("point"), table.schema.field("point"),
                                     pa.array([p for p, _ in rows], type=table.schema.field("point").type))
        path = self.folder / "results.parquet"
        with writing(path, force=True, tag="tmp") as tmp, open_new(tmp) as f:   # rebuilt from the parts each time
            pq.write_table(table, f)
        return path


def _column(values: list[Any]) -> pa.Array:
    """An Arrow column; numbers mixed with text (a figure that is text on some points) become text."""
    try:
        return pa.array(values)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array([None if v is None else str(v) for v in values])
