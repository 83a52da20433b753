"""Segments for imported runs: inferred from the data like a recorded run's, from a column, or none (said so)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from click.testing import CliRunner

from tests.report.conftest import ROOT, simulate
from tsa_bench.cli import main
from tsa_bench.store import read_run


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A simulated twist sweep (moves, holds, three loads) and its samples CSV without segment information."""
    d = tmp_path_factory.mktemp("sweep")
    run = simulate(ROOT / "configs" / "protocols" / "twist-sweep-3ply.yaml", d / "sweep.h5")
    assert CliRunner().invoke(main, ["export", str(run), "--csv", "--out", str(d)]).exit_code == 0
    rows = list(csv.reader(open(d / "sweep.samples.csv")))
    drop = [i for i, c in enumerate(rows[0]) if c.split(" ")[0] in ("segment", "motor_moving")]
    stripped = d / "stripped.csv"
    with open(stripped, "w", newline="") as f:
        csv.writer(f).writerows([[c for i, c in enumerate(r) if i not in drop] for r in rows])
    return run, stripped, d


def _fit(run, out, *extra):
    res = CliRunner().invoke(main, ["fit", "preisach", str(run), "--out", str(out), *extra])
    assert res.exit_code == 0, res.output
    return res, json.loads(out.read_text())["metrics"]


def test_fit_on_inferred_segments_matches_the_recorded_run(sweep, tmp_path):
    run, stripped, _ = sweep
    res = CliRunner().invoke(main, ["import", str(stripped), "--out", str(tmp_path / "imp.h5")])
    assert res.exit_code == 0, res.output
    assert "segments inferred: " in res.output
    assert ("thresholds: turns 0 turn (hysteresis 0), heater 0.05 V (hysteresis 0.01), load 0.05 N (hysteresis 0.01), "
            "minimum duration 0.25 s") in res.output
    imp = read_run(tmp_path / "imp.h5")
    kinds = set(imp.segments["kind"].astype(str))
    assert {"move", "hold"} <= kinds and len(imp.segments) > 50 and (imp.samples["segment"] >= 0).all()
    _, orig = _fit(run, tmp_path / "o.json")
    out, mine = _fit(tmp_path / "imp.h5", tmp_path / "i.json", "--validate", str(run))
    assert "no segments" not in out.output
    e_orig = orig["identification"][str(run)]["e_aver"]
    e_imp = mine["identification"][str(tmp_path / "imp.h5")]["e_aver"]
    n_orig, n_imp = orig["identification"][str(run)]["n"], mine["identification"][str(tmp_path / "imp.h5")]["n"]
    assert abs(n_imp - n_orig) <= 0.02 * n_orig  # the same quasi-static samples, give or take a move's edge
    assert abs(e_imp - e_orig) <= 0.02 * e_orig
    # the model fitted on the import predicts the recorded run as well as the recorded run's own model
    assert abs(mine["validation"][str(run)]["e_aver"] - e_orig) <= 0.02 * e_orig


def test_a_run_without_segments_is_said_on_the_first_line(sweep, tmp_path):
    _, stripped, d = sweep
    small = tmp_path / "small.csv"
    small.write_text("".join(open(stripped).readlines()[:601]))
    res = CliRunner().invoke(main, ["import", str(small), "--segments", "none", "--out", str(tmp_path / "n.h5")])
    assert res.exit_code == 0 and "segments: none (--segments none)" in res.output
    fit = CliRunner().invoke(main, ["fit", "polynomial", str(tmp_path / "n.h5"), "--out", str(tmp_path / "p.json")])
    assert fit.exit_code == 0, fit.output
    assert fit.output.splitlines()[0].startswith(f"note: {tmp_path / 'n.h5'} has no segments")
    diag = CliRunner().invoke(main, ["diagnose", str(tmp_path / "n.h5"), "--out", str(tmp_path / "dg"), "-q"])
    assert diag.exit_code == 0, diag.output
    assert diag.output.splitlines()[0].startswith(f"diagnose: note: {tmp_path / 'n.h5'} has no segments")


def test_segments_from_a_column(sweep, tmp_path):
    run, _, d = sweep
    res = CliRunner().invoke(main, ["import", str(d / "sweep.samples.csv"), "--map", "step_no=segment",
                                    "--units", "step_no=1", "--segments", "column=segment [1]",
                                    "--out", str(tmp_path / "c.h5")])
    assert res.exit_code == 2 and "segment" in res.output  # the column cannot be both mapped and the segments
    res = CliRunner().invoke(main, ["import", str(d / "sweep.samples.csv"), "--segments", "column=segment",
                                    "--out", str(tmp_path / "c.h5")])
    assert res.exit_code == 0, res.output
    c, o = read_run(tmp_path / "c.h5"), read_run(run)
    used = np.unique(o.samples["segment"][o.samples["segment"] >= 0])
    assert len(c.segments) == len(used) and "segments: " in res.output


def test_heater_and_load_changes_are_segments_and_thresholds_can_be_changed(tmp_path):
    t = np.arange(60) * 0.5
    volts = np.where((t >= 10) & (t < 20), 2.0, 0.0)
    load = np.where(t >= 20, 1.0, 0.5) + np.where(t >= 25, 0.02, 0.0)  # a 0.02 N step is below the default
    src = tmp_path / "h.csv"
    src.write_text("t [s],heater_voltage [V],load [N],length [mm]\n"
                   + "".join(f"{a},{v},{w},100\n" for a, v, w in zip(t, volts, load)))
    res = CliRunner().invoke(main, ["import", str(src), "--out", str(tmp_path / "h.h5")])
    assert res.exit_code == 0, res.output
    segs = read_run(tmp_path / "h.h5").segments
    assert list(segs["kind"].astype(str)) == ["hold", "heater", "heater"] and np.allclose(segs["t_start"], [0, 10, 20])
    assert json.loads(segs["params"][2])["load_change"] is True
    res = CliRunner().invoke(main, ["import", str(src), "--segment-threshold", "load_N=0.01", "--out", str(tmp_path / "h2.h5")])
    assert res.exit_code == 0 and "load 0.01 N" in res.output
    assert np.allclose(read_run(tmp_path / "h2.h5").segments["t_start"], [0, 10, 20, 25])
    bad = CliRunner().invoke(main, ["import", str(src), "--segment-threshold", "speed=1", "--out", str(tmp_path / "x.h5")])
    assert bad.exit_code == 2 and "unknown speed" in bad.output and not (tmp_path / "x.h5").exists()
