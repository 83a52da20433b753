"""A run writer driven step by step over stdin, for watching a run deterministically.

``python -m tests.report.stepped_writer RUN.h5`` writes RUN.h5 and its live sidecar
with the real consumers (RunWriter, LiveSidecar). Each stdin line ``block`` appends
ten samples (t advancing 1 s per sample) and flushes them to the sidecar, then prints
``wrote <last t>``; ``end`` closes the run as a success and exits. The test decides
when the run moves on, so what a watcher sees does not depend on machine load. With
``--sidecar-later`` the run file is created first and the sidecar only after a stdin
line ``sidecar`` (the moment between the two, stretched).
"""

from __future__ import annotations

import sys

import numpy as np

from tsa_bench.rundocs import SAMPLE_COLUMNS, RunStart, RunStop, SampleBlock, SegmentRecord
from tsa_bench.store import RunWriter
from tsa_bench.store.live import LiveSidecar

BLOCK = 10


def main(path: str, sidecar_later: bool = False) -> None:
    consumers = [RunWriter(path), LiveSidecar(path)]
    start = RunStart(plan_name="stepped", protocol_text="", protocol_path=None, bench_text="", bench_path=None,
                     backend="sim", port="stepped", firmware="0.0.0", identity={}, n_segments=1,
                     estimated_duration_s=100.0)
    consumers[0].on_start(start)
    if sidecar_later:
        print("run file open", flush=True)
        while sys.stdin.readline().strip() != "sidecar":
            pass
    consumers[1].on_start(start)
    n = 0
    for line in sys.stdin:
        if line.strip() == "block":
            t = np.arange(n, n + BLOCK, dtype=float)
            cols = {name: np.zeros(BLOCK, dtype=dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
            cols.update(t=t, length=250.0 + t, resistance=np.full(BLOCK, 5.0), counter=np.arange(n, n + BLOCK))
            for c in consumers:
                c.on_samples(SampleBlock(cols))
                c.on_segment(SegmentRecord(0, "hold", 0.0, float(t[-1]), {}, "stepped", None, False))
            n += BLOCK
            print(f"wrote {t[-1]:g}", flush=True)
        elif line.strip() == "end":
            break
    stop = RunStop("success", "all segments done", float(n), n, 0, 1, 0.1)
    for c in consumers:
        c.on_stop(stop)
    print("ended", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], "--sidecar-later" in sys.argv[2:])
