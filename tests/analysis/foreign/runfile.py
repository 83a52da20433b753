"""Write a run file by the contract of docs/run-format.md, with plain h5py."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tests.analysis.foreign.rig import G
from tests.analysis.foreign.walks import History, segments_table
from tests.analysis.runfiles import write_contract_run


def write(path: str | Path, h: History, length_mm: np.ndarray, resistance_ohm: np.ndarray,
          drop: tuple[str, ...] = (), nan: tuple[str, ...] = ()) -> Path:
    """The run file; ``drop`` leaves columns out, ``nan`` writes them as all NaN (broken inputs)."""
    n = len(h)
    cols = {"t": (h.t, "s"), "turns": (h.turns, "turn"), "length": (length_mm, "mm"),
            "resistance": (resistance_ohm, "ohm"), "heater_voltage": (h.volts, "V"),
            "load": (h.load_g * G / 1000.0, "N"), "segment": (h.segment, "1"), "motor_moving": (h.moving, "1"),
            "counter": (np.arange(n, dtype=np.uint32), "1")}
    kept = {name: (np.full(n, np.nan) if name in nan else a, unit) for name, (a, unit) in cols.items()
            if name not in drop}
    return write_contract_run(path, kept, segments_table(h), {
        "created": "2025-03-01T12:00:00+00:00", "backend": "import", "firmware": "", "exit_status": "success",
        "reason": "independent generator"})
