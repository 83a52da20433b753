"""The run-file contract (docs/run-format.md) written with plain h5py, for the test generators.

Only the file format is shared: each generator (hidden.py, foreign/, second/) builds its own
inputs and outputs with its own equations and hands the columns here.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import h5py
import numpy as np

SEGMENT_DTYPE = [("index", "i4"), ("kind", "str"), ("t_start", "f8"), ("t_end", "f8"), ("completed", "u1"),
                 ("cycle", "i4"), ("source", "str"), ("params", "str")]


def write_contract_run(path: str | Path, columns: Mapping[str, tuple[np.ndarray, str]], segments: list[tuple],
                       attrs: Mapping[str, str], extra: Mapping[str, str] | None = None) -> Path:
    """Write ``columns`` (name -> (array, units)) under /samples, ``segments`` rows under /segments,
    the file attributes ``attrs`` (besides format and version) and ``extra`` text datasets."""
    p = Path(path)
    st = h5py.string_dtype()
    dt = np.dtype([(name, st if kind == "str" else kind) for name, kind in SEGMENT_DTYPE])
    with h5py.File(p, "w") as f:
        f.attrs.update({"format": "tsa-bench/run", "format_version": "1.0", **attrs})
        g = f.create_group("samples")
        for name, (a, unit) in columns.items():
            g.create_dataset(name, data=a).attrs["units"] = unit
        f.create_dataset("segments", data=np.array(segments, dtype=dt))
        for name, text in (extra or {}).items():
            f.create_dataset(name, data=text)
    return p
