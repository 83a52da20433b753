"""`tsa-bench export --csv` and `tsa-bench import`: round trip, units, and every bad-input case."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.report.run_report import write_run_report
from tsa_bench.store import read_run
from tsa_bench.importers.csv_import import CsvImportError, import_csv


def test_export_then_import_gives_the_same_samples(protocol_runs, tmp_path):
    src = protocol_runs["twist-heat-4ply"]  # has NaN resistance while heating
    res = CliRunner().invoke(main, ["export", str(src), "--csv", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    samples = tmp_path / "twist-heat-4ply.samples.csv"
    with open(samples) as f:
        header = next(csv.reader(f))
    assert header[:6] == ["t [s]", "turns [turn]", "length [mm]", "resistance [ohm]", "heater_voltage [V]", "load [N]"]
    segs = list(csv.reader(open(tmp_path / "twist-heat-4ply.segments.csv")))
    original = read_run(src)
    assert segs[0][:4] == ["index", "kind", "t_start [s]", "t_end [s]"] and len(segs) == len(original.segments) + 1
    events = list(csv.reader(open(tmp_path / "twist-heat-4ply.events.csv")))
    assert events[0] == ["t [s]", "kind", "detail"] and "prompt" in [row[1] for row in events[1:]]
    out = tmp_path / "back.h5"
    res = CliRunner().invoke(main, ["import", str(samples), "--out", str(out), "--meta", "rig=bench B, room 2"])
    assert res.exit_code == 0, res.output
    back = read_run(out)
    assert back.attrs["backend"] == "import" and back.exit_status == "success"
    assert '"rig": "bench B, room 2"' in back.attrs["metadata"]
    assert set(back.samples) == set(original.samples)
    for name, a in original.samples.items():
        assert back.samples[name].dtype == a.dtype and np.array_equal(back.samples[name], a, equal_nan=True), name


def _csv(tmp_path, text: str, name: str = "rig.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


OTHER_RIG = """# exported by rig B
time_ms,len_cm,R_kohm,mass_g,twist_deg
0,25.0,0.0050,100,0
100,24.9,0.0051,100,360
200,24.8,,100,720
300,24.8,0.0052,100,720
400,24.8,0.0052,100,720
"""


def test_import_converts_units_and_fills_missing_columns(tmp_path):
    out = import_csv(_csv(tmp_path, OTHER_RIG), tmp_path / "b.h5",
                     {"t": "time_ms", "length": "len_cm", "resistance": "R_kohm", "load": "mass_g",
                      "turns": "twist_deg"}, {"t": "ms", "length": "cm", "R_kohm": "kohm", "load": "g", "turns": "deg"})
    run = read_run(out)
    s = run.samples
    assert np.allclose(s["t"], [0, 0.1, 0.2, 0.3, 0.4])
    assert np.allclose(s["length"], [250, 249, 248, 248, 248])
    assert np.allclose(s["resistance"], [5.0, 5.1, np.nan, 5.2, 5.2], equal_nan=True)
    assert np.allclose(s["load"], 0.1 * 9.80665) and np.allclose(s["turns"], [0, 1, 2, 2, 2])
    assert np.isnan(s["heater_voltage"]).all() and (s["segment"] == -1).all()
    assert list(s["motor_moving"]) == [0, 1, 1, 0, 0] and list(s["counter"]) == [0, 1, 2, 3, 4]
    assert list(s["adc_flags"]) == [0, 0, 4, 0, 0]
    assert run.segments is not None and len(run.segments) == 0
    rep = write_run_report(out, tmp_path / "rep")  # imported runs get a report like any other
    assert [f.name for f in rep.figures][0] == "timeseries"


BAD = [
    # (csv text, map, units, expected message parts)
    ("time_s,len\n0,1\n1,2\n", {"t": "time_s", "length": "len_mm"}, {},
     ["rig.csv:1", "column 'len_mm' (mapped to length) is not in the header", "time_s, len"]),
    ("time_s,len\n0,1\n1,2\n", {"t": "time_s", "lenght": "len"}, {}, ["unknown target 'lenght'"]),
    # time_s would be picked up as t (a partial --map keeps the automatic pick-up): a column not named as time
    ("stamp,len\n0,1\n1,2\n", {"length": "len"}, {"length": "mm"}, ["'t' (time) must be mapped"]),
    ("len\n1\n", None, {}, ["rig.csv:1", "no column named 't'"]),
    ("time_s,len\n0,1\n1,abc\n2,3\n", {"t": "time_s", "length": "len"}, {"length": "mm"},
     ["rig.csv:3", "column 'len' (length)", "cannot parse 'abc'"]),
    ("time_s,len\n0,1\n2,2\n1,3\n", {"t": "time_s", "length": "len"}, {"length": "mm"},
     ["rig.csv:4", "column 'time_s' (t)", "time 1 s is not after 2 s on line 3", "strictly increase"]),
    ("time_s,len\n0,1\n0,2\n", {"t": "time_s", "length": "len"}, {"len": "mm"}, ["rig.csv:3", "strictly increase"]),
    ("time_s,len\n0,1\n,2\n", {"t": "time_s", "length": "len"}, {"len": "mm"}, ["rig.csv:3", "(t)", "empty"]),
    ("time_s,len\n0,1\n1,2,3\n", {"t": "time_s", "length": "len"}, {"len": "mm"},
     ["rig.csv:3", "3 cells, the header has 2"]),
    # a physical column without a unit is refused, never read in the contract unit (ms as s, cm as mm)
    ("time,len,segment\n0,1,0\n", {"t": "time", "length": "len", "segment": "segment"}, {},
     ["rig.csv:1: column 'time' (t) has no unit", "--units t=UNIT (s, ms, us, min, h)",
      "column 'len' (length) has no unit", "'len [mm]'"]),
    ("time_s,len\n0,1\n", {"t": "time_s", "length": "len"}, {"len": "furlong"},
     ["rig.csv:1", "column 'len' (length)", "unit 'furlong' is not known", "mm, m, cm, um, nm, in"]),
    ("time_s,len\n0,1\n", {"t": "time_s", "length": "len"}, {"width": "mm"}, ["--units: 'width'"]),
    ("# only a comment\n", None, {}, ["rig.csv", "no header line"]),
    ("t [s],len\n", None, {}, ["rig.csv", "no data rows"]),
    ("t_s,segment\n0,1.5\n", {"t": "t_s", "segment": "segment"}, {},
     ["rig.csv:2", "column 'segment' (segment)", "not a whole number"]),
]


@pytest.mark.parametrize("text,mapping,units,parts", BAD)
def test_import_errors_say_where_and_what(tmp_path, text, mapping, units, parts):
    with pytest.raises(CsvImportError) as err:
        import_csv(_csv(tmp_path, text), tmp_path / "x.h5", mapping, units)
    for part in parts:
        assert part in str(err.value), (part, str(err.value))
    assert not (tmp_path / "x.h5").exists() and not list(tmp_path.glob("*.importing"))


def test_import_cli_errors_and_never_replaces_a_run(tmp_path, protocol_runs):
    src = _csv(tmp_path, "time_s,len\n0,1\n1,x\n")
    r = CliRunner().invoke(main, ["import", str(src), "--map", "t=time_s,length=len", "--units", "length=mm",
                                  "--out", str(tmp_path / "a.h5")])
    assert r.exit_code == 2 and "rig.csv:3" in r.output and "cannot parse 'x'" in r.output
    r = CliRunner().invoke(main, ["import", str(src), "--map", "t", "--out", str(tmp_path / "a.h5")])
    assert r.exit_code == 2 and "'t' is not KEY=VALUE" in r.output
    existing = tmp_path / "run.h5"
    existing.write_bytes(protocol_runs["stiffness-3ply"].read_bytes())
    good = _csv(tmp_path, "t [s],length [mm]\n0,1\n1,2\n", "good.csv")
    r = CliRunner().invoke(main, ["import", str(good), "--out", str(existing)])
    assert r.exit_code == 2 and "already exists" in r.output
    assert len(read_run(existing)) == 5399


def test_many_bad_cells_are_reported_together(tmp_path):
    rows = "".join(f"{i},bad{i}\n" for i in range(30))
    with pytest.raises(CsvImportError) as err:
        import_csv(_csv(tmp_path, "t [s],length [mm]\n" + rows), tmp_path / "x.h5")
    msg = str(err.value)
    assert msg.count("cannot parse") == 20 and "rig.csv:2:" in msg and "stopped after the first errors" in msg
