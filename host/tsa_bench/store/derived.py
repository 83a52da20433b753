"""A copy of a run file with a computed column added (a model's prediction, say).

Contract: :func:`write_with_column` never changes the recorded file. It copies it to a
random temporary name beside ``out`` (created exclusively, never through a link; the file
HDF5 then opens is checked to be that one), adds ``/samples/<name>`` (as long as the other
columns, with ``units`` and the given attributes; ``t`` attached as its dimension scale)
and the root attribute ``derived_from`` (the source file's name), then gives it the name
``out`` (:mod:`tsa_bench.outputs`). An existing ``out`` is replaced only when replacing
is allowed (``--force``; never the recorded run itself), and a column name the file
already has is refused.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tsa_bench.outputs import OutputExists, open_new, writing


class DerivedFileError(ValueError):
    """The derived file cannot be written; the message says why."""


def write_with_column(source: str | Path, out: str | Path, name: str, values: np.ndarray, units: str,
                      attrs: dict[str, Any] | None = None) -> Path:
    """Write ``out`` = ``source`` + ``/samples/<name>`` (module contract)."""
    src, dst = Path(source), Path(out)
    if dst.resolve() == src.resolve():
        raise DerivedFileError(f"{dst} is the recorded run itself; write the prediction to another file")
    try:
        with writing(dst, hint="give --force to replace it, or choose another file") as tmp:
            with open_new(tmp) as copy, open(src, "rb") as original:
                shutil.copyfileobj(original, copy)
                made = os.fstat(copy.fileno())
            with h5py.File(tmp, "a") as f:
                opened = os.fstat(f.id.get_vfd_handle())
                if (opened.st_dev, opened.st_ino) != (made.st_dev, made.st_ino):
                    raise DerivedFileError(f"{tmp} was replaced while it was written; nothing was written")
                g = f["samples"]
                if name in g:
                    raise DerivedFileError(f"{src} already has /samples/{name}")
                n = g["t"].shape[0]
                if len(values) != n:
                    raise DerivedFileError(f"/samples/{name} has {len(values)} values, the run has {n} samples")
                ds = g.create_dataset(name, data=np.asarray(values), chunks=True, compression="gzip", shuffle=True)
                ds.attrs["units"] = units
                for key, value in (attrs or {}).items():
                    ds.attrs[key] = value
                if g["t"].is_scale:
                    ds.dims[0].attach_scale(g["t"])
                f.attrs["derived_from"] = src.name
    except OutputExists as exc:
        raise DerivedFileError(str(exc)) from None
    except OSError as exc:
        raise DerivedFileError(f"cannot write {dst}: {exc.strerror or exc}") from None
    return dst
