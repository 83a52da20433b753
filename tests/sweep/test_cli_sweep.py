"""`tsa-bench sweep` from the command line: bad input, an unreachable scheduler, Ctrl-C and resume."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from tsa_bench.sweep.table import ResultsTable

ROOT = Path(__file__).resolve().parents[2]


def cli(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tsa_bench.cli", "sweep", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=300)


def test_unknown_path_is_refused_before_anything_runs(tmp_path):
    study = tmp_path / "bad.yaml"
    study.write_text("study: bad\nrunner: simulate\nvary:\n  protocol.cycles: [1, 2]\n  bench.sed: [1, 2]\n")
    r = cli(str(study), "--out", str(tmp_path / "out"))
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"error: {study}:5:3: unknown parameter 'bench.sed'"), r.stderr
    assert "Traceback" not in r.stderr and not (tmp_path / "out").exists()


def test_empty_grid_is_refused_with_its_line(tmp_path):
    study = tmp_path / "empty.yaml"
    study.write_text("study: e\nrunner: simulate\nvary:\n  protocol.cycles: {grid: {start: 1, stop: 5, num: 0}}\n")
    r = cli(str(study), "--out", str(tmp_path / "out"))
    assert r.returncode == 2 and f"{study}:4:" in r.stderr and "grid is empty" in r.stderr, r.stderr


def test_unreachable_scheduler_exits_1_naming_it(tmp_path):
    study = tmp_path / "s.yaml"
    study.write_text("study: s\nrunner: simulate\nbase: {protocol: {cycles: 2}}\n")
    r = cli(str(study), "--out", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:9", "--connect-timeout", "1")
    assert r.returncode == 1, r.stderr
    assert "error: no Dask scheduler answered at tcp://127.0.0.1:9" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_or_sigterm_keeps_finished_points_and_a_rerun_finishes_the_rest(tmp_path, sig):
    study = tmp_path / "slow.yaml"
    # the ten points take about ten seconds here, far longer than the results table's 2 s flush
    # interval, so the first part is written while most points are still to run and Ctrl-C lands
    # in the middle (with shorter points it landed while the finished process was exiting)
    study.write_text("study: slow\nrunner: simulate\nbase: {protocol: {cycles: 600}, bench: {settle_s: 10}}\n"
                     "vary:\n  bench.seed: {grid: {start: 0, stop: 9, step: 1}}\n")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "tsa_bench.cli", "sweep", str(study), "--out", str(out),
                             "--workers", "1"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not list((out / "parts").glob("*.parquet")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.2)
    os.kill(proc.pid, sig)
    stdout, stderr = proc.communicate(timeout=240)
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]   # no half-written part left
    if proc.returncode == 0:  # the machine was fast enough to finish first: nothing to resume, still whole
        assert len(pq.read_table(out / "results.parquet")) == 10
        return
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    kept = pq.read_table(out / "results.parquet").column("key").to_pylist()
    assert 1 <= len(kept) < 10
    r = cli(str(study), "--out", str(out), "--workers", "1")
    assert r.returncode == 0, r.stderr
    assert f"{10 - len(kept)} done, 0 failed, {len(kept)} already in the results (10 points)" in r.stdout
    table = pq.read_table(out / "results.parquet")
    assert sorted(table.column("point").to_pylist()) == list(range(10))
    assert set(kept) <= set(table.column("key").to_pylist())


def test_dry_run_and_report(tmp_path):
    study = tmp_path / "d.yaml"
    study.write_text("study: d\nrunner: simulate\nbase: {protocol: {cycles: 3}, bench: {settle_s: 10}}\n"
                     "vary:\n  protocol.cycles: [3, 4]\n")
    r = cli(str(study), "--out", str(tmp_path / "o"), "--dry-run")
    assert r.returncode == 0 and "2 points, 2 to run, runner simulate" in r.stdout, r.stderr
    r = cli(str(study), "--out", str(tmp_path / "o"), "--report")
    assert r.returncode == 1 and "no results yet" in r.stderr


def test_a_part_interrupted_while_it_is_written_leaves_nothing(tmp_path, monkeypatch):
    """SIGTERM (a KeyboardInterrupt in the sweep) inside the Parquet writer: no part and no
    temporary file; the rows stay buffered for the next flush."""
    table = ResultsTable(tmp_path)
    table.add(0, {"protocol": {"cycles": 1}}, {"protocol.cycles": 1}, {"key": "k0", "status": "done"})

    def interrupted(t, where, **kw):
        where.write(b"PAR1 half a part")
        raise KeyboardInterrupt

    monkeypatch.setattr("tsa_bench.sweep.table.pq.write_table", interrupted)
    with pytest.raises(KeyboardInterrupt):
        table.flush()
    assert list((tmp_path / "parts").iterdir()) == []
    monkeypatch.undo()
    assert table.flush() is not None and table.finished_keys() == {"k0"}
