"""Live sidecar: the run's journal, safe to read while it grows and after any kill.

Why: HDF5 is not safe for a reader while another process writes the file unless both
use SWMR, which needs the newest file format (a killed run would then not open without
h5clear; docs/run-format.md), and an HDF5 file killed inside a flush can be left with a
chunk or an index it cannot decode. So every run also writes ``RUN.h5.live``, an
append-only journal of everything the run file receives, written BEFORE the run file
gets it (:class:`~tsa_bench.store.RunWriter` with ``live=True`` owns one; a
:class:`LiveSidecar` can also be a consumer of its own):

* the file appears atomically and exclusively: the header and the start document are
  written to a new file with a random name (``RUN.h5.live.<random>.tmp``, created with
  O_EXCL and O_NOFOLLOW), which is then hard-linked to ``RUN.h5.live`` (refused if that
  name exists: a planted file or link is never written through), so a reader never
  sees a partial header;
* header: 8 bytes ``TSALIVE1``, u32 little-endian length, that many bytes of UTF-8 JSON
  (``version``, ``record_dtype``, ``record_size``, ``run_file``, ``plan_name``,
  ``n_segments``, ``estimated_duration_s``, ``pid``, ``host``, ``started``);
* then fixed-size little-endian records (:data:`RECORD`: every sample column of the run
  file, raw counts included, followed by the run's extra numeric columns such as a
  ``track_length`` controller's estimate, target and state, in the order of
  ``RunStart.extra_columns``; the header's ``record_dtype`` gives the layout),
  append-only, each block of samples, segment record and event written to the
  operating system with one ``write`` as it arrives (no buffer in this process: a
  SIGKILL loses nothing handed over);
* ``kind`` 0 is a sample; ``kind`` 4 (version 4) a document: its ``counter`` field is a
  byte length L and the next ceil(L / record size) records hold L bytes of UTF-8 JSON, one
  of ``{"start": {...}}`` (every field of the run's RunStart and the file's ``created``
  time: first, right after the header), ``{"segment": [index, kind, t_start, t_end,
  params, source, cycle, completed]}`` or ``{"event": [t, kind, detail]}``, so a run file
  can be rebuilt from the journal alone (:mod:`tsa_bench.store.recover`);
* the last record has ``kind`` 1 success, 2 aborted or 3 failed, with ``t`` the run's
  end time and ``counter`` the number of samples. It is written after the run file is
  closed, so a reader that sees it may open the run file; then the sidecar is deleted
  (a reader holding it open still reads it to the end).

A reader takes only whole records, and a document only once all of it is there. A
killed run leaves the sidecar without an end record; its ``pid`` then no longer exists.
Nothing here can lose recorded data: the sidecar never touches the run file, and a
sidecar that cannot be written is switched off with one warning on stderr (a consumer
must not raise, or the run would end as failed).
"""

from __future__ import annotations

import datetime as dt
import json
import math
import os
import socket
import stat
import struct
import sys
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.outputs import create_new, temp_name
from tsa_bench.rundocs import EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord
from tsa_bench.userfiles import DocumentError, parse_json

MAGIC = b"TSALIVE1"
VERSION = 4
#: Versions this reader understands: 2 had exactly :data:`RECORD`; 3 may append extra
#: columns; 4 adds the documents (start, segments, events).
READ_VERSIONS = (2, 3, 4)
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
DOCUMENT = 4
MAX_HEADER_BYTES = 64 * 1024
#: Longest document read (bytes): the start document carries the protocol and bench texts.
MAX_DOCUMENT_BYTES = 64 * 1024 * 1024


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


def recording(run_path: str | Path) -> bool:
    """Whether ``run_path``'s live sidecar is written by a living process on this host."""
    side = sidecar_path(run_path)
    if not side.is_file():
        return False
    try:
        tail = LiveTail(side)
    except (LiveFormatError, OSError):
        return False
    try:
        return bool(tail.writer_alive())
    finally:
        tail.close()


def _plain(value: Any) -> Any:
    """JSON for numpy scalars and arrays; anything else as its text."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return str(value)


def start_document(start: RunStart, created: str) -> dict[str, Any]:
    """The journal's start document: every RunStart field and the run file's ``created``."""
    doc = asdict(start)
    doc["extra_columns"] = {k: list(v) for k, v in start.extra_columns.items()}
    doc["created"] = created
    return doc


def start_from_document(doc: dict[str, Any]) -> tuple[RunStart, str]:
    """(RunStart, created) back from :func:`start_document`; ValueError naming a bad field."""
    fields = dict(doc)
    created = str(fields.pop("created", ""))
    try:
        fields["extra_columns"] = {str(k): (str(v[0]), str(v[1]), dict(v[2]))
                                   for k, v in (fields.get("extra_columns") or {}).items()}
        return RunStart(**fields), created
    except (TypeError, ValueError, IndexError, KeyError) as exc:
        raise ValueError(f"start document does not describe a run ({exc})") from None


class LiveSidecar:
    """Run consumer writing ``RUN.h5.live``; see the module contract.

    ``created`` is the run file's creation time the start document records (default: now).
    """

    def __init__(self, run_path: str | Path, remove_at_end: bool = True) -> None:
        self.run_path = Path(run_path)
        self.path = sidecar_path(run_path)
        self.remove_at_end = remove_at_end
        self._fd: int | None = None
        self.records = 0
        self.dtype = RECORD
        self.created = ""

    @property
    def active(self) -> bool:
        """Whether the journal is being written (False after a failure)."""
        return self._fd is not None

    def _fail(self, exc: BaseException) -> None:
        print(f"warning: live view disabled, cannot write {self.path}: {exc} (the run file is not affected)",
              file=sys.stderr)
        self._close()

    def _close(self) -> None:
        if self._fd is not None:
            try:
                os.close(self._fd)
            except OSError:
                pass
        self._fd = None

    def on_start(self, start: RunStart, created: str | None = None) -> None:
        self.dtype = record_dtype(start.extra_columns)
        self.created = created or dt.datetime.now(dt.timezone.utc).astimezone().isoformat(timespec="seconds")
        header = {"version": VERSION, "record_dtype": [list(d) for d in self.dtype.descr],
                  "record_size": self.dtype.itemsize,
                  "run_file": self.run_path.name, "plan_name": start.plan_name, "n_segments": start.n_segments,
                  "estimated_duration_s": start.estimated_duration_s, "pid": os.getpid(),
                  "host": socket.gethostname(), "started": dt.datetime.now().astimezone().isoformat(timespec="seconds")}
        text = json.dumps(header).encode()
        tmp = temp_name(self.path, "tmp")
        fd = None
        try:
            fd = create_new(tmp)
            _write_all(fd, MAGIC + struct.pack("<I", len(text)) + text
                       + self._document({"start": start_document(start, self.created)}))
            os.link(tmp, self.path, follow_symlinks=False)   # exclusive: a planted name is refused
            self._fd = fd
        except (OSError, TypeError, ValueError) as exc:
            if fd is not None:
                os.close(fd)
            self._fail(exc)
        finally:
            try:
                os.unlink(tmp)
            except OSError:
                pass

    def _document(self, doc: dict[str, Any]) -> bytes:
        """One document: its header record, then its JSON padded to whole records."""
        payload = json.dumps(doc, default=_plain).encode("utf-8", "surrogatepass")
        if len(payload) > MAX_DOCUMENT_BYTES:
            raise ValueError(f"a journal document of {len(payload):,} bytes (at most {MAX_DOCUMENT_BYTES:,})")
        head = np.zeros(1, dtype=self.dtype)
        head["kind"] = DOCUMENT
        head["counter"] = len(payload)
        size = self.dtype.itemsize
        return head.tobytes() + payload + b"\0" * (-len(payload) % size)

    def _write(self, data: bytes, records: int = 0) -> None:
        if self._fd is None:
            return
        try:
            _write_all(self._fd, data)
            self.records += records
        except OSError as exc:
            self._fail(exc)

    def on_samples(self, block: SampleBlock) -> None:
        if self._fd is None:
            return
        c = block.columns
        rec = np.zeros(len(block), dtype=self.dtype)
        for name in self.dtype.names[1:]:
            if name in c:
                rec[name] = c[name]
        self._write(rec.tobytes(), len(rec))

    def on_segment(self, s: SegmentRecord) -> None:
        if self._fd is not None:
            self._write(self._document({"segment": [s.index, s.kind, s.t_start, s.t_end, s.params, s.source,
                                                    s.cycle, bool(s.completed)]}))

    def on_event(self, e: EventRecord) -> None:
        if self._fd is not None:
            self._write(self._document({"event": [e.t, e.kind, e.detail]}))

    def on_stop(self, stop: RunStop, remove: bool | None = None) -> None:
        """The end record, then (``remove``, default ``remove_at_end``) the sidecar is deleted.
        ``remove`` applies even when the end record could not be written (a full disk):
        the caller knows whether the run file holds the run."""
        end = np.zeros(1, dtype=self.dtype)
        end["kind"] = END_KINDS.get(stop.exit_status, 3)
        end["t"] = stop.t_end
        end["counter"] = stop.samples
        end["segment"] = stop.segments_done
        wrote = self._fd is not None
        self._write(end.tobytes())
        self._close()
        if (self.remove_at_end if remove is None else remove) and (wrote or remove):
            try:
                self.path.unlink()
            except FileNotFoundError:
                pass
            except OSError as exc:
                print(f"warning: cannot remove {self.path}: {exc}", file=sys.stderr)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


class LiveFormatError(ValueError):
    """A file that is not a live sidecar; the message names it."""


class LiveTail:
    """Reads a sidecar while it grows: :meth:`poll` returns the new whole records.

    Holds the file open (so it stays readable after the writer deletes it) and never
    writes to it or locks it, so it can neither corrupt nor block the writer. With
    ``documents`` it keeps the documents it reads: :attr:`start` (the start document,
    None before it or in a sidecar older than version 4), :attr:`segments` and
    :attr:`events` (lists, journal order); :meth:`items` gives everything in order.
    """

    def __init__(self, path: str | Path, documents: bool = False) -> None:
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
        self.keep_documents = documents
        self.start: dict[str, Any] | None = None
        self.segments: list[list[Any]] = []
        self.events: list[list[Any]] = []
        self.bad_documents = 0

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
        self.version = header.get("version")
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

    @property
    def offset(self) -> int:
        """Bytes of the sidecar read so far."""
        return self._offset

    def items(self, max_records: int = 1 << 16) -> Iterator[tuple[str, Any]]:
        """Everything new, in journal order, read ``max_records`` at a time (bounded memory):
        ("samples", records), ("start" | "segment" | "event", the document's value)."""
        while self.end_kind is None:
            before = self._offset
            got = self._read(max_records)
            yield from got
            if self._offset == before:
                return

    def poll(self, max_records: int | None = None) -> np.ndarray:
        """New sample records since the last call (whole records only; documents are kept
        when asked for, else skipped)."""
        parts: list[np.ndarray] = []
        for kind, value in self._read(max_records):
            if kind == "samples":
                parts.append(value)
        if not parts:
            return np.zeros(0, dtype=self.dtype)
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _read(self, max_records: int | None) -> list[tuple[str, Any]]:
        if self.end_kind is not None:
            return []
        size = self.dtype.itemsize
        k = (os.fstat(self._f.fileno()).st_size - self._offset) // size
        if max_records is not None:
            k = min(k, max_records)
        if k <= 0:
            return []
        self._f.seek(self._offset)
        raw = self._f.read(k * size)
        k = len(raw) // size
        rec = np.frombuffer(raw[: k * size], dtype=self.dtype)
        out: list[tuple[str, Any]] = []
        marks = np.flatnonzero(rec["kind"] != 0)   # documents' payload records may be among them
        i = 0
        while i < k:
            j = int(marks[np.searchsorted(marks, i)]) if len(marks) and marks[-1] >= i else k
            if j > i:
                out.append(("samples", rec[i:j]))
            if j == k:
                i = k
                break
            kind = int(rec["kind"][j])
            if kind != DOCUMENT or self.version != VERSION:
                self.end_kind, self.end_record = kind, rec[j]
                i = j + 1
                break
            length = int(rec["counter"][j])
            n = math.ceil(length / size)
            if length > MAX_DOCUMENT_BYTES:
                self.end_kind, self.end_record = END_KINDS["failed"], rec[j]   # a broken journal ends here
                self.bad_documents += 1
                i = j + 1
                break
            if j + 1 + n > k:
                if i == j and max_records is not None and 1 + n > k:   # a document longer than the window
                    more = self._f.read((1 + n) * size - len(raw))
                    raw, k = raw + more, (len(raw) + len(more)) // size
                    if j + 1 + n <= k:
                        rec = np.frombuffer(raw[: k * size], dtype=self.dtype)
                        continue
                i = j      # the rest of the document is not written yet: read it next time
                break
            payload = raw[(j + 1) * size:(j + 1) * size + length]
            out.extend(self._document(payload))
            i = j + 1 + n
        self._offset += i * size
        return out

    def _document(self, payload: bytes) -> list[tuple[str, Any]]:
        try:
            doc = json.loads(payload.decode("utf-8", "surrogatepass"))
        except (UnicodeDecodeError, ValueError, RecursionError):
            self.bad_documents += 1
            return []
        if not isinstance(doc, dict) or len(doc) != 1:
            self.bad_documents += 1
            return []
        (kind, value), = doc.items()
        if kind == "start" and isinstance(value, dict):
            if self.keep_documents:
                self.start = value
        elif kind in ("segment", "event") and isinstance(value, list) and len(value) == (8 if kind == "segment" else 3):
            if self.keep_documents:
                (self.segments if kind == "segment" else self.events).append(value)
        else:
            self.bad_documents += 1
            return []
        return [(kind, value)]

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
