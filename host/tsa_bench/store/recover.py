"""Finish the file of a killed run from its journal (the live sidecar).

Contract: a run killed before it closed its file leaves ``exit_status`` "running" (or,
killed inside a flush, a file HDF5 cannot read, or while creating it, an empty file) and
its journal ``RUN.h5.live`` (:mod:`tsa_bench.store.live`), which holds every sample,
segment record and event handed to the writer, raw counts included. :func:`recover_run`
refuses (:class:`RecoveryError`) while the process that wrote the journal is still alive
on this host, and never touches a file whose status is not "running" (except one whose
writer failed while closing it and kept its journal: root attribute ``journal_kept``).
Otherwise:

* with a version-4 journal (it has the run's start document), the run is rebuilt from the
  journal alone into a new file written exclusively beside the run file (the same writer,
  so the same layout), with a ``recovered`` event, ``exit_status`` "failed" and a reason
  saying so. If the run file reads and every sample it holds is the journal's (same
  counters and times, no more segments or events than the journal), the rebuilt file
  replaces it in one step (``rename``); if it does not read, it is left as it is and the
  run is rebuilt into ``RUN-rebuilt.h5`` (the next free name; the root attribute
  ``rebuilt_from`` names the damaged file), and :attr:`Recovery.rebuilt` says so;
* with an older journal (samples only), the samples whose counter comes after the last
  stored one are appended to the run file in place (first cutting every column to the
  rows all columns have), as before.

Then the journal and any temporary file the killed writer left are removed: their content
is in the file. A kill during recovery leaves the journal, so recovery can run again.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from tsa_bench.outputs import reserve_free_name, temp_name
from tsa_bench.rundata import RunData
from tsa_bench.rundocs import EventRecord, RunStop, SampleBlock, SegmentRecord
from tsa_bench.store.hdf5 import EVENT_DTYPE, RunWriter
from tsa_bench.store.live import (
    RECORD, SAMPLE_FIELDS, LiveFormatError, LiveTail, sidecar_path, start_from_document,
)
from tsa_bench.store.probe import check_hdf5_terminates
from tsa_bench.store.reader import RunFileError, read_run, stored_rows


class RecoveryError(ValueError):
    """The killed run cannot be finished; the message says why."""


@dataclass(frozen=True)
class Recovery:
    """What :func:`recover_run` did. ``path`` holds the run from now on (the run file, or
    the new file it was rebuilt into); ``samples``: samples it holds that the run file did
    not; ``rebuilt``: the run file could not be read and ``path`` is a new file."""

    path: Path
    samples: int
    rebuilt: bool
    message: str


def recover_killed_run(run_path: str | Path) -> int:
    """:func:`recover_run`; the number of samples recovered (kept for older callers)."""
    return recover_run(run_path).samples


def recover_run(run_path: str | Path) -> Recovery:
    """Finish a killed run's file from its journal (module contract)."""
    path = Path(run_path)
    side = sidecar_path(path)
    tail = None
    if side.is_file():
        try:
            tail = LiveTail(side, documents=True)
        except (LiveFormatError, OSError) as exc:
            raise RecoveryError(f"{side}: cannot read the live sidecar ({exc})") from None
    try:
        if tail is not None and tail.writer_alive():
            raise RecoveryError(f"{path} is still being recorded (process {tail.header.get('pid')} is alive); "
                                "wait for it to end or stop it first")
        run, damage = _read(path)
        if run is not None and run.exit_status != "running" and not (tail is not None and run.attrs.get("journal_kept")):
            return Recovery(path, 0, False, f"{path} was closed ({run.exit_status}); nothing to recover")
        if tail is not None and tail.version == 4:
            result = _rebuild(path, tail, run, damage)
        elif run is not None:
            result = _append_in_place(path, tail)
        else:
            raise RecoveryError(f"{damage}; and there is no live sidecar {side.name} to rebuild the run from"
                                if tail is None else f"{damage}; its live sidecar (version {tail.version}) "
                                "holds only samples, not enough to rebuild the run")
    finally:
        if tail is not None:
            tail.close()
    if tail is not None:   # its writer is gone: its journal is in the file now, its temporaries are junk
        _remove_leftovers(path, side)
    return result


def _is_empty(path: Path) -> bool:
    try:
        return path.is_file() and not path.is_symlink() and path.stat().st_size == 0
    except OSError:
        return False


def _read(path: Path) -> tuple[RunData | None, str]:
    """The run file as far as it reads, or None and why not (an empty file: created, never written)."""
    try:
        if _is_empty(path):
            return None, f"{path}: empty (the run was killed while it created its file)"
        return read_run(path), ""
    except RunFileError as exc:
        return None, str(exc)


def _covered(run: RunData, counters: np.ndarray, times: np.ndarray, n_segments: int, n_events: int) -> bool:
    """Whether the journal holds everything the run file holds (its first samples are the file's)."""
    n = len(run)
    return (len(counters) >= n and np.array_equal(run.samples["counter"], counters[:n])
            and np.array_equal(run.samples["t"], times[:n])
            and (run.segments is None or len(run.segments) <= n_segments)
            and (run.events is None or len(run.events) <= n_events))


def _rebuild(path: Path, tail: LiveTail, run: RunData | None, damage: str) -> Recovery:
    """Replay the journal through the writer into a new file; publish it (module contract)."""
    side = tail.path
    first = next(tail.items(1), None)
    if first is None or first[0] != "start":
        raise RecoveryError(f"{damage or path}; its live sidecar {side.name} has no start document")
    try:
        start, created = start_from_document(first[1])
    except ValueError as exc:
        raise RecoveryError(f"{side}: {exc}") from None
    tmp = temp_name(path, "rebuilding")
    writer = RunWriter(tmp, flush_interval_s=math.inf, min_flush_interval_s=math.inf, created=created)
    counters: list[np.ndarray] = []
    times: list[np.ndarray] = []
    n = n_segments = n_events = lost = 0
    t_end = 0.0
    last_counter: int | None = None
    try:
        writer.on_start(start)
        for kind, value in tail.items():
            if kind == "samples" and len(value):
                block = SampleBlock({name: np.asarray(value[name]) for name in value.dtype.names if name != "kind"})
                for name, dtype in writer.column_dtypes.items():   # a column the journal lacks: its fill value
                    if name not in block.columns:
                        block.columns[name] = np.full(len(value), np.nan if dtype.kind == "f" else 0, dtype=dtype)
                writer.on_samples(block)
                c = value["counter"].astype(np.int64)
                if last_counter is not None:
                    lost += int(((c[0] - last_counter) % (1 << 32)) - 1)
                lost += int(np.clip(np.diff(c) % (1 << 32) - 1, 0, None).sum())
                last_counter = int(c[-1])
                n += len(value)
                t_end = float(value["t"][-1])
                if run is not None and n - len(value) < len(run):
                    counters.append(value["counter"].copy())
                    times.append(value["t"].copy())
            elif kind == "segment":
                writer.on_segment(_segment(value))
                n_segments += 1
            elif kind == "event":
                writer.on_event(EventRecord(float(value[0]), str(value[1]), str(value[2])))
                n_events += 1
        empty = run is None and _is_empty(path)   # created, never written: nothing in it to keep
        replace = empty or run is not None and _covered(run, _cat(counters, np.uint32), _cat(times, float),
                                                        n_segments, n_events)
        k = n - len(run) if replace and run is not None else n
        if replace:
            detail = f"{k} samples after the last flush recovered from the live sidecar {side.name}"
        else:
            detail = (f"the run file {path.name} could not be read ({_why(damage, path)}); the run was rebuilt "
                      f"from its live sidecar {side.name} ({n} samples)" if run is None else
                      f"the run file {path.name} holds samples its live sidecar {side.name} lacks; the run "
                      f"was rebuilt from the sidecar beside it ({n} samples)")
        writer.on_event(EventRecord(t_end, "recovered", detail))
        ended = f" (its journal records it ended {tail.ended})" if tail.ended else ""
        writer.on_stop(RunStop("failed", f"the recording process ended without closing the file (killed?){ended}; "
                                         f"{detail}", t_end, n, max(lost, 0), n_segments, float("nan")))
        if writer.close_error or writer.broken:
            raise RecoveryError(f"cannot write the recovered run: {writer.close_error or writer.broken}")
        with h5py.File(tmp, "r+") as f:
            del f.attrs["wall_time_s"]   # unknown: the journal does not say when the process died
            f.attrs["recovered_samples"] = k
            if not replace:
                f.attrs["rebuilt_from"] = path.name
        if replace:
            os.replace(tmp, path)
            return Recovery(path, k, False, f"{path} was killed while recording; {detail}")
        new = reserve_free_name(path.parent, f"{path.stem}-rebuilt", path.suffix or ".h5")
        os.replace(tmp, new)
        return Recovery(new, k, True, f"{path} cannot be read; {detail} into {new} ({path} is left as it is)")
    except (OSError, ValueError, KeyError, TypeError) as exc:
        if isinstance(exc, RecoveryError):
            raise
        raise RecoveryError(f"{path}: cannot rebuild the run from its live sidecar ({type(exc).__name__}: {exc})") \
            from None
    finally:
        writer.discard()   # after a failure: the half-written file is removed (a success renamed it)


def _why(damage: str, path: Path) -> str:
    prefix = f"{path}: "
    return damage[len(prefix):] if damage.startswith(prefix) else damage


def _cat(parts: list[np.ndarray], dtype) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(0, dtype=dtype)


def _segment(value: list) -> SegmentRecord:
    index, kind, t_start, t_end, params, source, cycle, completed = value
    return SegmentRecord(int(index), str(kind), float(t_start), float(t_end), params if isinstance(params, dict) else {},
                         str(source), None if cycle is None else int(cycle), bool(completed))


def _append_in_place(path: Path, tail: LiveTail | None) -> Recovery:
    """An older journal (samples only): append its samples after the file's last counter."""
    side = sidecar_path(path)
    records = tail.poll() if tail is not None else np.zeros(0, dtype=RECORD)
    why = check_hdf5_terminates(path)
    if why:
        raise RecoveryError(f"{path}: {why}")
    try:
        f = h5py.File(path, "a")
    except OSError as exc:
        raise RecoveryError(f"{path}: cannot open it for writing ({exc})") from None
    with f:
        g = f["samples"]
        columns = [name for name in g if isinstance(g[name], h5py.Dataset) and g[name].ndim == 1
                   and g[name].maxshape[0] is None]   # the contract's and a runner's extra columns
        n = min(stored_rows(g[name]) for name in columns)
        for name in columns:
            if g[name].shape[0] != n:
                g[name].resize((n,))
        counters = g["counter"][max(0, n - 1):n] if "counter" in g else np.zeros(0)
        last = int(counters[-1]) if len(counters) else None
        new = records if last is None else records[records["counter"].astype(np.int64) > last]
        k = len(new)
        carried = set(SAMPLE_FIELDS) | set(new.dtype.names or ()) - {"kind"}   # extras: a sidecar of version 3
        if k:
            for name in columns:   # columns the sidecar lacks get their fill value (NaN / 0)
                ds = g[name]
                ds.resize((n + k,))
                if name in carried:
                    ds[n:] = new[name].astype(ds.dtype)
        t_end = float(new["t"][-1]) if k else (float(g["t"][n - 1]) if n else 0.0)
        detail = (f"{k} samples after the last flush recovered from the live sidecar {side.name}" if tail
                  else "no live sidecar was left: the samples after the last flush are lost")
        if "events" in f:
            ev = f["events"]
            ev.resize((ev.shape[0] + 1,))
            ev[-1] = np.array([(t_end, "recovered", detail)], dtype=EVENT_DTYPE)[0]
        f.attrs["exit_status"] = "failed"
        f.attrs["reason"] = f"the recording process ended without closing the file (killed?); {detail}"
        f.attrs["recovered_samples"] = k
        f.attrs["duration_s"] = t_end
    return Recovery(path, k, False, f"{path} was killed while recording; {detail}")


def _remove_leftovers(path: Path, side: Path) -> None:
    """The journal (its content is in the file now) and the killed writer's temporaries."""
    names = [side]
    prefix, live_prefix = path.name + ".", path.name + ".live."
    try:
        for entry in os.scandir(path.parent):
            if (entry.name.startswith(prefix) and entry.name.endswith((".writing", ".rebuilding"))
                    or entry.name.startswith(live_prefix) and entry.name.endswith(".tmp")) \
                    and entry.is_file(follow_symlinks=False):
                names.append(Path(entry.path))
    except OSError:
        pass
    for name in names:
        try:
            name.unlink()
        except OSError:
            pass
