"""Read any file meeting the run-file contract (docs/run-format.md) into memory.

Contract: :func:`read_run` opens the file read-only and checks it against the
contract: root ``format`` attribute, the required ``/samples`` columns with their
units, equal column lengths. It returns a :class:`RunData` holding every sample
column (required and extra), the segment and event tables (None when absent) and the
configuration texts. Anything that breaks the contract raises :class:`RunFileError`
whose message names the file and exactly what is wrong, so `fit`, `diagnose` and
`report` never work on a file they misread. Files written by other tools or imported
from CSV are welcome as long as they meet the contract.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from tsa_bench.store.hdf5 import FORMAT

#: Required sample columns and their units (docs/run-format.md).
REQUIRED_COLUMNS: dict[str, str] = {
    "t": "s", "turns": "turn", "length": "mm", "resistance": "ohm", "heater_voltage": "V", "load": "N",
    "segment": "1", "motor_moving": "1",
}


class RunFileError(ValueError):
    """A file that is not a readable tsa-bench run file; the message says why."""


def _plain(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    if isinstance(value, np.generic):
        return value.item()
    return value


@dataclass(frozen=True)
class RunData:
    """One run in memory. ``samples[name]`` are equal-length arrays in ``units[name]``."""

    path: str
    attrs: dict[str, Any]
    samples: dict[str, np.ndarray]
    units: dict[str, str]
    segments: np.ndarray | None = None
    events: np.ndarray | None = None
    protocol_text: str = ""
    bench_text: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.samples["t"])

    @property
    def t_s(self) -> np.ndarray:
        return self.samples["t"]

    @property
    def exit_status(self) -> str:
        return str(self.attrs.get("exit_status", ""))


def _text(f: h5py.File, name: str) -> str:
    if name not in f:
        return ""
    value = f[name][()]
    return value.decode(errors="replace") if isinstance(value, bytes) else str(value)


def read_run(path: str | Path) -> RunData:
    """Load and check one run file; raise RunFileError naming the file and the problem."""
    p = Path(path)
    if not p.exists():
        raise RunFileError(f"{p}: no such file")
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise RunFileError(f"{p}: not a readable HDF5 file ({exc})") from None
    with f:
        attrs = {k: _plain(v) for k, v in f.attrs.items()}
        if attrs.get("format") != FORMAT:
            raise RunFileError(f"{p}: root attribute 'format' is {attrs.get('format')!r}, expected {FORMAT!r}")
        if "samples" not in f or not isinstance(f["samples"], h5py.Group):
            raise RunFileError(f"{p}: no /samples group")
        group = f["samples"]
        missing = [name for name in REQUIRED_COLUMNS if name not in group]
        if missing:
            raise RunFileError(f"{p}: /samples lacks the required column(s) {missing} "
                               f"(required: {', '.join(REQUIRED_COLUMNS)})")
        samples: dict[str, np.ndarray] = {}
        units: dict[str, str] = {}
        for name, ds in group.items():
            if not isinstance(ds, h5py.Dataset) or ds.ndim != 1:
                raise RunFileError(f"{p}: /samples/{name} is not a 1-D dataset")
            samples[name] = ds[()]
            units[name] = str(_plain(ds.attrs.get("units", "")))
        for name, expected in REQUIRED_COLUMNS.items():
            if units[name] != expected:
                raise RunFileError(f"{p}: /samples/{name} has units {units[name]!r}, the contract says {expected!r}")
        lengths = {name: len(a) for name, a in samples.items()}
        if len(set(lengths.values())) > 1:
            raise RunFileError(f"{p}: /samples columns differ in length: {lengths}")
        segments = f["segments"][()] if "segments" in f else None
        events = f["events"][()] if "events" in f else None
        return RunData(str(p), attrs, samples, units, segments, events,
                       _text(f, "config/protocol"), _text(f, "config/bench"))
