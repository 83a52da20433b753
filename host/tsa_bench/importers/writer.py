"""Writing an imported run: contract columns filled, extra columns kept, segments, atomically.

Contract columns the source lacks are filled: float columns NaN, ``segment`` -1 (or the
segments found), ``motor_moving`` from ``turns``, ``counter`` the row number,
``step_position``/``position_raw``/``resistance_raw`` 0, ``adc_flags`` bit 2 where
resistance is NaN and bit 3 where length is NaN. Extra columns are sample columns of the
run (``RunStart.extra_columns``: compressed, on the t dimension scale, with their units). The
file is written under a random temporary name beside ``out`` (``OUT.h5.<random>.importing``,
created exclusively, never through a link; the file HDF5 reopens is checked to be that one)
and published with a hard link that refuses an existing name (:mod:`tsa_bench.outputs`): an
existing file or link is never replaced or written through, and nothing is left behind on
failure.

The run writer creates the file, the segments and the attributes; the sample columns,
whole in memory here, are then written in one call each, and a column holding only its
dataset's fill value (NaN, 0: the columns an import fills) is not written at all - HDF5
reads unwritten chunks as the fill value - which keeps a large import's writing to the
columns that carry data.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tsa_bench.importers.errors import ImportFileError
from tsa_bench.outputs import OutputExists, same_file, writing
from tsa_bench.rundocs import SAMPLE_COLUMNS, RunStart, RunStop, SegmentRecord
from tsa_bench.store.hdf5 import RunWriter

#: gzip level of an imported run's sample columns: 1 writes a 1,000,000-row import in 0.36 s of CPU
#: where the recorder's level 4 takes 0.46 s, for a file 1.5 % larger (scripts/bench/import_speed.py)
IMPORT_COMPRESSION = 1


def fill(data: dict[str, np.ndarray], n: int) -> dict[str, np.ndarray]:
    """All contract columns, in their dtypes, from ``data`` (module contract). A column the source lacks
    and that holds one value is a read-only broadcast of it (no memory; :func:`write_run` writes nothing)."""
    out: dict[str, np.ndarray] = {}
    for name, (dtype, _) in SAMPLE_COLUMNS.items():
        if name in data:
            out[name] = data[name].astype(dtype, copy=False)
        elif name == "counter":
            out[name] = np.arange(n, dtype=dtype)
        else:
            value = np.nan if dtype == "f8" else -1 if name == "segment" else 0
            out[name] = np.broadcast_to(np.asarray(value, dtype=dtype), (n,))
    if "adc_flags" not in data:
        flags = np.zeros(n, "u1")
        flags[np.isnan(out["resistance"])] |= 4
        flags[np.isnan(out["length"])] |= 8
        out["adc_flags"] = flags
    return out


def _only_fill(values: np.ndarray, fill: Any) -> bool:
    """Whether every value is the dataset's fill value (NaN matching NaN); one comparison for a broadcast."""
    v = values[:1] if values.strides == (0,) else values
    if isinstance(fill, float) or getattr(fill, "dtype", np.dtype("i1")).kind == "f":
        return bool(np.isnan(fill) and np.isnan(v).all() or (v == fill).all())
    return bool((v == fill).all())


def write_run(out: Path, start: RunStart, samples: dict[str, np.ndarray], extras: dict[str, tuple[np.ndarray, str]],
              segments: list[SegmentRecord], reason: str) -> Path:
    """Write the run file ``out`` (module contract); FileExistsError if it exists."""
    n = len(samples["t"])
    start = replace(start, extra_columns={name: ("f8", unit, {}) for name, (_, unit) in extras.items()})
    try:
        with writing(out, tag="importing") as tmp:
            writer = RunWriter(tmp, compression_level=IMPORT_COMPRESSION)
            try:
                writer.on_start(start)
                for s in segments:
                    writer.on_segment(s)
                writer.on_stop(RunStop("success", reason, float(samples["t"][-1]), n, 0, 0, 0.0))
                trouble = writer.full or writer.broken or writer.close_error
                if trouble:
                    raise ImportFileError(f"cannot write {out}: {trouble}; nothing was written")
            finally:
                writer.discard()   # a failure: its file is removed (a closed one is left to be published)
            with h5py.File(tmp, "a") as f:   # HDF5 opens by name: the file it opened must be the one written
                if not same_file(f.id.get_vfd_handle(), tmp):
                    raise ImportFileError(f"{tmp} was replaced while it was written; nothing was written")
                g = f["samples"]
                for name, values in {**samples, **{k: v for k, (v, _) in extras.items()}}.items():
                    ds = g[name]
                    ds.resize((n,))
                    if _only_fill(values, ds.fillvalue):
                        continue
                    ds.write_direct(np.ascontiguousarray(values, dtype=ds.dtype))
    except OutputExists as exc:
        raise FileExistsError(str(exc)) from None
    return out


def start_record(name: str, src: Path, duration_s: float, n_segments: int, metadata: dict[str, Any]) -> RunStart:
    return RunStart(plan_name=name, protocol_text="", protocol_path=None, bench_text="", bench_path=None,
                    backend="import", port=str(src), firmware="", identity={"source": str(src)},
                    n_segments=n_segments, estimated_duration_s=duration_s, metadata=metadata)
