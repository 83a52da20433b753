"""Read any file meeting the run-file contract (docs/run-format.md) into memory.

Contract: :func:`read_run` opens the file read-only and checks it against the
contract before anyone computes with it. It refuses, with a :class:`RunFileError`
whose one-line message names the file and exactly what is wrong:

* a path that is not a regular file (a FIFO would block, a device never end) or not HDF5;
* a root ``format`` attribute other than "tsa-bench/run";
* soft or external links where the contract has data (``/samples``, its columns,
  ``/segments``, ``/events``, ``/config``): a run file holds its data itself, and a
  link may point anywhere, including to a FIFO;
* a missing required column, a column that is not a 1-D numeric dataset, wrong units,
  more than :data:`MAX_SAMPLES` rows;
* columns of different lengths, except in a file whose ``exit_status`` is still
  "running" (a run killed mid-write): it keeps the rows every column has
  (``RunData.extra["truncated_rows"]`` says how many were cut);
* ``t`` not finite or not strictly increasing; any value of magnitude above
  :data:`MAX_ABS_VALUE` or infinite in a float column (NaN means "not measured" and is
  kept);
* ``/segments`` or ``/events`` that are not 1-D tables with the contract's fields of
  the right kinds, segment indices outside 0 to :data:`MAX_SEGMENT_INDEX` (or -1); in the
  coded layout of format 1.2, a ``kind_names`` attribute that is not a JSON list of texts,
  a /segment_texts that is not a 1-D text dataset, or a code naming no kind or text;
* damaged datasets or attributes that HDF5 cannot read;
* more data than the memory budget (:mod:`tsa_bench.store.budget`): the rows x bytes
  per value its datasets declare are added up before any data is read.

A file whose ``exit_status`` is still "running" (a run killed mid-write) is read as far
as it was written: each column and table up to its last chunk that was stored whole and
decodes (a kill inside a flush can leave the declared length ahead of the stored chunks,
or an index pointing past the file's recorded end); ``RunData.extra["truncated_rows"]``
says how many declared rows were cut. :func:`tsa_bench.store.recover.recover_run` then
finishes such a file from the run's journal.

It returns a :class:`~tsa_bench.rundata.RunData` holding every sample column (required and extra), the
segment and event tables normalised to one in-memory layout, :data:`SEGMENT_DTYPE`
with texts in every row, whichever layout the file has (None when absent; optional
fields missing in a file from another tool are filled: ``completed`` 1, ``cycle`` -1,
texts empty) and the configuration texts. Files written by other tools or imported
from CSV are welcome as long as they meet the contract.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tsa_bench.rundata import RunData
from tsa_bench.store.budget import OverBudget, check_budget
from tsa_bench.userfiles import DocumentError, check_regular_file
from tsa_bench.store.hdf5 import EVENT_DTYPE, FORMAT, SEGMENT_DTYPE, SEGMENT_ROW_DTYPE
from tsa_bench.store.probe import check_hdf5_terminates

#: Required sample columns and their units (docs/run-format.md).
REQUIRED_COLUMNS: dict[str, str] = {
    "t": "s", "turns": "turn", "length": "mm", "resistance": "ohm", "heater_voltage": "V", "load": "N",
    "segment": "1", "motor_moving": "1",
}
#: Most rows read (a 1 kHz run of 5.5 hours); more is refused rather than exhausting memory.
MAX_SAMPLES = 20_000_000
#: Largest magnitude accepted in a float column; beyond it (1e308, inf) arithmetic overflows.
MAX_ABS_VALUE = 1e15
#: Largest segment index accepted in /segments (the plan compiler allows 1,000,000 segments).
MAX_SEGMENT_INDEX = 10_000_000
#: Longest configuration text read (the YAML as run).
MAX_CONFIG_CHARS = 16 * 1024 * 1024
_SEGMENT_REQUIRED = {"index": "iu", "kind": "SOU", "t_start": "iuf", "t_end": "iuf"}
_SEGMENT_OPTIONAL = {"completed": ("iub", 1), "cycle": ("iu", -1), "source": ("SOU", b""), "params": ("SOU", b"")}
_EVENT_REQUIRED = {"t": "iuf", "kind": "SOU"}
_EVENT_OPTIONAL = {"detail": ("SOU", b"")}


class RunFileError(ValueError):
    """A file that is not a readable tsa-bench run file; the message says why."""


def _clean(text: str) -> str:
    """Printable on any terminal: lone surrogates replaced, newlines kept out of one-liners."""
    return text.encode("utf-8", "replace").decode("utf-8")


def _plain(value: Any) -> Any:
    if isinstance(value, bytes):
        return _clean(value.decode(errors="replace"))
    if isinstance(value, str):
        return _clean(value)
    if isinstance(value, np.generic):
        return _plain(value.item())
    if isinstance(value, np.ndarray):
        return _plain(value.reshape(-1)[0]) if value.size == 1 else [_plain(v) for v in value.reshape(-1)[:100]]
    return value


class _File:
    """Checked access to one open file; every problem raises RunFileError naming it."""

    def __init__(self, path: Path, f: h5py.File, running: bool = False) -> None:
        self.path, self.f = path, f
        self.running = running   # a killed run's file: read each dataset as far as it was stored

    def rows(self, ds: h5py.Dataset) -> int:
        """Rows of a 1-D dataset to read: all, or in a killed run's file the stored ones."""
        return stored_rows(ds) if self.running else int(ds.shape[0])

    def fail(self, message: str) -> RunFileError:
        return RunFileError(f"{self.path}: {message}")

    def member(self, name: str) -> h5py.Group | h5py.Dataset | None:
        """The object at ``name`` through hard links only; None when absent."""
        node: Any = self.f
        parts = [p for p in name.split("/") if p]
        for i, part in enumerate(parts):
            if not isinstance(node, h5py.Group) or part not in node:
                return None
            link = node.get(part, getlink=True)
            if not isinstance(link, h5py.HardLink):
                kind = "an external link" if isinstance(link, h5py.ExternalLink) else "a soft link"
                raise self.fail(f"/{'/'.join(parts[:i + 1])} is {kind}; a run file must hold its data itself")
            node = node[part]
        return node

    def attrs(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key in list(self.f.attrs):
            try:
                out[_plain(key)] = _plain(self.f.attrs[key])
            except (OSError, TypeError, ValueError, KeyError):
                out[_plain(key)] = "<unreadable attribute>"
        return out

    def text(self, name: str) -> str:
        ds = self.member(name)
        if ds is None:
            return ""
        if not isinstance(ds, h5py.Dataset) or ds.shape != () or ds.dtype.kind not in "SOU":
            raise self.fail(f"/{name} must be one text (the YAML as run), got {_describe(ds)}")
        value = ds[()]
        text = value.decode(errors="replace") if isinstance(value, bytes) else str(value)
        if len(text) > MAX_CONFIG_CHARS:
            raise self.fail(f"/{name} holds {len(text):,} characters, more than {MAX_CONFIG_CHARS:,}")
        return _clean(text)

    def table(self, name: str, dtype: np.dtype, required: dict[str, str],
              optional: dict[str, tuple[str, Any]]) -> np.ndarray | None:
        ds = self.member(name)
        if ds is None:
            return None
        fields = ds.dtype.names if isinstance(ds, h5py.Dataset) else None
        if not fields or ds.ndim != 1:
            raise self.fail(f"/{name} must be a 1-D table with fields {', '.join(required)}, got {_describe(ds)}")
        if ds.shape[0] > MAX_SAMPLES:
            raise self.fail(f"/{name} has {ds.shape[0]:,} rows, more than {MAX_SAMPLES:,}")
        for key, kinds in required.items():
            if key not in fields:
                raise self.fail(f"/{name} lacks the field '{key}' (fields: {', '.join(fields)})")
        for key, kinds in {**required, **{k: v[0] for k, v in optional.items()}}.items():
            if key in fields and ds.dtype[key].kind not in kinds:
                raise self.fail(f"/{name} field '{key}' has the wrong type ({ds.dtype[key]})")
        raw = ds[:self.rows(ds)]
        out = np.zeros(len(raw), dtype=dtype)
        for key in dtype.names:
            if key in fields:
                column = raw[key]
                if dtype[key].kind == "O":
                    out[key] = [v if isinstance(v, bytes) else str(v).encode("utf-8", "replace") for v in column]
                else:
                    if dtype[key].kind == "f":
                        _check_floats(self, column.astype(float), f"/{name} field '{key}'")
                    out[key] = column
            else:
                out[key] = optional[key][1]
        return out


def _describe(obj: Any) -> str:
    if isinstance(obj, h5py.Group):
        return "a group"
    if isinstance(obj, h5py.Dataset):
        return f"a dataset of shape {obj.shape} and type {obj.dtype}"
    return type(obj).__name__


def _check_floats(f: _File, x: np.ndarray, what: str) -> None:
    bad = np.flatnonzero(np.isinf(x) | (np.abs(np.nan_to_num(x)) > MAX_ABS_VALUE))
    if len(bad):
        i = int(bad[0])
        raise f.fail(f"{what} row {i} holds {x[i]!r}; values must be finite and at most {MAX_ABS_VALUE:g} "
                     f"in magnitude (NaN marks 'not measured') - {len(bad)} such value(s)")


def _samples(f: _File, exit_status: str) -> tuple[dict[str, np.ndarray], dict[str, str], dict[str, Any]]:
    group = f.member("samples")
    if not isinstance(group, h5py.Group):
        raise f.fail("no /samples group")
    missing = [name for name in REQUIRED_COLUMNS if name not in group]
    if missing:
        raise f.fail(f"/samples lacks the required column(s) {missing} (required: {', '.join(REQUIRED_COLUMNS)})")
    samples: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}
    declared: dict[str, int] = {}
    _check_memory(f, group)
    for name in list(group):
        ds = f.member(f"samples/{name}")
        shown = _clean(name)
        if not isinstance(ds, h5py.Dataset) or ds.ndim != 1 or ds.dtype.kind not in "biuf":
            raise f.fail(f"/samples/{shown} is not a 1-D numeric column ({_describe(ds)})")
        if ds.shape[0] > MAX_SAMPLES:
            raise f.fail(f"/samples/{shown} has {ds.shape[0]:,} rows, more than the {MAX_SAMPLES:,} read")
        unit = _plain(ds.attrs["units"]) if "units" in ds.attrs else ""
        units[shown] = unit if isinstance(unit, str) else str(unit)
        samples[shown] = ds[:f.rows(ds)]
        declared[shown] = int(ds.shape[0])
    for name, expected in REQUIRED_COLUMNS.items():
        if units[name] != expected:
            raise f.fail(f"/samples/{name} has units {units[name]!r}, the contract says {expected!r}")
    extra: dict[str, Any] = {}
    lengths = {name: len(a) for name, a in samples.items()}
    if len(set(lengths.values())) > 1:
        if exit_status != "running":
            raise f.fail(f"/samples columns differ in length: {lengths}")
        n = min(lengths.values())  # killed mid-write: keep the rows every column has
        samples = {name: a[:n] for name, a in samples.items()}
    if exit_status == "running" and declared and max(declared.values()) > len(samples["t"]):
        extra["truncated_rows"] = max(declared.values()) - len(samples["t"])
    for name, a in samples.items():
        if a.dtype.kind == "f":
            _check_floats(f, a, f"/samples/{name}")
    t = samples["t"].astype(float)
    if np.isnan(t).any():
        raise f.fail(f"/samples/t row {int(np.flatnonzero(np.isnan(t))[0])} is NaN; time must be known for every sample")
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        i = int(back[0]) + 1
        raise f.fail(f"/samples/t is not increasing: row {i} at {t[i]!r} s follows {t[i - 1]!r} s "
                     f"({len(back)} such step(s)); each sample must come after the one before")
    return samples, units, extra


def stored_rows(ds: h5py.Dataset) -> int:
    """Rows of a killed run's 1-D dataset that were stored and decode: up to the first chunk
    missing from its index (the declared length can be ahead of the chunks), then back to
    the last chunk that reads (an index written before the file's recorded end was)."""
    n = int(ds.shape[0])
    if n == 0:
        return 0
    if ds.chunks is None:
        return n if _reads(ds, 0, n) else 0
    c = int(ds.chunks[0])
    try:
        k = ds.id.get_num_chunks()
        starts = {int(ds.id.get_chunk_info(i).chunk_offset[0]) for i in range(min(k, n // c + 2))}
    except (OSError, RuntimeError, ValueError):
        return 0
    rows = 0
    while rows < n and rows in starts:
        rows += c
    rows = min(rows, n)
    while rows > 0:
        first = (rows - 1) // c * c
        if _reads(ds, first, rows):
            break
        rows = first
    return rows


def _reads(ds: h5py.Dataset, lo: int, hi: int) -> bool:
    try:
        ds[lo:hi]
        return True
    except (OSError, RuntimeError, ValueError, KeyError):
        return False


def _check_memory(f: _File, group: h5py.Group) -> None:
    """The budget check: rows x bytes per value of everything the reader will load."""
    needed = 0.0
    for name in list(group):
        ds = group.get(name, getlink=True)
        if isinstance(ds, h5py.HardLink):
            obj = group[name]
            if isinstance(obj, h5py.Dataset) and obj.shape is not None:
                needed += float(np.prod(obj.shape, dtype=float)) * obj.dtype.itemsize
    for name, per_row in (("segments", SEGMENT_DTYPE.itemsize), ("events", EVENT_DTYPE.itemsize),
                          ("segment_texts", 64)):
        ds = f.member(name)
        if isinstance(ds, h5py.Dataset) and ds.shape is not None:
            needed += float(np.prod(ds.shape, dtype=float)) * (ds.dtype.itemsize + per_row)
    check_budget(needed, str(f.path), "its samples and tables")


def _read(f: _File) -> RunData:
    attrs = f.attrs()
    if attrs.get("format") != FORMAT:
        raise f.fail(f"root attribute 'format' is {attrs.get('format')!r}, expected {FORMAT!r}")
    f.running = attrs.get("exit_status") == "running"
    samples, units, extra = _samples(f, str(attrs.get("exit_status", "")))
    segments = _coded_segments(f)
    if segments is None:
        segments = f.table("segments", SEGMENT_DTYPE, _SEGMENT_REQUIRED, _SEGMENT_OPTIONAL)
    if segments is not None and len(segments):
        idx = segments["index"]
        if idx.min() < -1 or idx.max() > MAX_SEGMENT_INDEX:
            raise f.fail(f"/segments index values must be -1..{MAX_SEGMENT_INDEX:,}, got {idx.min()}..{idx.max()}")
    events = f.table("events", EVENT_DTYPE, _EVENT_REQUIRED, _EVENT_OPTIONAL)
    return RunData(str(f.path), attrs, samples, units, segments, events,
                   f.text("config/protocol"), f.text("config/bench"), extra)


def _coded_segments(f: _File) -> np.ndarray | None:
    """/segments in the coded layout (format 1.2: numbers for kind, source and params)
    decoded to :data:`SEGMENT_DTYPE`; None when the file has the layout with texts in rows."""
    ds = f.member("segments")
    names = ds.dtype.names if isinstance(ds, h5py.Dataset) else None
    if not names or "kind" not in names or ds.dtype["kind"].kind not in "iu":
        return None
    if ds.ndim != 1:
        raise f.fail(f"/segments must be a 1-D table, got {_describe(ds)}")
    if ds.shape[0] > MAX_SAMPLES:
        raise f.fail(f"/segments has {ds.shape[0]:,} rows, more than {MAX_SAMPLES:,}")
    for key in SEGMENT_ROW_DTYPE.names:
        if key not in names:
            raise f.fail(f"/segments (coded layout) lacks the field '{key}' (fields: {', '.join(names)})")
        if ds.dtype[key].kind not in ("iuf" if key in ("t_start", "t_end") else "iu"):
            raise f.fail(f"/segments field '{key}' has the wrong type ({ds.dtype[key]})")
    try:
        kinds = json.loads(_plain(ds.attrs["kind_names"]))
    except (KeyError, TypeError, ValueError):
        kinds = None
    if not isinstance(kinds, list) or not all(isinstance(k, str) for k in kinds):
        raise f.fail("/segments has a numeric 'kind' but no attribute 'kind_names' (a JSON list of texts) naming it")
    texts_ds = f.member("segment_texts")
    if not isinstance(texts_ds, h5py.Dataset) or texts_ds.ndim != 1 or texts_ds.dtype.kind not in "SOU":
        raise f.fail(f"/segment_texts must be a 1-D text dataset (the texts /segments refers to), "
                     f"got {_describe(texts_ds) if texts_ds is not None else 'nothing'}")
    if texts_ds.shape[0] > MAX_SAMPLES:
        raise f.fail(f"/segment_texts has {texts_ds.shape[0]:,} rows, more than {MAX_SAMPLES:,}")
    raw = ds[:f.rows(ds)]
    texts = np.array([v if isinstance(v, bytes) else str(v).encode("utf-8", "replace")
                      for v in texts_ds[:f.rows(texts_ds)]] + [b""], dtype=object)
    out = np.zeros(len(raw), dtype=SEGMENT_DTYPE)
    for key, table, what in (("kind", np.array([k.encode() for k in kinds] + [b""], dtype=object), "kind_names"),
                             ("source", texts, "/segment_texts"), ("params", texts, "/segment_texts")):
        codes = raw[key].astype(np.int64)
        bad = np.flatnonzero((codes < 0) | (codes >= len(table) - 1))
        if len(bad) and f.running:   # a killed run: rows whose texts were not stored yet are cut
            raw, out, codes, bad = raw[:bad[0]], out[:bad[0]], codes[:bad[0]], bad[:0]
        if len(bad):
            i = int(bad[0])
            raise f.fail(f"/segments row {i} field '{key}' is {codes[i]}, but {what} has {len(table) - 1} entries "
                         f"({len(bad)} such row(s))")
        out[key] = table[codes]
    for key in ("t_start", "t_end"):
        _check_floats(f, raw[key].astype(float), f"/segments field '{key}'")
    for key in ("index", "t_start", "t_end", "completed", "cycle"):
        out[key] = raw[key]
    return out


def read_run(path: str | Path) -> RunData:
    """Load and check one run file (module contract); return it as a :class:`~tsa_bench.rundata.RunData`.

    Raises :class:`RunFileError` whose one-line message names the file and the problem; the
    file is opened read-only and never changed.
    """
    p = Path(path)
    try:
        check_regular_file(p, "run file")
    except DocumentError as exc:
        if "not found" in exc.message:
            raise RunFileError(f"{p}: no such file") from None
        raise RunFileError(str(exc)) from None
    why = check_hdf5_terminates(p)
    if why:
        raise RunFileError(f"{p}: {why}")
    try:
        handle = h5py.File(p, "r")
    except Exception as exc:  # h5py reports a bad file with many exception types
        raise RunFileError(f"{p}: not a readable HDF5 file ({_one_line(exc)})") from None
    try:
        with handle:
            return _read(_File(p, handle))
    except RunFileError:
        raise
    except OverBudget as exc:
        raise RunFileError(str(exc)) from None
    except (OSError, RuntimeError, KeyError, ValueError, TypeError, IndexError, AttributeError,
            MemoryError, OverflowError) as exc:
        raise RunFileError(f"{p}: damaged run file ({type(exc).__name__}: {_one_line(exc)})") from None


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:300]
