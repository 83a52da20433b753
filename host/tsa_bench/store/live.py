"""Live sidecar: the latest samples of a run being recorded, safe to read concurrently.

Why a sidecar: HDF5 is not safe for a reader while another process writes the file
unless both use SWMR, which needs the newest file format, which we avoid on purpose
(a killed run would then not open without h5clear; docs/run-format.md). So the run
file stays the only record, and :class:`LiveSidecar`, a run consumer placed AFTER the
:class:`~tsa_bench.store.RunWriter`, also appends every sample to ``RUN.h5.live``:

* the file appears atomically (header written to ``RUN.h5.live.tmp``, then renamed),
  so a reader never sees a partial header;
* header: 8 bytes ``TSALIVE1``, u32 little-endian length, that many bytes of UTF-8 JSON
  (``version``, ``record_dtype``, ``record_size``, ``run_file``, ``plan_name``,
  ``n_segments``, ``estimated_duration_s``, ``pid``, ``host``, ``started``);
* then fixed-size little-endian records (:data:`RECORD`: every sample column of the run
  file, raw counts included, followed by the run's extra numeric columns such as a
  ``track_length`` controller's estimate, target and state, in the order of
  ``RunStart.extra_columns``; the header's ``record_dtype`` gives the layout), so a killed
  run's last samples can be recovered from it
  by ``tsa-bench run --resume``), append-only, flushed to the
  operating system at least every ``flush_interval_s`` (0.1 s), at segment ends when
  samples were written since the last flush (the runner hands samples over in blocks, at
  least every 0.5 s, each followed by the segment records that came after it) and at the
  end; a
  reader takes only whole records below the size it sees;
* ``kind`` 0 is a sample; the last record has ``kind`` 1 success, 2 aborted or 3 failed,
  with ``t`` the run's end time and ``counter`` the number of samples. It is written
  after the run file is closed, so a reader that sees it may open the run file; then
  the sidecar is deleted (a reader holding it open still reads it to the end).

A killed run leaves the sidecar without an end record; its ``pid`` then no longer
exists. Nothing here can lose recorded data: the sidecar never touches the run file,
and a sidecar that cannot be written is switched off with one warning on stderr (a
consumer must not raise, or the run would end as failed).
"""

from __future__ import annotations

import datetime as dt
import json
import os
import socket
import stat
import struct
import sys
import time
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from tsa_bench.userfiles import DocumentError, parse_json
from tsa_bench.rundocs import EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord

MAGIC = b"TSALIVE1"
VERSION = 3
#: Versions this reader understands: 2 had exactly :data:`RECORD`; 3 may append extra columns.
READ_VERSIONS = (2, 3)
RECORD = np.dtype([("kind", "u1"), ("motor_moving", "u1"), ("adc_flags", "u1"),
                   ("segment", "<i4"), ("counter", "<u4"), ("step_position", "<i4"), ("resistance_raw", "<i4"),
                   ("position_raw", "<i2"), ("t", "<f8"), ("turns", "<f8"), ("length", "<f8"), ("resistance", "<f8"),
                   ("heater_voltage", "<f8"), ("load", "<f8")])
#: Record fields that are sample columns of the run file.
SAMPLE_FIELDS = RECORD.names[1:]
#: Numeric types an extra column may have in a sidecar record (little-endian or byte-sized).
EXTRA_TYPES = frozenset({"|u1", "|i1", "<u2", "<i2", "<u4", "<i4", "<u8", "<i8", "<f4", "<f8"})
MAX_EXTRA_COLUMNS = 64
END_KINDS = {"success": 1, "aborted": 2, "failed": 3}
END_NAMES = {v: k for k, v in END_KINDS.items()}
MAX_HEADER_BYTES = 64 * 1024


def record_dtype(extra_columns: dict[str, tuple[str, str, dict[str, str]]] | None = None) -> np.dtype:
    """:data:`RECORD` followed by the run's extra numeric columns (name -> (dtype, units, attrs)).

    A column whose type has no fixed little-endian form (strings, objects) is left out:
    the run file keeps it; the sidecar only carries numbers.
    """
    fields = list(RECORD.descr)
    for name, spec in (extra_columns or {}).items():
        dt = np.dtype(spec[0]).newbyteorder("<")
        if dt.str in EXTRA_TYPES and name not in RECORD.names and len(fields) < len(RECORD.descr) + MAX_EXTRA_COLUMNS:
            fields.append((name, dt.str))
    return np.dtype(fields)


def sidecar_path(run_path: str | Path) -> Path:
    """``RUN.h5`` -> ``RUN.h5.live``."""
    p = Path(run_path)
    return p.with_name(p.name + ".live")


class LiveSidecar:
    """Run consumer writing ``RUN.h5.live``; see the module contract."""

    def __init__(self, run_path: str | Path, flush_interval_s: float = 0.1, remove_at_end: bool = True) -> None:
        self.run_path = Path(run_path)
        self.path = sidecar_path(run_path)
        self.flush_interval_s = flush_interval_s
        self.remove_at_end = remove_at_end
        self._f: BinaryIO | None = None
        self._last_flush = 0.0
        self._dirty = False      # written since the last flush
        self.records = 0
        self.dtype = RECORD

    def _fail(self, exc: BaseException) -> None:
        print(f"warning: live view disabled, cannot write {self.path}: {exc} (the run file is not affected)",
              file=sys.stderr)
        try:
            if self._f is not None:
                self._f.close()
        except OSError:
            pass
        self._f = None

    def on_start(self, start: RunStart) -> None:
        self.dtype = record_dtype(start.extra_columns)
        header = {"version": VERSION, "record_dtype": [list(d) for d in self.dtype.descr],
                  "record_size": self.dtype.itemsize,
                  "run_file": self.run_path.name, "plan_name": start.plan_name, "n_segments": start.n_segments,
                  "estimated_duration_s": start.estimated_duration_s, "pid": os.getpid(),
                  "host": socket.gethostname(), "started": dt.datetime.now().astimezone().isoformat(timespec="seconds")}
        text = json.dumps(header).encode()
        tmp = self.path.with_name(self.path.name + ".tmp")
        try:
            f = open(tmp, "wb")
            f.write(MAGIC + struct.pack("<I", len(text)) + text)
            f.flush()
            os.replace(tmp, self.path)
            self._f = f
            self._last_flush = time.monotonic()
        except OSError as exc:
            self._fail(exc)

    def _write(self, rec: np.ndarray, force: bool = False) -> None:
        if self._f is None:
            return
        try:
            if len(rec):
                self._f.write(rec.tobytes())
                self.records += len(rec)
                self._dirty = True
            now = time.monotonic()
            if self._dirty and (force or now - self._last_flush >= self.flush_interval_s):
                self._f.flush()
                self._last_flush = now
                self._dirty = False
        except (OSError, ValueError) as exc:
            self._fail(exc)

    def on_samples(self, block: SampleBlock) -> None:
        c = block.columns
        rec = np.zeros(len(block), dtype=self.dtype)
        for name in self.dtype.names[1:]:
            if name in c:
                rec[name] = c[name]
        self._write(rec)

    def on_segment(self, segment: SegmentRecord) -> None:
        if self._dirty:   # a flush only when samples are waiting (thousands of segment ends cost nothing else)
            self._write(np.zeros(0, dtype=self.dtype), force=True)

    def on_event(self, event: EventRecord) -> None:
        pass

    def on_stop(self, stop: RunStop) -> None:
        end = np.zeros(1, dtype=self.dtype)
        end["kind"] = END_KINDS.get(stop.exit_status, 3)
        end["t"] = stop.t_end
        end["counter"] = stop.samples
        end["segment"] = stop.segments_done
        self._write(end, force=True)
        if self._f is None:
            return
        try:
            self._f.close()
            if self.remove_at_end:
                self.path.unlink()
        except OSError as exc:
            self._fail(exc)
        self._f = None


class LiveFormatError(ValueError):
    """A file that is not a live sidecar; the message names it."""


class LiveTail:
    """Reads a sidecar while it grows: :meth:`poll` returns the new whole records.

    Holds the file open (so it stays readable after the writer deletes it) and never
    writes to it or locks it, so it can neither corrupt nor block the writer.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        # never block on a FIFO or read a device: regular files only (FileNotFoundError passes)
        fd = os.open(self.path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_NOCTTY", 0))
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            os.close(fd)
            raise LiveFormatError(f"{self.path}: not a regular file, so not a live sidecar")
        self._f = os.fdopen(fd, "rb")
        try:
            self.header = self._read_header()
        except LiveFormatError:
            self._f.close()
            raise
        self._offset = 12 + self._header_len
        self.end_kind: int | None = None
        self.end_record: np.void | None = None

    def _read_header(self) -> dict[str, Any]:
        head = self._f.read(12)
        if len(head) < 12 or head[:8] != MAGIC:
            raise LiveFormatError(f"{self.path}: not a tsa-bench live sidecar (bad magic)")
        (n,) = struct.unpack("<I", head[8:])
        if n > MAX_HEADER_BYTES:
            raise LiveFormatError(f"{self.path}: sidecar header of {n:,} bytes (at most {MAX_HEADER_BYTES:,})")
        raw = self._f.read(n)
        try:
            header = parse_json(raw.decode("utf-8"), str(self.path)) if len(raw) == n else None
        except (UnicodeDecodeError, DocumentError) as exc:
            raise LiveFormatError(f"{self.path}: unreadable sidecar header ({exc})") from None
        if not isinstance(header, dict):
            raise LiveFormatError(f"{self.path}: unreadable sidecar header (truncated or not a JSON object)")
        for key, kind in (("n_segments", int), ("pid", int), ("estimated_duration_s", (int, float))):
            if key in header and (isinstance(header[key], bool) or not isinstance(header[key], kind)):
                raise LiveFormatError(f"{self.path}: sidecar header field {key!r} is {header[key]!r}")
        for key in ("plan_name", "host", "run_file", "started"):
            if key in header and not isinstance(header[key], str):
                header[key] = str(header[key])
        self._header_len = n
        self.dtype = self._layout(header)
        return header

    def _layout(self, header: dict[str, Any]) -> np.dtype:
        """The record type the header declares: :data:`RECORD`, then (version 3) numeric extras."""
        version, layout = header.get("version"), header.get("record_dtype")
        base = [list(d) for d in RECORD.descr]
        wrong = LiveFormatError(f"{self.path}: sidecar version {version!r} with another record layout; "
                                f"this tsa-bench reads versions {', '.join(map(str, READ_VERSIONS))}")
        if version not in READ_VERSIONS or not isinstance(layout, list) or layout[:len(base)] != base:
            raise wrong
        extra = layout[len(base):]
        if (version == 2 and extra) or len(extra) > MAX_EXTRA_COLUMNS:
            raise wrong
        names = set(RECORD.names)
        for item in extra:
            if not (isinstance(item, list) and len(item) == 2 and isinstance(item[0], str) and item[0].isidentifier()
                    and item[0] not in names and item[1] in EXTRA_TYPES):
                raise LiveFormatError(f"{self.path}: sidecar record field {item!r} is not a numeric column")
            names.add(item[0])
        dtype = np.dtype([(name, kind) for name, kind in RECORD.descr] + [(a, b) for a, b in extra])
        if header.get("record_size") != dtype.itemsize:
            raise LiveFormatError(f"{self.path}: sidecar record_size {header.get('record_size')!r} does not match "
                                  f"its layout ({dtype.itemsize} bytes)")
        return dtype

    @property
    def ended(self) -> str | None:
        """Exit status once the end record has been read, else None."""
        return None if self.end_kind is None else END_NAMES.get(self.end_kind, "failed")

    def poll(self) -> np.ndarray:
        """New sample records since the last call (whole records only)."""
        size = os.fstat(self._f.fileno()).st_size
        k = (size - self._offset) // self.dtype.itemsize
        if k <= 0:
            return np.zeros(0, dtype=self.dtype)
        self._f.seek(self._offset)
        raw = self._f.read(k * self.dtype.itemsize)
        k = len(raw) // self.dtype.itemsize
        self._offset += k * self.dtype.itemsize
        rec = np.frombuffer(raw[: k * self.dtype.itemsize], dtype=self.dtype)
        ends = np.flatnonzero(rec["kind"] != 0)
        if len(ends):
            self.end_kind = int(rec["kind"][ends[0]])
            self.end_record = rec[ends[0]]
            rec = rec[: ends[0]]
        return rec

    def writer_alive(self) -> bool | None:
        """True/False when the writer ran on this host (by its pid), None when unknown."""
        pid = self.header.get("pid")
        if self.header.get("host") != socket.gethostname() or not isinstance(pid, int) or not 0 < pid < 2**31:
            return None
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except OSError:
            return True
        return True

    def close(self) -> None:
        self._f.close()
