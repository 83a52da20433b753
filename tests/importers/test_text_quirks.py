"""Text files as labs write them: no header, other delimiters, decimal commas, preambles, units in names."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.store import read_run


def _import(tmp_path, text: str, *args: str, name: str = "lab.txt", out: str = "run.h5"):
    src = tmp_path / name
    src.write_text(text, encoding="utf-8")
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / out), *args])
    return res, tmp_path / out


def test_headerless_file_is_mapped_by_position(tmp_path):
    res, out = _import(tmp_path, "0.0\t7\t250.0\n0.1\t7\t249.5\n0.2\t7\t249.0\n", "--no-header",
                       "--map", "t=1,length=3", "--units", "t=s,length=mm")
    assert res.exit_code == 0, res.output
    s = read_run(out).samples
    assert np.allclose(s["t"], [0, 0.1, 0.2]) and np.allclose(s["length"], [250, 249.5, 249])
    assert "column 1 -> t (contract column, mapped) [s]" in res.output
    assert "column 2 left out: no name: map it by position (--map NAME=2)" in res.output


def test_a_first_line_of_numbers_is_data_not_a_header(tmp_path):
    res, out = _import(tmp_path, "0,250\n1,249\n2,248\n", "--map", "t=1,length=2", "--units", "t=s,length=mm")
    assert res.exit_code == 0, res.output
    assert len(read_run(out)) == 3 and "line 1 is all numbers: the file has no header" in res.output
    bad, _ = _import(tmp_path, "0,250\n1,249\n", "--map", "t=1,length=5", "--units", "t=s,length=mm", out="x.h5")
    assert bad.exit_code == 2 and "no column '5'" in bad.output and "position 1..2" in bad.output


@pytest.mark.parametrize("delim", [";", "\t"])
def test_decimal_comma_preamble_and_comments(tmp_path, delim):
    rows = ["Logger XY-200 export", "Operator: A. N. Other", delim.join(["t/s", "Length [mm]", "R_ohm", "Force (N)"]),
            delim.join(["0,0", "250,5", "5,25", "1,0"]), "# pause", "",
            delim.join(["0,5", "250,0", "5,5", "1,25"]), delim.join(["1,0", "249,5", "", "1,5"])]
    res, out = _import(tmp_path, "\n".join(rows) + "\n")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    s = run.samples
    assert np.allclose(s["t"], [0, 0.5, 1.0]) and np.allclose(s["length"], [250.5, 250, 249.5])
    assert np.allclose(s["resistance"], [5.25, 5.5, np.nan], equal_nan=True)
    assert np.allclose(s["force"], [1.0, 1.25, 1.5]) and run.units["force"] == "N"
    assert "skipped 2 preamble lines" in res.output and "decimal comma" in res.output
    assert "column 'R_ohm' -> resistance (contract column, picked up) [ohm]" in res.output
    assert "column 'Force (N)' -> force (extra column, picked up) [N]" in res.output


def test_header_unit_disagreeing_with_units_is_an_error_naming_both(tmp_path):
    res, out = _import(tmp_path, "t [s],resistance [ohm]\n0,5\n1,6\n", "--units", "resistance=kohm")
    assert res.exit_code == 2 and not out.exists()
    assert "column 'resistance [ohm]' (resistance)" in res.output
    assert "the header says 'ohm' but --units says 'kohm'" in res.output and "Traceback" not in res.output
    same, out2 = _import(tmp_path, "t [s],resistance [Ohm]\n0,5\n1,6\n", "--units", "resistance=ohm", out="ok.h5")
    assert same.exit_code == 0, same.output  # the same unit spelled differently is no conflict
    assert np.allclose(read_run(out2).samples["resistance"], [5, 6])


def test_partial_map_keeps_the_automatic_pick_up(tmp_path):
    text = "time_ms,lvdt,load [N],temp [K],comment\n0,1.0,2.0,300,a\n100,1.5,2.0,301,b\n"
    res, out = _import(tmp_path, text, "--map", "length=lvdt", "--units", "lvdt=cm")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    s = run.samples
    assert np.allclose(s["t"], [0, 0.1]) and np.allclose(s["length"], [10, 15]) and np.allclose(s["load"], 2.0)
    assert np.allclose(s["temperature"], [26.85, 27.85])
    lines = res.output.splitlines()
    assert "  column 'time_ms' -> t (contract column, picked up) [ms -> s, x0.001]" in lines
    assert "  column 'lvdt' -> length (contract column, mapped) [cm -> mm, x10]" in lines
    assert "  column 'load [N]' -> load (contract column, picked up) [N]" in lines
    assert "  column 'temp [K]' -> temperature (extra column, picked up) [K -> degC, x1 -273.15]" in lines
    assert any(ln.startswith("  column 'comment' left out: ") for ln in lines)
    meta = json.loads(run.attrs["metadata"])
    assert meta["column_map"]["length"] == "lvdt" and meta["source_units"]["t"] == "ms"
    assert "comment" in meta["columns_left_out"]


def test_fast_and_careful_paths_read_the_same_values(tmp_path):
    rng = np.random.default_rng(5)
    rows = [f"{i * 0.01!r},{float(v)!r},{'' if i % 7 == 3 else repr(float(w))},x{i}" for i, (v, w) in
            enumerate(zip(rng.normal(250, 1, 500), rng.normal(5, 0.1, 500)))]
    plain = "t [s],length [mm],resistance [ohm],tag\n" + "\n".join(rows) + "\n"
    commented = plain.replace(rows[200], "# operator pause\n" + rows[200])  # a comment line: the careful path
    a, out_a = _import(tmp_path, plain, name="plain.csv", out="a.h5")
    b, out_b = _import(tmp_path, commented, name="commented.csv", out="b.h5")
    assert a.exit_code == 0 and b.exit_code == 0, a.output + b.output
    sa, sb = read_run(out_a).samples, read_run(out_b).samples
    for name in ("t", "length", "resistance"):
        assert np.array_equal(sa[name], sb[name], equal_nan=True), name
    assert np.isnan(sa["resistance"][3]) and np.isfinite(sa["resistance"][4])
    bad = plain.replace(rows[300], rows[300].replace(",", ",oops", 1))
    c, out_c = _import(tmp_path, bad, name="bad.csv", out="c.h5")
    assert c.exit_code == 2 and "bad.csv:302: column 'length [mm]' (length): cannot parse 'oops" in c.output


def test_compound_and_dash_units_that_reduce_to_the_channel(tmp_path):
    res, out = _import(tmp_path, "t [s],strain [mm/mm],eps [-]\n0,0.01,0.02\n1,0.02,0.03\n")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert np.allclose(run.samples["strain"], [0.01, 0.02]) and run.units["strain"] == "1"
    assert np.allclose(run.samples["eps"], [0.02, 0.03]) and run.units["eps"] == "-"
    assert "column 'strain [mm/mm]' -> strain (extra column, picked up) [mm/mm]" in res.output
