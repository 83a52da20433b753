"""Hostile files, built from fixed contents: each declares far more than it holds, or makes
the HDF5 library loop. Used by tests/store/test_memory_budget.py and
scripts/bench/hostile_files.py.

* :func:`huge_run_file`: a run file whose /samples columns (the contract's 13 and 60 extras)
  each declare 20,000,000 rows of float64, their chunks never written: tiny on disk, about
  11.7 GB to read.
* :func:`huge_matlab_file`: a MATLAB v7.3 file (the 512-byte MATLAB header, then HDF5) with
  one 1 x 3e9 double matrix never written: about 2 KB on disk, 24 GB to read.
* :func:`looping_file`: a run file whose global heap's first object has its size's top bit
  flipped; the HDF5 library then loops on every read of its string attributes.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from tsa_bench.rundocs import SAMPLE_COLUMNS

ROWS = 20_000_000
EXTRAS = 60


def huge_run_file(path: Path, rows: int = ROWS, extras: int = EXTRAS) -> Path:
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "tsa-bench/run"
        f.attrs["format_version"] = "1.2"
        f.attrs["exit_status"] = "success"
        g = f.create_group("samples")
        units = {"t": "s", "turns": "turn", "length": "mm", "resistance": "ohm", "heater_voltage": "V", "load": "N"}
        names = list(SAMPLE_COLUMNS) + [f"extra_{i}" for i in range(extras)]
        for name in names:
            ds = g.create_dataset(name, shape=(rows,), maxshape=(None,), chunks=(8192,), dtype="f8")
            ds.attrs["units"] = units.get(name, SAMPLE_COLUMNS.get(name, ("", "1"))[1])
    return path


def huge_matlab_file(path: Path, values: int = 3_000_000_000) -> Path:
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    with h5py.File(path, "w", userblock_size=512) as f:
        f.create_dataset("x", shape=(values, 1), dtype="f8")   # (MATLAB's 1 x N, stored transposed)
        f["x"].attrs["MATLAB_class"] = np.bytes_("double")
    with open(path, "r+b") as f:
        f.write(header.ljust(116, b" ") + b"\0" * 8 + b"\x00\x02IM")
    return path


def looping_file(path: Path) -> Path:
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "tsa-bench/run"
        f.attrs["exit_status"] = "success"
    data = bytearray(path.read_bytes())
    at = data.find(b"GCOL")   # "GCOL", version, 3 reserved, 8-byte collection size, then objects:
    assert at >= 0            # index u16, references u16, reserved u32, size u64 (at +24), data
    data[at + 24] ^= 0x80
    path.write_bytes(bytes(data))
    return path
