"""Logger clocks that step back or repeat: refused by default, sorted or dropped on request, said so."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner

from tsa_bench.cli import main
from tsa_bench.store import read_run

# line 5 steps back (0.15 after 0.3), line 6 repeats 0.3 once more... lines 2.. are data
STEPPING = "t [s],length [mm]\n0.0,10\n0.1,11\n0.3,13\n0.15,12\n0.3,14\n0.4,15\n0.5,16\n"


def _run(tmp_path, *args: str, out: str = "run.h5"):
    src = tmp_path / "clock.csv"
    src.write_text(STEPPING)
    return CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / out), *args]), tmp_path / out


def test_default_refuses_naming_the_first_line_and_the_count(tmp_path):
    res, out = _run(tmp_path)
    assert res.exit_code == 2 and not out.exists()
    assert "clock.csv:5: column 't [s]' (t): time 0.15 s is not after 0.3 s on line 4" in res.output
    assert "2 rows are out of order or repeated" in res.output and "--time-order sort or drop" in res.output


def test_sort_orders_by_time_and_drops_repeats(tmp_path):
    res, out = _run(tmp_path, "--time-order", "sort")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert np.allclose(run.samples["t"], [0, 0.1, 0.15, 0.3, 0.4, 0.5])
    assert np.allclose(run.samples["length"], [10, 11, 12, 13, 15, 16])  # the first of the two 0.3 s rows is kept
    assert "time order: sorted by time: 2 rows moved, 1 row repeating an earlier time dropped" in res.output
    meta = json.loads(run.attrs["metadata"])["time_order"]
    assert meta == {"mode": "sort", "rows_affected": 2, "rows_moved": 2, "rows_dropped": 1,
                    "first_line": f"{tmp_path / 'clock.csv'}:5"}


def test_drop_keeps_only_rows_after_all_earlier_ones(tmp_path):
    res, out = _run(tmp_path, "--time-order", "drop")
    assert res.exit_code == 0, res.output
    run = read_run(out)
    assert np.allclose(run.samples["t"], [0, 0.1, 0.3, 0.4, 0.5]) and np.allclose(run.samples["length"], [10, 11, 13, 15, 16])
    assert "time order: dropped 2 rows" in res.output
    assert json.loads(run.attrs["metadata"])["time_order"]["rows_dropped"] == 2


def test_sample_rate_and_jitter_are_printed_and_stored(tmp_path):
    rng = np.random.default_rng(1)
    t = np.arange(200) * 0.01 + rng.normal(0, 0.0002, 200)
    src = tmp_path / "jit.csv"
    src.write_text("t [s],length [mm]\n" + "".join(f"{float(v)!r},1\n" for v in t))
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / "j.h5")])
    assert res.exit_code == 0, res.output
    line = next(ln for ln in res.output.splitlines() if ln.startswith("sample rate"))
    rate = json.loads(read_run(tmp_path / "j.h5").attrs["metadata"])["sample_rate"]
    assert abs(rate["rate_hz"] - 100) < 2 and 0.0001 < rate["jitter_rms_s"] < 0.0005
    assert f"{rate['rate_hz']:.6g} Hz" in line and "jitter" in line


def test_sort_stores_the_sorted_clock_when_no_row_repeats(tmp_path):
    """Issue 29, item 7b: the clock steps back by 0.25 s for three rows; no time repeats, so no row is dropped,
    and the stored t (and every column with it) must still come out in time order."""
    t = [round(0.1 * k, 2) for k in range(495, 501)] + [49.75, 49.85, 49.95] + [round(0.1 * k, 2) for k in range(501, 506)]
    src = tmp_path / "step_back.csv"
    src.write_text("t [s],length [mm]\n" + "".join(f"{v},{100 + v}\n" for v in t))
    res = CliRunner().invoke(main, ["import", str(src), "--time-order", "sort", "--out", str(tmp_path / "s.h5")])
    assert res.exit_code == 0, res.output
    assert "sorted by time: " in res.output and "0 rows repeating an earlier time dropped" in res.output
    s = read_run(tmp_path / "s.h5").samples
    assert len(s["t"]) == len(t) and bool(np.all(np.diff(s["t"]) > 0))
    assert np.allclose(s["t"], sorted(t)) and np.allclose(s["length"], 100 + s["t"])
