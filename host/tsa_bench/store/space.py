"""Room left for a run file, so that a full disk ends a run cleanly.

Why ahead of time: once the HDF5 library fails to write, the file can no longer be
closed (the library's own state is broken, the process may crash on exit and the file
is left truncated). So the writer never lets a write fail: before every flush it asks
:func:`available_bytes` whether the flush fits with :data:`CLOSE_RESERVE_BYTES` to
spare for closing the file, and stops the run as "disk full" while it still can close
it. Available means the smaller of the file system's free space for this user and,
under a file-size limit (``ulimit -f``, RLIMIT_FSIZE), what the file may still grow.

The run's journal (the live sidecar) shares the disk: the writer checks before it
journals a block that the block and everything still waiting for the run file fit with
the same reserve (:func:`journal_bytes`), so the journal never takes the room the run file
needs to store what it holds and to close.

Sizes in bytes. :data:`ROW_BYTES` is one sample row of the run file plus its journal
record; :data:`FILE_ROW_BYTES` one row of the run file alone (uncompressed, an upper
bound); :data:`CHUNK_ROW_BYTES` one new HDF5 chunk of every sample column (what a flush may
allocate beyond its rows).
"""

from __future__ import annotations

import os
import resource
from pathlib import Path

from tsa_bench.rundocs import StorageFull

__all__ = ["StorageFull", "available_bytes", "ensure_room", "flush_bytes", "journal_bytes", "run_bytes"]

#: Kept free for closing the file (attributes, superblock, metadata cache).
CLOSE_RESERVE_BYTES = 512 * 1024
#: One sample row of the run file's columns, uncompressed.
FILE_ROW_BYTES = 68
#: One sample row: the run file's columns (68 B) and the journal's record (69 B and extras).
ROW_BYTES = FILE_ROW_BYTES + 69
#: One new chunk of 8192 rows for every sample column, allocated whole by HDF5.
CHUNK_ROW_BYTES = 8192 * 68
#: Segment and event rows with their strings, a generous average.
SEGMENT_ROW_BYTES = 400
EVENT_ROW_BYTES = 300
#: File header, groups, empty tables and their first chunks.
HEADER_BYTES = 256 * 1024


def available_bytes(path: str | Path) -> int:
    """Bytes the file ``path`` (existing or not) may still grow by, on this disk and under rlimits."""
    p = Path(path)
    directory = p.parent if str(p.parent) else Path(".")
    st = os.statvfs(directory)
    free = st.f_bavail * st.f_frsize
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    if soft != resource.RLIM_INFINITY:
        try:
            size = p.stat().st_size
        except OSError:
            size = 0
        free = min(free, max(0, soft - size))
    return free


#: A new chunk of /segments (4096 rows of 34 bytes, stored uncompressed at worst) with one of
#: /segment_texts, and one of /events (256 rows).
SEGMENT_CHUNK_BYTES, EVENT_CHUNK_BYTES = 4096 * 34 + 256 * 16, 256 * 48


def flush_bytes(rows: int, segments: int, events: int) -> int:
    """Upper bound of what one flush of that many rows may add to the file (with a new
    chunk of each table written to, and 64 KiB of metadata)."""
    total = 64 * 1024
    if rows:
        total += rows * FILE_ROW_BYTES + CHUNK_ROW_BYTES
    if segments:
        total += segments * SEGMENT_ROW_BYTES + SEGMENT_CHUNK_BYTES
    if events:
        total += events * EVENT_ROW_BYTES + EVENT_CHUNK_BYTES
    return total


def journal_bytes(records: int, record_size: int, waiting_rows: int, waiting_segments: int,
                  waiting_events: int) -> int:
    """Room to journal ``records`` more samples and still store and close what waits for the
    run file (``waiting_*``, the new records included)."""
    return records * record_size + flush_bytes(waiting_rows, waiting_segments, waiting_events)


def run_bytes(samples: float, segments: int) -> int:
    """Estimated size of a whole run file (and sidecar) of that many samples and segments."""
    return int(HEADER_BYTES + samples * ROW_BYTES + CHUNK_ROW_BYTES + segments * SEGMENT_ROW_BYTES)


def ensure_room(path: str | Path, needed: int, what: str) -> None:
    """Raise StorageFull unless ``needed`` bytes plus the close reserve fit (module docstring)."""
    have = available_bytes(path)
    if have < needed + CLOSE_RESERVE_BYTES:
        raise StorageFull(f"disk full: {what} needs about {_mb(needed + CLOSE_RESERVE_BYTES)} and only "
                          f"{_mb(have)} is available for {path}")


def _mb(n: float) -> str:
    return f"{n / 1e6:.2f} MB" if n >= 1e4 else f"{int(n)} bytes"
