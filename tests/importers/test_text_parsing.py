"""CSV/TSV data rows are parsed by pyarrow's CSV reader; a file it cannot take as it is is read again line by line,
so refusals and line numbers are the same whichever path read it (issue 29, item 12)."""

from __future__ import annotations

import tomllib

import numpy as np
import pyarrow.csv
import pytest

from tests.importers.fixtures import run_import
from tests.report.conftest import ROOT
from tsa_bench.importers import text
from tsa_bench.store import read_run


@pytest.fixture
def paths(monkeypatch):
    """Counts pyarrow parses and line-by-line reads."""
    calls = {"arrow": 0, "careful": 0}
    real_read, real_careful = pyarrow.csv.read_csv, text._careful

    def read(*a, **k):
        calls["arrow"] += 1
        return real_read(*a, **k)

    def careful(*a, **k):
        calls["careful"] += 1
        return real_careful(*a, **k)

    monkeypatch.setattr(pyarrow.csv, "read_csv", read)
    monkeypatch.setattr(text, "_careful", careful)
    return calls


def test_pyarrow_is_a_core_dependency():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert any(d.replace(" ", "").startswith("pyarrow") for d in deps)


def test_a_clean_file_is_parsed_by_pyarrow_alone(tmp_path, paths):
    rows = "".join(f"{k * 0.1:.1f},{k % 7},{'' if k % 5 == 0 else 250 - k * 0.01:.6},\"{k}\",ok\n" for k in range(300))
    res, out = run_import(tmp_path, "# exported\r\nt [s],turns [turn],length [mm],n [1],status\r\n"
                          + rows.replace("\n", "\r\n"))
    assert res.exit_code == 0, res.output
    assert paths == {"arrow": 1, "careful": 0}
    s = read_run(out).samples
    assert len(s["t"]) == 300 and np.isnan(s["length"][0]) and np.isclose(s["length"][1], 249.99)
    assert np.allclose(s["n"], np.arange(300)) and np.allclose(s["turns"][:8], [0, 1, 2, 3, 4, 5, 6, 0])


def test_bad_rows_are_named_by_line_after_pyarrow_refused_them(tmp_path, paths):
    good = "".join(f"{k * 0.1:.1f},{100 + k}\n" for k in range(3, 40))
    text_ = "t [s],length [mm]\n0,100\n0.1,101\n0.2,x\n" + good[:40] + "0.9\n" + good[40:]
    res, out = run_import(tmp_path, text_)
    assert res.exit_code == 2 and not out.exists()
    assert paths["arrow"] >= 1 and paths["careful"] >= 1
    bad_line = text_.splitlines().index("0.9") + 1
    assert f"lab.csv:{bad_line}: 1 cells, the header has 2" in res.output
    res, out = run_import(tmp_path, text_.replace("0.9\n", "0.95,1\n"), out="b.h5")
    assert res.exit_code == 2 and "lab.csv:4: column 'length [mm]' (length): cannot parse 'x' as a number" in res.output


@pytest.mark.parametrize("pause", ["\n# paused\n", "\n\n"])
def test_blank_and_comment_lines_among_the_data_keep_their_line_numbers(tmp_path, paths, pause):
    body = f"t [s],length [mm]\n0,100\n0.1,101\n{pause}0.2,102\n0.15,103\n"
    res, out = run_import(tmp_path, body)
    assert res.exit_code == 2 and "lab.csv:7: column 't [s]' (t): time 0.15 s is not after 0.2 s on line 6" in res.output
    res, out = run_import(tmp_path, body.replace("0.15,103", "0.3,103"), out="b.h5")
    assert res.exit_code == 0 and np.allclose(read_run(out).samples["length"], [100, 101, 102, 103])


@pytest.mark.parametrize("body,args", [
    ("t;length\n0;1,5\n0,1;2,25\n0,2;\n", ("--units", "t=s,length=mm")),           # decimal comma, empty cell
    ("t [s]\tlength [mm]\n0\t1e2\n0.1\t+5.\n0.2\t.5\n", ()),                           # tabs, exponents, signs
    ('"t [s]","length [mm]"\n"0","1"\n"0.1","2"\n', ()),                            # every cell quoted
    ("t [s],length [mm],R [ohm]\n0,1,nan\n0.1,2,inf\n0.2,3,NaN\n", ()),             # nan and inf spelled out
    ("\ufeffstatus,t [s],length [mm]\r\nok,0,1\r\n# note,5,6\r\nok,0.1,2\r\n", ()),    # BOM, CRLF, a comment
    ("status,t [s],length [mm]\nok,0,1\n  // note,5,6\n ok,0.1,2\n", ()),              # an indented comment
    ("t [s],length [mm]\r0,1\r0.1,2\r0.2,3\r", ()),                                  # bare CR line ends
])
def test_pyarrow_and_the_line_by_line_reader_agree(tmp_path, monkeypatch, body, args):
    res, out = run_import(tmp_path, body, *args)
    monkeypatch.setattr(text, "_arrow", lambda *a, **k: None)
    res2, out2 = run_import(tmp_path, None, *args, out="careful.h5")
    assert res.exit_code == res2.exit_code
    if res.exit_code:   # the same refusal, word for word
        assert res.output == res2.output and "inf where a finite value is required" in res.output
        return
    assert res.exit_code == 0, res.output
    a, b = read_run(out).samples, read_run(out2).samples
    for name in a:
        assert np.array_equal(a[name], b[name], equal_nan=True), name
