"""Writing an imported run: contract columns filled, extra columns kept, segments, atomically.

Contract columns the source lacks are filled: float columns NaN, ``segment`` -1 (or the
segments found), ``motor_moving`` from ``turns``, ``counter`` the row number,
``step_position``/``position_raw``/``resistance_raw`` 0, ``adc_flags`` bit 2 where
resistance is NaN and bit 3 where length is NaN. The file is written to a temporary name
and renamed; an existing file is never replaced, and nothing is left behind on failure.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tsa_bench.rundocs import SAMPLE_COLUMNS, RunStart, RunStop, SampleBlock, SegmentRecord
from tsa_bench.store.hdf5 import CHUNK, RunWriter
from tsa_bench.store.replace import replacing


def fill(data: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """All contract columns, in their dtypes, from ``data`` (module contract)."""
    out: dict[str, np.ndarray] = {}
    for name, (dtype, _) in SAMPLE_COLUMNS.items():
        if name in data:
            out[name] = data[name].astype(dtype)
        elif dtype == "f8":
            out[name] = np.full(n, np.nan)
        elif name == "segment":
            out[name] = np.full(n, -1, dtype=dtype)
        elif name == "counter":
            out[name] = np.arange(n, dtype=dtype)
        else:
            out[name] = np.zeros(n, dtype=dtype)
    if "adc_flags" not in data:
        out["adc_flags"] = (np.isnan(out["resistance"]) * 4 + np.isnan(out["length"]) * 8).astype("u1")
    return out


def write_run(out: Path, start: RunStart, samples: dict[str, np.ndarray], extras: dict[str, tuple[np.ndarray, str]],
              segments: list[SegmentRecord], reason: str) -> Path:
    """Write the run file ``out`` (module contract)."""
    if out.exists():
        raise FileExistsError(out)
    n = len(samples["t"])
    with replacing(out, ".importing") as tmp:
        writer = RunWriter(tmp)
        writer.on_start(start)
        writer.on_samples(SampleBlock(samples))
        for s in segments:
            writer.on_segment(s)
        writer.on_stop(RunStop("success", reason, float(samples["t"][-1]), n, 0, 0, 0.0))
        if extras:
            with h5py.File(tmp, "a") as f:
                g = f["samples"]
                for name, (values, unit) in extras.items():
                    ds = g.create_dataset(name, data=values.astype("f8"), maxshape=(None,), chunks=(CHUNK,),
                                          fillvalue=np.nan)
                    ds.attrs["units"] = unit
    return out


def start_record(name: str, src: Path, duration_s: float, n_segments: int, metadata: dict[str, Any]) -> RunStart:
    return RunStart(plan_name=name, protocol_text="", protocol_path=None, bench_text="", bench_path=None,
                    backend="import", port=str(src), firmware="", identity={"source": str(src)},
                    n_segments=n_segments, estimated_duration_s=duration_s, metadata=metadata)
