"""HDF5 run writer: the run-file contract of docs/run-format.md, written crash-safe.

Contract: :class:`RunWriter` is a :class:`~tsa_bench.rundocs.RunConsumer`.
``on_start`` creates the file exclusively (the name is reserved with O_EXCL, never through
a link; the HDF5 file is built under a random temporary name beside it and renamed onto
the reservation once its header is written) with ``exit_status`` "running"; samples,
segments and events are buffered in memory and written, then the file is flushed, at
every segment end, at least every ``flush_interval_s`` of wall time (default 1 s) and
whenever a chunk's worth of rows (``chunk_rows``) is waiting. Segment ends closer
together than ``min_flush_interval_s`` of wall time (default 0.5 s) share one flush: that
only happens on the simulated bench running thousands of times faster than real time.
``on_stop`` writes the rest, the exit status and reason, and closes the file.

Crash safety: HDF5 updates a file in place, so a process killed inside a flush can leave
an index pointing at a chunk that is not written yet, or at space the same flush reused.
So (1) a compressed chunk (sample columns, /segments) is written exactly once, whole:
during the run only whole chunks are written, the last partial chunk at ``on_stop``, so no
chunk is ever rewritten or moved and no space is freed and reused; the small uncompressed
tables (/events, /segment_texts) are rewritten in place at the same address. (2) With
``live=True`` the writer also keeps the run's journal ``RUN.h5.live``
(:mod:`tsa_bench.store.live`), and hands every sample block, segment record and event to
it BEFORE buffering it, so the journal holds everything the file holds and more; a run
killed at any instant (even inside a flush) is finished from it by
:func:`tsa_bench.store.recover.recover_killed_run` (``run --resume``, ``info``). The
journal is deleted once the file is closed, kept when it could not be. Memory stays flat
in run length: each dataset's chunk cache is bounded (:data:`CACHE_BYTES`) and
:meth:`RunWriter.summary` gives the closing statistics from running sums kept while
writing, not by reading the file back. The low-level h5py API is used for appends because
the high-level slicing costs ~1 ms per append of 13 columns, which a 12,000-segment
lifetime run cannot afford at every segment end.

Storage (:mod:`tsa_bench.store.space`): before creating the file and before every
flush the writer checks that the write fits with room to spare for closing the file;
when it does not, it raises :class:`~tsa_bench.store.space.StorageFull` ("disk full:
...") and the runner ends the run "failed"; the writer keeps what it could not write
in memory, and ``on_stop`` stores it if it still fits (else says how many samples were
not stored), writes the status and closes the file, which then reads like any other.
Every flush writes all columns of its rows or none, so columns never differ in length.
If the HDF5 library itself fails a write (another program filled the disk within
milliseconds of the check), the file cannot be closed any more: :attr:`RunWriter.broken`
says so and the writer leaves the file alone (the journal keeps the samples). Any other
error while closing is kept in :attr:`RunWriter.close_error`; the file is then marked
"failed" with that reason if it can still be written, and the journal is kept.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import time
from pathlib import Path

import h5py
import numpy as np
from h5py import h5s

import tsa_bench
from tsa_bench.rundocs import (
    SAMPLE_COLUMNS, EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord,
)
from tsa_bench.store.space import HEADER_BYTES, StorageFull, ensure_room, flush_bytes, journal_bytes

#: errno values that mean "no room": ENOSPC, EFBIG, EDQUOT
NO_ROOM_ERRNOS = {28, 27, 122}

FORMAT = "tsa-bench/run"
#: 1.1: sample columns gzip+shuffle compressed, ``t`` an HDF5 dimension scale of the others
#: (1.0 files, uncompressed and without scales, are read the same way).
#: 1.2: /segments coded (kind a number named by its ``kind_names`` attribute, source and
#: params numbers of rows of /segment_texts, each distinct text stored once) and compressed;
#: 1.0 and 1.1 files, with the texts in every row, are read the same way.
FORMAT_VERSION = "1.3"
#: Rows per chunk of a sample column.
CHUNK = 8192
#: gzip level of the sample columns (0: uncompressed); shuffle goes with it.
COMPRESSION_LEVEL = 4
#: Chunk cache of each dataset while writing (bytes): two chunks of 8-byte values, enough
#: for appends (the chunk being filled stays cached), and bounded whatever the run's length.
CACHE_BYTES = 2 * CHUNK * 8
STR = h5py.string_dtype("utf-8")
#: The segment table as readers get it (and as 1.0/1.1 files store it: texts in every row).
SEGMENT_DTYPE = np.dtype([("index", "i4"), ("kind", STR), ("t_start", "f8"), ("t_end", "f8"),
                          ("completed", "u1"), ("cycle", "i4"), ("source", STR), ("params", STR)])
#: The segment table as 1.2 files store it: ``kind`` indexes the ``kind_names`` attribute,
#: ``source`` and ``params`` index /segment_texts.
SEGMENT_ROW_DTYPE = np.dtype([("index", "i4"), ("kind", "u1"), ("t_start", "f8"), ("t_end", "f8"),
                              ("completed", "u1"), ("cycle", "i4"), ("source", "u4"), ("params", "u4")])
#: Rows per chunk of /segments, and the distinct texts a writer remembers (later texts are
#: stored again each time: memory stays bounded whatever the run).
SEGMENT_CHUNK = 4096
MAX_REMEMBERED_TEXTS = 65_536
SEGMENT_UNITS = {"t_start": "s", "t_end": "s", "cycle": "1 (-1 outside repeat blocks)"}
EVENT_DTYPE = np.dtype([("t", "f8"), ("kind", STR), ("detail", STR)])


class _Appender:
    """Appends to one resizable 1-D dataset through the low-level API (fast path).

    Caches the dataset id, dtype and length, since looking them up through h5py's
    high-level objects costs more than the write itself.
    """

    def __init__(self, ds: h5py.Dataset) -> None:
        self.id = ds.id
        self.dtype = ds.dtype
        self.n = ds.shape[0]

    def append(self, data: np.ndarray) -> None:
        k = len(data)
        if k == 0:
            return
        self.id.set_extent((self.n + k,))
        fspace = self.id.get_space()
        fspace.select_hyperslab((self.n,), (k,))
        self.id.write(h5s.create_simple((k,)), fspace, np.ascontiguousarray(data, dtype=self.dtype))
        self.n += k


class RunWriter:
    """Writes one run file; see the module contract.

    ``live``: keep the run's journal ``RUN.h5.live`` (what ``tsa-bench run`` does).
    ``reserved``: ``path`` is an empty file the caller created exclusively for this run
    (:func:`tsa_bench.outputs.reserve_free_name`); otherwise the writer creates it, and
    refuses a path that exists. ``created``: the ``created`` attribute (default: now; a
    run rebuilt from its journal keeps the original's).
    """

    def __init__(self, path: str | Path, flush_interval_s: float = 1.0, min_flush_interval_s: float = 0.5,
                 *, chunk_rows: int = CHUNK, compression_level: int = COMPRESSION_LEVEL, live: bool = False,
                 reserved: bool = False, created: str | None = None) -> None:
        if not 1 <= chunk_rows <= 1 << 20 or not 0 <= compression_level <= 9:
            raise ValueError(f"chunk_rows must be 1..{1 << 20} and compression_level 0..9, "
                             f"got {chunk_rows} and {compression_level}")
        self.path = Path(path)
        self.chunk_rows = chunk_rows
        self.compression_level = compression_level
        self.flush_interval_s = flush_interval_s
        self.min_flush_interval_s = min_flush_interval_s
        self.reserved = reserved
        self.created = created
        self.live = None
        if live:
            from tsa_bench.store.live import LiveSidecar
            self.live = LiveSidecar(self.path)
        self._segment_flush_due = False
        self.flushes = 0
        self._f: h5py.File | None = None
        self._pending: list[SampleBlock] = []
        self._pending_rows = 0
        self._segments: list[tuple] = []
        self._events: list[tuple] = []
        self._last_flush = time.monotonic()
        self._columns: dict[str, _Appender] = {}
        self._segment_rows: _Appender | None = None
        self._text_rows: _Appender | None = None
        from tsa_bench.plan.actions import KINDS
        self._kinds: dict[str, int] = {k: i for i, k in enumerate(KINDS)}   # kind -> its code
        self._kinds_changed = False
        self._text_ids: dict[str, int] = {}   # distinct source/params text -> row of /segment_texts
        self._texts: list[str] = []           # new texts waiting for the next flush
        self._n_texts = 0
        self._event_rows: _Appender | None = None
        self._closing = False                 # on_stop: the last partial chunks are written too
        self.full: str | None = None    # why nothing more is written ("disk full: ...")
        self.broken: str | None = None  # the HDF5 library failed a write: the file cannot be closed
        self.close_error: str | None = None  # an error while closing (the file is marked failed if it can be)
        self.samples_not_stored = 0
        from tsa_bench.store.inspect import RunningStats  # (inspect reads files through the reader, which imports us)
        #: statistics of what is stored, kept as it is written (:meth:`summary`)
        self.stats = RunningStats({name: units for name, (_, units) in SAMPLE_COLUMNS.items()})

    def on_start(self, start: RunStart) -> None:
        from tsa_bench.outputs import create_new, temp_name

        self.path.parent.mkdir(parents=True, exist_ok=True)
        ensure_room(self.path, HEADER_BYTES, "creating the run file")
        if not self.reserved:
            try:
                os.close(create_new(self.path))
            except OSError as exc:
                if exc.errno in NO_ROOM_ERRNOS:
                    raise StorageFull(f"disk full: cannot create {self.path}: {exc.strerror}") from None
                raise
        created = self.created or dt.datetime.now(dt.timezone.utc).astimezone().isoformat(timespec="seconds")
        if self.live is not None:   # the journal first: a kill from here on loses nothing
            self.live.on_start(start, created)
        tmp = temp_name(self.path, "writing")
        # Default (earliest) format on purpose: with libver="latest" the superblock marks the
        # file open-for-write, and a killed run would then not open without h5clear.
        try:
            f = self._f = h5py.File(tmp, "x", rdcc_nbytes=max(CACHE_BYTES, 2 * self.chunk_rows * 8))
        except OSError as exc:
            self._abandon(None)
            if exc.errno in NO_ROOM_ERRNOS:
                raise StorageFull(f"disk full: cannot create {self.path}: {exc.strerror}") from None
            raise
        try:
            self._header(f, start, created)
            self.flush()
            os.replace(tmp, self.path)   # onto the reservation: the run file appears with its header
        except BaseException:
            self._abandon(tmp)
            raise

    def _abandon(self, tmp: Path | None) -> None:
        """A start that failed: nothing was recorded; remove what this writer created."""
        if self._f is not None:
            try:
                self._f.close()
            except Exception:   # a file HDF5 could not write may not close either
                pass
            self._f = None
        for path in (tmp, None if self.reserved else self.path):
            if path is not None:
                try:
                    if path.stat().st_size == 0 or path == tmp:
                        path.unlink()
                except OSError:
                    pass
        if self.live is not None and self.live.active:
            self.live.on_stop(RunStop("failed", "the run file could not be created", 0.0, 0, 0, 0, 0.0), remove=True)

    def _header(self, f: h5py.File, start: RunStart, created: str) -> None:
        """Root attributes, /config, and the empty datasets of the contract."""
        a = f.attrs
        a["format"] = FORMAT
        a["format_version"] = FORMAT_VERSION
        a["created"] = created
        a["backend"] = start.backend
        a["firmware"] = start.firmware
        a["exit_status"] = "running"
        a["reason"] = ""
        a["software"] = f"tsa-bench {tsa_bench.__version__}"
        a["plan_name"] = start.plan_name
        a["port"] = start.port
        a["estimated_duration_s"] = start.estimated_duration_s
        a["n_segments"] = start.n_segments
        a["device_identity"] = json.dumps(start.identity)
        a["metadata"] = json.dumps(start.metadata, default=str)
        for key, value in start.extra_attrs.items():
            a[key] = value
        cfg = f.create_group("config")
        cfg.create_dataset("protocol", data=start.protocol_text, dtype=STR)
        cfg["protocol"].attrs["path"] = start.protocol_path or ""
        cfg.create_dataset("bench", data=start.bench_text, dtype=STR)
        cfg["bench"].attrs["path"] = start.bench_path or ""
        g = f.create_group("samples")
        packed = {"compression": "gzip", "compression_opts": self.compression_level, "shuffle": True} \
            if self.compression_level else {}
        columns = {**{k: (d, u, {}) for k, (d, u) in SAMPLE_COLUMNS.items()}, **start.extra_columns}
        for name, (dtype, units, attrs) in columns.items():
            fill = np.nan if dtype == "f8" else 0
            ds = g.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(self.chunk_rows,), dtype=dtype,
                                  fillvalue=fill, **packed)
            ds.attrs["units"] = units
            for key, value in attrs.items():
                ds.attrs[key] = value
        g["t"].make_scale("t")  # xarray, netCDF and HDFView see time as the dimension of every column
        for name in columns:
            if name != "t":
                g[name].dims[0].attach_scale(g["t"])
        seg = f.create_dataset("segments", shape=(0,), maxshape=(None,), chunks=(SEGMENT_CHUNK,),
                               dtype=SEGMENT_ROW_DTYPE, **packed)
        for field, units in SEGMENT_UNITS.items():
            seg.attrs[f"{field}_units"] = units
        seg.attrs["kind_names"] = json.dumps(list(self._kinds))
        seg.attrs["texts"] = "/segment_texts"   # source and params are row numbers there
        texts = f.create_dataset("segment_texts", shape=(0,), maxshape=(None,), chunks=(256,), dtype=STR)
        self._text_rows = _Appender(texts)
        ev = f.create_dataset("events", shape=(0,), maxshape=(None,), chunks=(256,), dtype=EVENT_DTYPE)
        ev.attrs["t_units"] = "s"
        self._columns = {name: _Appender(g[name]) for name in columns}
        self._segment_rows, self._event_rows = _Appender(seg), _Appender(ev)

    def on_samples(self, block: SampleBlock) -> None:
        self._pending.append(block)
        self._pending_rows += len(block)
        if self.live is not None and self.live.active and not self.full:
            try:   # the journal must not take the room the file needs for what it holds, nor outgrow its own
                more = len(block) * self.live.dtype.itemsize
                ensure_room(self.path, journal_bytes(len(block), self.live.dtype.itemsize, self._pending_rows,
                                                     len(self._segments), len(self._events)),
                            f"journaling {len(block)} more samples")
                ensure_room(self.live.path, more, f"journaling {len(block)} more samples")   # (a file size limit)
            except StorageFull as exc:
                self.full = str(exc)
                raise
            self.live.on_samples(block)
        self._maybe_flush()

    def on_segment(self, s: SegmentRecord) -> None:
        if self.live is not None:
            self.live.on_segment(s)
        code = self._kinds.get(s.kind)
        if code is None:
            if len(self._kinds) > 255:
                raise ValueError(f"more than 256 segment kinds (new: {s.kind!r})")
            code = self._kinds[s.kind] = len(self._kinds)
            self._kinds_changed = True
        self._segments.append((s.index, code, s.t_start, s.t_end, int(s.completed),
                               -1 if s.cycle is None else s.cycle, self._text(s.source), self._text(json.dumps(s.params))))
        self._segment_flush_due = True
        self._maybe_flush()

    def _text(self, text: str) -> int:
        """The /segment_texts row holding ``text`` (a new row for a text not seen before)."""
        row = self._text_ids.get(text)
        if row is None:
            row = self._n_texts
            self._n_texts += 1
            self._texts.append(text)
            if len(self._text_ids) < MAX_REMEMBERED_TEXTS:
                self._text_ids[text] = row
        return row

    def on_event(self, e: EventRecord) -> None:
        if self.live is not None:
            self.live.on_event(e)
        self._events.append((e.t, e.kind, e.detail))
        self._maybe_flush()

    def on_stop(self, stop: RunStop) -> None:
        closed = False
        try:
            closed = self._close(stop)
        except Exception as exc:   # a bug or an unexpected library error: never leave "running" silently
            self.close_error = f"{type(exc).__name__}: {exc}"
            closed = self._close_failed(stop)
        finally:
            if self.live is not None:
                self.live.on_stop(stop, remove=closed)

    def _close(self, stop: RunStop) -> bool:
        """Write the rest and close (module contract); whether the file was closed."""
        if self._f is None or self.broken:
            return False
        self._closing = True
        status, reason = stop.exit_status, stop.reason
        if not self.full:
            try:
                self.flush()
            except StorageFull:
                if self.broken:
                    return False
        if self.full:
            if status == "success":  # the disk filled while the run closed: its data is incomplete
                status, reason = "failed", self.full
            elif "disk full" not in reason:
                reason += f"; then {self.full}"
            try:
                self._write_pending()
            except StorageFull:
                if self.broken:
                    return False
                # no room for the samples: keep the segments and events (the STOP among them)
                self.samples_not_stored = sum(len(b) for b in self._pending)
                self._pending, self._pending_rows = [], 0
                reason += f"; {self.samples_not_stored} samples received after that were not stored"
                try:
                    self._write_pending()
                except StorageFull:
                    if self.broken:
                        return False
                    self._segments, self._events = [], []
                    reason += " (nor the last segments and events)"
        self._finish(status, reason, stop)
        return True

    def _finish(self, status: str, reason: str, stop: RunStop) -> None:
        a = self._f.attrs
        a["exit_status"] = status
        a["reason"] = reason
        a["samples_lost"] = stop.samples_lost
        if self.samples_not_stored:
            a["samples_not_stored"] = self.samples_not_stored
        a["duration_s"] = stop.t_end
        a["wall_time_s"] = stop.wall_time_s
        for key, value in stop.attrs.items():
            a[key] = value
        self._f.close()
        self._f = None

    def _close_failed(self, stop: RunStop) -> bool:
        """After an error while closing: mark the file failed with the reason, if it can be."""
        if self._f is None or self.broken:
            return False
        try:
            if self.live is not None and self.live.active:   # recovery may finish the file from it
                self._f.attrs["journal_kept"] = self.live.path.name
            self._finish("failed", f"host error while closing the run file: {self.close_error}; "
                         f"the run itself ended {stop.exit_status} ({stop.reason})", stop)
            return False   # the file lacks what could not be written: the journal keeps it
        except Exception:
            return False

    def _maybe_flush(self) -> None:
        since = time.monotonic() - self._last_flush
        if since >= self.flush_interval_s or (self._segment_flush_due and since >= self.min_flush_interval_s) \
                or self._pending_rows >= self.chunk_rows:
            self.flush()

    def flush(self) -> None:
        """Write everything buffered that may be written now (module contract: whole chunks
        of the compressed datasets during the run) and flush the file to the operating system.

        Raises StorageFull (once) when it does not fit; after that it writes nothing more.
        """
        if self._f is None or self.full or self.broken:
            return
        try:
            self._write_pending()
        except StorageFull as exc:
            self.full = str(exc)
            raise
        self._segment_flush_due = False
        self.flushes += 1
        self._last_flush = time.monotonic()

    def _due(self, rows: int, chunk: int) -> int:
        """How many of ``rows`` waiting rows to write now: all when closing or uncompressed,
        else whole chunks only (a compressed chunk is written once)."""
        if self._closing or not self.compression_level:
            return rows
        return rows - rows % chunk

    def _take_samples(self, rows: int) -> dict[str, np.ndarray]:
        """The first ``rows`` pending samples as columns; the rest stay pending."""
        if rows == 0:
            return {}
        blocks = self._pending
        columns = {name: (blocks[0].columns[name] if len(blocks) == 1 else
                          np.concatenate([b.columns[name] for b in blocks])) for name in self._columns}
        if rows < self._pending_rows:
            self._pending = [SampleBlock({name: c[rows:] for name, c in columns.items()})]
            columns = {name: c[:rows] for name, c in columns.items()}
        else:
            self._pending = []
        return columns

    def _write_pending(self) -> None:
        """Check room, then append every row due (all columns) and flush; StorageFull if no room."""
        f = self._f
        assert f is not None
        rows = self._due(self._pending_rows, self.chunk_rows)
        n_segments = self._due(len(self._segments), SEGMENT_CHUNK)
        ensure_room(self.path, flush_bytes(rows, n_segments, len(self._events)), f"storing {rows} more samples")
        pending = self._pending
        columns = self._take_samples(rows)
        segments = np.array(self._segments[:n_segments], dtype=SEGMENT_ROW_DTYPE) if n_segments else None
        texts = np.array(self._texts, dtype=object) if self._texts else None
        events = np.array(self._events, dtype=EVENT_DTYPE) if self._events else None
        try:
            for name, column in self._columns.items():
                if columns:
                    column.append(columns[name])
            if texts is not None:
                self._text_rows.append(texts)
            if self._kinds_changed:
                f["segments"].attrs["kind_names"] = json.dumps(list(self._kinds))
                self._kinds_changed = False
            if segments is not None:
                self._segment_rows.append(segments)
            if events is not None:
                self._event_rows.append(events)
            f.flush()
        except (OSError, RuntimeError) as exc:
            self._pending = pending
            self.broken = f"the HDF5 library failed to write {self.path} ({exc}); the file cannot be closed"
            raise StorageFull(f"disk full or write error: {self.broken}") from None
        self._pending_rows -= rows
        self._segments = self._segments[n_segments:]
        self._events, self._texts = [], []
        if columns:
            self.stats.add_samples(columns)
        if segments is not None:
            names = list(self._kinds)
            self.stats.add_segments(segments, names)
        if events is not None:
            self.stats.add_events(events)

    @property
    def column_dtypes(self) -> dict[str, np.dtype]:
        """The sample columns of the file being written and their types (after ``on_start``)."""
        return {name: column.dtype for name, column in self._columns.items()}

    def discard(self) -> None:
        """Give up a file that was not closed: close it as it is and remove it (used for a
        temporary file, such as a run being rebuilt; never for a recording)."""
        if self._f is None:
            return
        name = Path(self._f.filename)
        try:
            self._f.close()
        except Exception:   # a file HDF5 failed to write may not close either
            pass
        self._f = None
        for path in {name, self.path}:
            try:
                path.unlink()
            except OSError:
                pass

    def summary(self) -> "RunInfo":  # noqa: F821 (tsa_bench.store.inspect.RunInfo)
        """What :func:`~tsa_bench.store.inspect.inspect_run` says about the closed file,
        from the statistics kept while writing (only the attributes are read back)."""
        from tsa_bench.store.reader import _File
        with h5py.File(self.path, "r") as f:
            attrs = _File(self.path, f).attrs()
        return self.stats.info(str(self.path), attrs)
