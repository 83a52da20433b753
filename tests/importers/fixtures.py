"""Small measured-looking data sets and writers of the file formats labs use (written by the tests)."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

N = 240


def data() -> dict[str, np.ndarray]:
    """A twist staircase: t (s), turns, length (mm), resistance (ohm), temperature (degC); holds of 3 s."""
    rng = np.random.default_rng(7)
    t = np.arange(N) * 0.1
    turns = np.floor(t / 3.0) * 2.0
    length = 250 - 0.9 * turns - 0.004 * turns ** 2 + rng.normal(0, 0.01, N)
    resistance = 5.0 + 0.02 * turns + rng.normal(0, 0.001, N)
    temperature = 24 + 0.01 * t
    return {"t": t, "turns": turns, "length": length, "resistance": resistance, "temperature": temperature}


HEADER = ["Time (s)", "Twist [turn]", "Length [mm]", "R_ohm", "Temp [degC]"]


def write_xlsx(path: Path) -> Path:
    import openpyxl

    wb = openpyxl.Workbook()
    ws = wb.active
    ws.title = "Notes"
    ws.append(["exported by the DAQ"])
    data_ws = wb.create_sheet("Data")
    data_ws.append(["Rig 4, run 12"])  # a preamble row
    data_ws.append(HEADER)
    d = data()
    for row in zip(*d.values()):
        data_ws.append([float(v) for v in row])
    wb.save(path)
    return path


def write_mat5(path: Path) -> Path:
    import scipy.io

    d = data()
    scipy.io.savemat(path, {"run": {"time": d["t"], "twist": d["turns"], "len_mm": d["length"],
                                    "R_ohm": d["resistance"]}, "note": "rig 4"})
    return path


def write_mat73(path: Path) -> Path:
    """A file laid out as MATLAB v7.3 writes one: a 512-byte header, then HDF5 with transposed arrays."""
    d = data()
    m = np.column_stack([d["t"], d["turns"], d["length"], d["resistance"]])  # N x 4 in MATLAB
    with h5py.File(path, "w", userblock_size=512) as f:
        ds = f.create_dataset("M", data=m.T)  # stored 4 x N, as MATLAB's column-major layout shows in HDF5
        ds.attrs["MATLAB_class"] = np.bytes_("double")
    head = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 23 10:00:00 2026 HDF5 schema 1.00 ."
    head = head.ljust(116, b" ") + b"\0" * 8 + b"\x00\x02IM"
    with open(path, "r+b") as f:
        f.write(head.ljust(512, b"\0"))
    return path


def write_tdms(path: Path, waveform: bool = False) -> Path:
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    d = data()
    chans = []
    if not waveform:
        chans.append(ChannelObject("Measured", "Time", d["t"], properties={"unit_string": "s"}))
    props = {"wf_increment": 0.1, "wf_start_offset": 0.0} if waveform else {}
    chans += [ChannelObject("Measured", "Twist", d["turns"], properties={"unit_string": "turn", **props}),
              ChannelObject("Measured", "Length", d["length"], properties={"unit_string": "mm", **props}),
              ChannelObject("Measured", "Resistance", d["resistance"], properties={"unit_string": "Ohm", **props})]
    with TdmsWriter(path) as w:
        w.write_segment([RootObject({"operator": "lab"}), GroupObject("Measured"), *chans])
    return path


def run_import(tmp_path: Path, text: str | None, *args: str, name: str = "lab.csv", out: str = "run.h5"):
    """`tsa-bench import` of ``text`` written to ``tmp_path/name`` (None: the file is already there);
    returns (click result, output path)."""
    from click.testing import CliRunner

    from tsa_bench.cli import main

    src = tmp_path / name
    if text is not None:
        src.write_text(text, encoding="utf-8")
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / out), *args])
    return res, tmp_path / out
