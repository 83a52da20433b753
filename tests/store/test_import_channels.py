"""Runs from other rigs keep their own channels: import, info, report, export and fit on extra columns."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.store import read_run
from tsa_bench.importers.csv_import import CsvImportError, import_csv

RIG = """# rig C: a heated actuator with a load cell and a pressure line
time_s,len_mm,T_K,F_N,p_kPa,humidity
0,250.0,300.15,1.0,101.3,40
1,249.5,310.15,1.1,101.4,41
2,248.0,320.15,1.3,101.2,41
3,247.5,330.15,1.4,101.3,42
4,247.0,340.15,1.5,101.5,42
"""


@pytest.fixture()
def rig_csv(tmp_path):
    p = tmp_path / "rigc.csv"
    p.write_text(RIG)
    return p


def test_extra_channels_are_stored_with_their_units(tmp_path, rig_csv):
    out = import_csv(rig_csv, tmp_path / "c.h5",
                     {"t": "time_s", "length": "len_mm", "temperature": "T_K", "force": "F_N", "pressure": "p_kPa",
                      "humidity": "humidity"},
                     {"temperature": "K", "humidity": "%"})
    run = read_run(out)
    s, u = run.samples, run.units
    assert u["temperature"] == "degC" and np.allclose(s["temperature"], [27, 37, 47, 57, 67])  # K -> degC
    assert u["force"] == "N" and np.allclose(s["force"], [1.0, 1.1, 1.3, 1.4, 1.5])
    assert u["pressure"] == "kPa" and u["humidity"] == "%"  # an unknown channel keeps its own unit
    meta = json.loads(run.attrs["metadata"])
    assert meta["extra_columns"] == {"temperature": "degC", "force": "N", "pressure": "kPa", "humidity": "%"}
    assert meta["source_units"]["temperature"] == "K"
    assert np.isnan(s["resistance"]).all() and s["length"][0] == 250.0  # contract columns as before


@pytest.mark.parametrize("mapping,units,parts", [
    ({"t": "time_s", "temperature": "T_K"}, {"temperature": "N"},
     ["rigc.csv:2", "unit 'N' is not known for temperature", "degC, C, °C, K, degF"]),
    ({"t": "time_s", "force": "F_N"}, {"force": "psi"}, ["unit 'psi' is not known for force", "N, MN, kN, mN, uN, lbf"]),
    ({"t": "time_s", "length": "len_mm"}, {"length": "furlong"}, ["unit 'furlong' is not known for length", "mm, m, cm, um"]),
    ({"t": "time_s", "humidity": "humidity"}, {}, ["extra column humidity has no unit", "--units humidity=UNIT"]),
    ({"t": "time_s", "temprature": "T_K"}, {}, ["unknown target 'temprature'", "did you mean 'temperature'"]),
])
def test_a_wrong_unit_names_the_allowed_ones(tmp_path, rig_csv, mapping, units, parts):
    with pytest.raises(CsvImportError) as err:
        import_csv(rig_csv, tmp_path / "x.h5", mapping, units)
    for part in parts:
        assert part in str(err.value), (part, str(err.value))
    assert not (tmp_path / "x.h5").exists()


def test_import_cli_unknown_unit_is_exit_2_with_the_allowed_units(tmp_path, rig_csv):
    r = CliRunner().invoke(main, ["import", str(rig_csv), "--map", "t=time_s,temperature=T_K", "--units",
                                  "temperature=kelvins", "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "kelvins" in r.output and "degC, C, °C, K, degF" in r.output
    assert "Traceback" not in r.output and not (tmp_path / "x.h5").exists()


def test_whitespace_file_without_time_gets_t_from_the_row_order(tmp_path):
    p = tmp_path / "loop.txt"
    p.write_text("Temperature Strain Stress\n30.0 0.043 99.0\n60.0 0.040 101.0\n90.0 0.010 100.0\n")
    r = CliRunner().invoke(main, ["import", str(p), "--map", "temperature=Temperature,strain=Strain,stress=Stress",
                                  "--units", "temperature=degC,strain=1,stress=MPa", "--sample-period", "0.5",
                                  "--out", str(tmp_path / "loop.h5")])
    assert r.exit_code == 0, r.output
    run = read_run(tmp_path / "loop.h5")
    assert np.allclose(run.samples["t"], [0, 0.5, 1.0]) and run.units["stress"] == "MPa"
    assert "row index" in json.loads(run.attrs["metadata"])["time"]
    bad = CliRunner().invoke(main, ["import", str(p), "--map", "t=Temperature,strain=Strain", "--units", "strain=1",
                                    "--sample-period", "1", "--out", str(tmp_path / "bad.h5")])
    assert bad.exit_code == 2 and "do not also map t" in bad.output


def test_info_report_and_export_show_extra_columns(tmp_path, rig_csv):
    out = import_csv(rig_csv, tmp_path / "c.h5", {"t": "time_s", "length": "len_mm", "temperature": "T_K",
                                                  "force": "F_N"}, {"temperature": "K"})
    info = CliRunner().invoke(main, ["info", str(out)])
    # p_kPa is picked up as pressure although not mapped: a partial --map keeps the automatic pick-up
    assert info.exit_code == 0 and "extra columns (3, beyond the contract):" in info.output
    line = next(ln for ln in info.output.splitlines() if ln.startswith("temperature"))
    assert "degC" in line and "67" in line
    rep = CliRunner().invoke(main, ["report", str(out), "--out", str(tmp_path / "rep")])
    assert rep.exit_code == 0, rep.output
    assert (tmp_path / "rep" / "extras.png").exists() and (tmp_path / "rep" / "extras_xy.png").exists()
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "Extra columns" in page and "<td>temperature</td><td>degC</td>" in page
    exp = CliRunner().invoke(main, ["export", str(out), "--csv", "--out", str(tmp_path / "exp")])
    assert exp.exit_code == 0, exp.output
    header = next(csv.reader(open(tmp_path / "exp" / "c.samples.csv")))
    assert "temperature [degC]" in header and "force [N]" in header
    back = import_csv(tmp_path / "exp" / "c.samples.csv", tmp_path / "back.h5")  # no --map: units in the header
    b, a = read_run(back), read_run(out)
    assert set(b.samples) == set(a.samples)
    for name in ("temperature", "force"):
        assert b.units[name] == a.units[name] and np.array_equal(b.samples[name], a.samples[name])


def test_fit_any_column_on_a_run_without_segments(tmp_path):

    temp = np.r_[np.linspace(30, 140, 200), np.linspace(140, 30, 200)]
    strain = 0.04 / (1 + np.exp((temp - np.r_[np.full(200, 90.0), np.full(200, 70.0)]) / 5))
    p = tmp_path / "sma.csv"
    p.write_text("temperature [degC],strain [1]\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(temp, strain)))
    run = tmp_path / "sma.h5"
    assert CliRunner().invoke(main, ["import", str(p), "--sample-period", "1", "--out", str(run)]).exit_code == 0
    res = CliRunner().invoke(main, ["fit", "preisach", str(run), "--input", "temperature", "--output", "strain",
                                    "--out", str(tmp_path / "m.json")])
    assert res.exit_code == 0, res.output
    assert "has no segments" in res.output and "the whole run, 400 samples, was used" in res.output
    assert "211 parameters for 400 fitted samples" in res.output  # more than a tenth of the samples
    pol = CliRunner().invoke(main, ["fit", "polynomial", str(run), "--input", "temperature", "--output", "strain",
                                    "--out", str(tmp_path / "p.json")])
    assert pol.exit_code == 0 and "parameters for" not in pol.output  # 4 parameters: no warning
    e_pre = json.loads((tmp_path / "m.json").read_text())["metrics"]["identification"][str(run)]["e_aver"]
    e_pol = json.loads((tmp_path / "p.json").read_text())["metrics"]["identification"][str(run)]["e_aver"]
    assert e_pre < 0.5 * e_pol  # the loop is hysteretic: Preisach follows it, a cubic cannot
    missing = CliRunner().invoke(main, ["fit", "polynomial", str(run), "--input", "pressure", "--output", "strain",
                                        "--out", str(tmp_path / "q.json")])
    assert missing.exit_code == 2 and "no sample column 'pressure'" in missing.output

