"""A run written by the real writer from synthetic documents, to be killed anywhere.

``python -m tests.store.kill_driver OUT.h5 [--kill-at-append K] [--kill-at-flush K]
[--kill-after-flush K]`` writes
one run with its journal (``RunWriter(live=True)``): 40 blocks of samples with the
``track_length`` extra columns, a segment record after each block, an event after every
third, small chunks so that flushes and appends write whole chunks throughout, and a
flush at every segment end. ``--kill-at-append K`` SIGKILLs the process inside the K-th
column append (before the library call), ``--kill-at-flush K`` inside the K-th file
flush, ``--kill-after-flush K`` as the K-th file flush returns (the file holds more than at
any earlier instant); without them it is killed from outside (``strace -e inject=pwrite64:signal=KILL``)
or runs to the end. Deterministic: the same documents and the same writes every time.
"""

from __future__ import annotations

import argparse
import os
import signal

import h5py
import numpy as np

from tsa_bench.rundocs import SAMPLE_COLUMNS, EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord
from tsa_bench.runner.tracking import COLUMNS as TRACKING_COLUMNS
from tsa_bench.store import RunWriter
from tsa_bench.store import hdf5

BLOCKS, ROWS = 40, 333
CHUNK_ROWS = 1024


def start() -> RunStart:
    return RunStart(plan_name="kill-driver", protocol_text="name: kill-driver\nsteps: []\n", protocol_path=None,
                    bench_text="name: b\n", bench_path=None, backend="sim", port="sim://", firmware="1.0.0",
                    identity={"steps_per_turn": 3200}, n_segments=BLOCKS, estimated_duration_s=BLOCKS * ROWS * 1e-3,
                    metadata={"driver": True}, extra_columns=TRACKING_COLUMNS)


def block(i: int) -> SampleBlock:
    n0 = i * ROWS
    k = np.arange(n0, n0 + ROWS)
    cols = {name: (k % 1000).astype(dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
    cols["t"] = k * 1e-3
    cols["counter"] = (k + 7 * (k >= 5000)).astype("u4")   # a gap of 7 lost samples
    cols["segment"] = np.full(ROWS, i, dtype="i4")
    cols["length"] = 250.0 + np.sin(k * 0.01)
    cols["resistance"] = np.where(k % 5 == 0, np.nan, 20.0 + k * 1e-6)
    for name, (dtype, _, _) in TRACKING_COLUMNS.items():
        cols[name] = (np.cos(k * 0.02) * 3 + 250).astype(dtype) if dtype == "f8" else (k % 3).astype(dtype)
    return SampleBlock(cols)


def _kill_on_call(owner, name: str, at: int, after: bool = False) -> None:
    calls = [0]
    original = getattr(owner, name)

    def hooked(self, *args, **kwargs):
        calls[0] += 1
        if calls[0] == at and not after:
            os.kill(os.getpid(), signal.SIGKILL)
        result = original(self, *args, **kwargs)
        if calls[0] == at and after:
            os.kill(os.getpid(), signal.SIGKILL)
        return result

    setattr(owner, name, hooked)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--kill-at-append", type=int, default=0)
    ap.add_argument("--kill-at-flush", type=int, default=0)
    ap.add_argument("--kill-after-flush", type=int, default=0)
    args = ap.parse_args()
    if args.kill_at_append:
        _kill_on_call(hdf5._Appender, "append", args.kill_at_append)
    if args.kill_at_flush:
        _kill_on_call(h5py.File, "flush", args.kill_at_flush)
    if args.kill_after_flush:
        _kill_on_call(h5py.File, "flush", args.kill_after_flush, after=True)
    w = RunWriter(args.out, min_flush_interval_s=0.0, chunk_rows=CHUNK_ROWS, live=True)
    w.on_start(start())
    for i in range(BLOCKS):
        b = block(i)
        w.on_samples(b)
        t = b.columns["t"]
        w.on_segment(SegmentRecord(i, "hold" if i % 2 else "move", float(t[0]), float(t[-1]),
                                   {"duration_s": 0.333, "i": i % 4}, f"driver.yaml:{3 + i % 5}", i // 10, True))
        if i % 3 == 0:
            w.on_event(EventRecord(float(t[-1]), "note", f"block {i}"))
    n = BLOCKS * ROWS
    w.on_stop(RunStop("success", "all segments done", n * 1e-3, n, 7, BLOCKS, 1.0))


if __name__ == "__main__":
    main()
