"""Spreadsheets, MATLAB and LabVIEW files import like text; unreadable files name what they look like."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from tests.importers import fixtures
from tsa_bench.cli import main
from tsa_bench.store import read_run

CASES = {
    "xlsx": ("lab.xlsx", fixtures.write_xlsx, ["--sheet", "Data", "--map", "turns=Twist"]),
    "mat5": ("lab.mat", fixtures.write_mat5, ["--map", "t=time,turns=twist,length=len_mm,resistance=R_ohm",
                                              "--units", "t=s,turns=turn"]),
    "mat73": ("lab73.mat", fixtures.write_mat73, ["--var", "M", "--map", "t=1,turns=2,length=3,resistance=4",
                                                  "--units", "t=s,turns=turn,length=mm,resistance=ohm"]),
    "tdms": ("lab.tdms", fixtures.write_tdms, ["--map", "turns=Twist"]),
    "tdms-waveform": ("wave.tdms", lambda p: fixtures.write_tdms(p, waveform=True), ["--map", "turns=Twist"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_format_imports_and_is_accepted_by_info_fit_report_and_diagnose(tmp_path, case):
    name, write, args = CASES[case]
    src = write(tmp_path / name)
    out = tmp_path / "run.h5"
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(out), *args])
    assert res.exit_code == 0, res.output
    run, d = read_run(out), fixtures.data()
    assert np.allclose(run.samples["t"], d["t"]) and np.allclose(run.samples["length"], d["length"])
    assert np.allclose(run.samples["turns"], d["turns"]) and np.allclose(run.samples["resistance"], d["resistance"])
    assert len(run.segments) == 15 and "segments inferred: 15 (7 move, 8 hold" in res.output  # 8 holds, 7 moves
    if case == "xlsx":
        assert np.allclose(run.samples["temperature"], d["temperature"]) and "skipped 1 preamble line" in res.output
    meta = json.loads(run.attrs["metadata"])
    assert meta["source_format"].split()[0] in ("xlsx", "MATLAB", "TDMS")
    info = CliRunner().invoke(main, ["info", str(out)])
    assert info.exit_code == 0, info.output
    fit = CliRunner().invoke(main, ["fit", "polynomial", str(out), "--out", str(tmp_path / "m.json")])
    assert fit.exit_code == 0 and "no segments" not in fit.output, fit.output
    e = json.loads((tmp_path / "m.json").read_text())["metrics"]["identification"][str(out)]["e_aver"]
    assert e < 0.05  # a cubic follows the quadratic staircase to the noise
    rep = CliRunner().invoke(main, ["report", str(out), "--out", str(tmp_path / "rep")])
    assert rep.exit_code == 0, rep.output
    diag = CliRunner().invoke(main, ["diagnose", str(out), "--out", str(tmp_path / "dg"), "-q"])
    assert diag.exit_code == 0 and "VERDICT" in diag.output and "no segments" not in diag.output, diag.output


def test_sheet_var_and_group_errors_list_what_there_is(tmp_path):
    x = fixtures.write_xlsx(tmp_path / "a.xlsx")
    r = CliRunner().invoke(main, ["import", str(x), "--sheet", "Dat", "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "no sheet 'Dat' (sheets: Notes, Data)" in r.output
    m = fixtures.write_mat5(tmp_path / "a.mat")
    r = CliRunner().invoke(main, ["import", str(m), "--var", "nope", "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "no variable 'nope'" in r.output and "run (struct)" in r.output
    t = fixtures.write_tdms(tmp_path / "a.tdms")
    r = CliRunner().invoke(main, ["import", str(t), "--group", "Other", "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "no channel group 'Other' (groups: Measured)" in r.output
    assert not (tmp_path / "x.h5").exists()


BAD = {
    "broken.xlsx": (b"PK\x03\x04" + b"\x00" * 60, "looks like an Excel workbook (.xlsx) but cannot be read"),
    "old.xls": (b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + b"\x00" * 100, "looks like a legacy Excel .xls"),
    "cut.mat": (b"MATLAB 5.0 MAT-file, Platform: x".ljust(128, b" ") + b"\x01\x00", "looks like a MATLAB v5 .mat file"),
    "cut.tdms": (b"TDSm\x0e\x00\x00\x00", "looks like a LabVIEW TDMS file but cannot be read"),
    "blob.bin": (bytes(range(256)), "looks like binary data of no known format"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_unreadable_file_names_the_format_it_looks_like(tmp_path, name):
    raw, part = BAD[name]
    (tmp_path / name).write_bytes(raw)
    r = CliRunner().invoke(main, ["import", str(tmp_path / name), "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and part in r.output, r.output
    assert "supported formats: CSV/TSV/text" in r.output and ".xlsx" in r.output and ".tdms" in r.output
    assert "Traceback" not in r.output and not list(tmp_path.glob("x.h5*"))


def test_a_missing_optional_reader_names_its_extra(tmp_path, monkeypatch):
    t = fixtures.write_tdms(tmp_path / "a.tdms")
    monkeypatch.setitem(sys.modules, "nptdms", None)  # as if npTDMS were not installed
    r = CliRunner().invoke(main, ["import", str(t), "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "needs the optional extra 'tdms'" in r.output and "tsa-bench[tdms]" in r.output


def test_matlab_vectors_of_different_lengths_are_chosen_by_map(tmp_path):
    """Issue 29, item 6: a workspace of vectors of several lengths; the ones --map names must agree."""
    import scipy.io

    n = 50
    src = tmp_path / "ws.mat"
    scipy.io.savemat(src, {"time": np.arange(n) * 0.1, "defl": np.linspace(0, 2, n), "volt": np.linspace(0, 5, n),
                           "calib": np.arange(7.0), "other_t": np.arange(12.0)})
    res = CliRunner().invoke(main, ["import", str(src), "--map", "t=time,length=defl,heater_voltage=volt",
                                    "--units", "t=s,length=mm,heater_voltage=V", "--out", str(tmp_path / "w.h5")])
    assert res.exit_code == 0, res.output
    assert "vectors of another length left out: calib (7), other_t (12)" in res.output
    s = read_run(tmp_path / "w.h5").samples
    assert len(s["t"]) == n and np.allclose(s["length"][-1], 2.0)
    bad = CliRunner().invoke(main, ["import", str(src), "--map", "t=time,length=calib", "--units", "t=s,length=mm",
                                    "--out", str(tmp_path / "x.h5")])
    assert bad.exit_code == 2 and not (tmp_path / "x.h5").exists()
    assert "the vectors --map names are of different lengths (time 50, calib 7)" in bad.output


def test_matlab_source_code_is_named_with_the_hint_to_save_a_mat_file(tmp_path):
    src = tmp_path / "DataT.m"
    src.write_text("% measured data\nfunction d = DataT()\n  d = [0 1; 0.1 2];\nend\n")
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / "d.h5")])
    assert res.exit_code == 2 and not (tmp_path / "d.h5").exists()
    assert "looks like MATLAB source code (a script or function), not data" in res.output
    assert "save the workspace as a .mat file" in res.output and "cells, the header has" not in res.output
