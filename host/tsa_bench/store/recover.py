"""Finish the file of a killed run from its live sidecar.

Contract: a run killed before it closed its file leaves ``exit_status`` "running", the
samples up to the writer's last flush, and its live sidecar ``RUN.h5.live``
(:mod:`tsa_bench.store.live`), which holds every sample up to the kill, raw counts
included. :func:`recover_killed_run` appends to the run file the sidecar's samples
whose counter comes after the last stored one (first cutting every column to the rows
all columns have; extra columns such as a controller's estimate included), records a ``recovered`` event, sets ``exit_status`` "failed" with a
reason saying so, and removes the sidecar (its samples are now in the file). It refuses
(:class:`RecoveryError`) while the process that wrote the sidecar is still alive on
this host, and never touches a file whose status is not "running".
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from tsa_bench.store.hdf5 import EVENT_DTYPE
from tsa_bench.store.live import RECORD, SAMPLE_FIELDS, LiveFormatError, LiveTail, sidecar_path
from tsa_bench.store.probe import check_hdf5_terminates


class RecoveryError(ValueError):
    """The killed run cannot be finished; the message says why."""


def recover_killed_run(run_path: str | Path) -> int:
    """Append the sidecar's missing samples to a killed run (module contract); return how many."""
    path = Path(run_path)
    side = sidecar_path(path)
    tail = None
    records = np.zeros(0, dtype=RECORD)
    if side.is_file():
        try:
            tail = LiveTail(side)
        except (LiveFormatError, OSError) as exc:
            raise RecoveryError(f"{side}: cannot read the live sidecar ({exc})") from None
        try:
            if tail.writer_alive():
                raise RecoveryError(f"{path} is still being recorded (process {tail.header.get('pid')} is alive); "
                                    "wait for it to end or stop it first")
            records = tail.poll()
        finally:
            tail.close()
    why = check_hdf5_terminates(path)
    if why:
        raise RecoveryError(f"{path}: {why}")
    try:
        f = h5py.File(path, "a")
    except OSError as exc:
        raise RecoveryError(f"{path}: cannot open it for writing ({exc})") from None
    with f:
        if str(f.attrs.get("exit_status", "")) != "running":
            return 0
        g = f["samples"]
        columns = [name for name in g if isinstance(g[name], h5py.Dataset) and g[name].ndim == 1
                   and g[name].maxshape[0] is None]   # the contract's and a runner's extra columns
        n = min(g[name].shape[0] for name in columns)
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
    if tail is not None:
        try:
            side.unlink()
        except OSError:
            pass
    return k
