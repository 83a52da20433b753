"""Every run registered (recorded, resumed, imported, diagnosed), never at the run's cost;
ls searching the catalogue; rebuild and check holding the run files as the truth."""

from __future__ import annotations

import json
import signal
import sqlite3

import h5py
import pytest

from click.testing import CliRunner

from tests.catalogue.helpers import cli, live_samples, short_protocol, start_cli, wait_for
from tsa_bench import catalogue
from tsa_bench.catalogue.runfiles import sha256_of
from tsa_bench.cli import main


def _one_row(folder):
    with catalogue.open(folder) as cat:
        rows = cat.search()
    assert len(rows) == 1, rows
    return rows[0]


def test_a_run_is_registered_at_its_start_and_completed_at_its_end(tmp_path):
    out = tmp_path / "runs" / "r.h5"
    proc = start_cli("run", str(short_protocol(tmp_path)), "--output", str(out), "--speed", "10", "--set",
                     "load_g=250", "--meta", "sample=S3", "--meta", "rig=B", "--meta", "operator=ana")
    try:
        wait_for(lambda: live_samples(out) > 0, "the first samples")
        row = _one_row(out.parent)
        assert row.status == "running" and row.pid == proc.pid and row.started is not None
        assert (row.sample, row.rig, row.operator, row.load_g, row.plan) == ("S3", "B", "ana", 250.0, "short-life")
        assert row.sha256 is None and row.file_state() == "running"
    finally:
        stdout, stderr = proc.communicate(timeout=300)
    assert proc.returncode == 0, stderr
    row = _one_row(out.parent)
    with h5py.File(out, "r") as f:
        samples, t_end = f["samples/t"].shape[0], float(f.attrs["duration_s"])
    assert row.status == "success" and row.samples == samples > 0 and row.device_time_s == t_end
    assert row.samples_lost == 0 and row.segments_done == row.n_segments and row.pid is None
    assert row.sha256 == sha256_of(out) and row.file_state() == "ok" and row.ended >= row.started
    assert row.meta["protocol_variables"] == {"load_g": 250} and row.kind == "recorded"


@pytest.mark.parametrize("where", ["postgresql://nobody@127.0.0.1:9/none", "{tmp}/no/such/folder/cat.sqlite"])
def test_a_catalogue_that_cannot_be_written_is_a_warning_never_a_lost_run(tmp_path, where):
    out = tmp_path / "r.h5"
    res = cli("run", str(short_protocol(tmp_path)), "--output", str(out), "--catalogue", where.format(tmp=tmp_path))
    assert res.returncode == 0, res.stderr
    assert "warning: catalogue" in res.stderr and f"tsa-bench catalogue rebuild {tmp_path}" in res.stderr
    assert "Traceback" not in res.stderr
    with h5py.File(out, "r") as f:
        assert f.attrs["exit_status"] == "success" and f["samples/t"].shape[0] > 500
        assert f["segments"]["completed"].all() and f["segments"].shape[0] == f.attrs["n_segments"]


def test_a_locked_catalogue_does_not_hold_the_run_up(tmp_path):
    """Another writer holds the SQLite catalogue for the whole run: the run records and
    closes its file all the same, and its row is written once the lock is gone."""
    out = tmp_path / "r.h5"
    catalogue.open(tmp_path).close()
    locker = sqlite3.connect(tmp_path / "catalogue.sqlite", isolation_level=None)
    locker.execute("BEGIN EXCLUSIVE")
    proc = start_cli("run", str(short_protocol(tmp_path)), "--output", str(out))
    try:
        lines = []
        wait_for(lambda: lines.append(proc.stdout.readline()) or any(ln.startswith("wrote ") for ln in lines),
                 "the run's end while the catalogue is locked")
        with h5py.File(out, "r") as f:
            assert f.attrs["exit_status"] == "success"
        assert proc.poll() is None    # the command waits for the catalogue only after the run
    finally:
        locker.execute("ROLLBACK")
        locker.close()
        proc.communicate(timeout=120)
    assert proc.returncode == 0
    row = _one_row(tmp_path)
    assert row.status == "success" and row.sha256 == sha256_of(out)


def test_a_resumed_run_keeps_its_variables_and_both_rows_say_how_they_link(tmp_path):
    first = tmp_path / "first.h5"
    proc = start_cli("run", str(short_protocol(tmp_path)), "--output", str(first), "--speed", "10",
                     "--set", "load_g=420")
    wait_for(lambda: live_samples(first) > 100, "samples of the first run")
    proc.send_signal(signal.SIGINT)
    proc.communicate(timeout=120)
    assert proc.returncode == 130
    second = tmp_path / "second.h5"
    res = cli("run", "--resume", str(first), "--output", str(second))
    assert res.returncode == 0, res.stderr
    with catalogue.open(tmp_path) as cat:
        a, b = cat.by_path(first), cat.by_path(second)
    assert a.status == "aborted" and a.continued_in == "second.h5" and a.file_state() == "ok"
    assert b.kind == "resumed" and b.resumed_from == "first.h5" and b.status == "success"
    assert a.load_g == b.load_g == 420.0    # the resumed plan was compiled with the stored --set
    res = cli("run", str(short_protocol(tmp_path)), "--set", "weight=3", "--output", str(tmp_path / "x.h5"))
    assert res.returncode == 2 and "weight, which this protocol does not declare" in res.stderr


def tsa(*args):
    """A command in this process (quicker than a process for the reading commands)."""
    return CliRunner().invoke(main, [str(a) for a in args])


def ls(*args):
    return tsa("ls", *args)


def _three_runs(tmp_path):
    folder = tmp_path / "runs"
    protocol = short_protocol(tmp_path)
    for name, sample, load in (("a", "S1", 200), ("b", "S3", 300), ("c", "S3", 450)):
        res = cli("run", str(protocol), "--output", str(folder / f"{name}.h5"), "--catalogue", "none",
                  "--meta", f"sample={sample}", "--set", f"load_g={load}", "--seed", "1")
        assert res.returncode == 0, res.stderr
    return folder


def test_ls_lists_and_searches_the_files_and_rebuild_check_hold_them_as_the_truth(tmp_path):
    folder = _three_runs(tmp_path)
    res = ls(str(folder))                          # no catalogue: the files, listed as before
    assert res.exit_code == 0 and res.stdout.splitlines()[1].startswith("success")
    res = ls(str(folder), "--where", "sample=S3", "--json")   # searched all the same
    assert [r["path"].rsplit("/", 1)[1] for r in json.loads(res.stdout)] == ["b.h5", "c.h5"]
    assert "no catalogue in" in res.stderr and not (folder / "catalogue.sqlite").exists()

    res = tsa("catalogue", "rebuild", str(folder))
    assert res.exit_code == 0 and "3 run files registered" in res.stdout, res.stderr
    res = ls(str(folder), "--where", "sample=S3", "--where", "load_g>=400", "--json")
    (row,) = json.loads(res.stdout)
    assert row["path"] == str(folder / "c.h5") and row["load_g"] == 450.0 and row["file_state"] == "ok"
    assert row["sha256"] == sha256_of(folder / "c.h5") and row["status"] == "success"
    res = ls(str(folder), "--open", str(row["id"]))
    assert res.exit_code == 0 and res.stdout.strip() == str(folder / "c.h5")
    assert ls(str(folder), "--open", "999").exit_code == 2
    assert tsa("catalogue", "check", str(folder), "--verify").exit_code == 0

    with h5py.File(folder / "b.h5", "a") as f:           # someone edits a run file
        f.attrs["note"] = "edited"
    (folder / "a.h5").unlink()
    (folder / "junk.h5").write_bytes(b"not hdf5")
    res = ls(str(folder))
    assert "FILE MISSING" in next(ln for ln in res.stdout.splitlines() if "a.h5" in ln)
    assert "FILE CHANGED" in next(ln for ln in res.stdout.splitlines() if "b.h5" in ln)
    assert "not a readable HDF5 file" in next(ln for ln in res.stdout.splitlines() if "junk.h5" in ln)
    assert ls(str(folder), "--open", str(_id_of(folder, "a.h5"))).exit_code == 1
    res = tsa("catalogue", "check", str(folder))
    assert res.exit_code == 1 and "missing" in res.stdout and "changed" in res.stdout
    res = tsa("catalogue", "rebuild", str(folder))
    assert "changed since registered" in res.stderr and "b.h5" in res.stderr
    assert "missing: run" in res.stderr and "skipped" in res.stderr and "junk.h5" in res.stderr
    with catalogue.open(folder) as cat:
        assert cat.by_path(folder / "b.h5").file_state() == "ok"   # the file wins


def _id_of(folder, name):
    with catalogue.open(folder) as cat:
        return cat.by_path(folder / name).id


def test_an_import_is_registered(tmp_path):
    csv = tmp_path / "m.csv"
    csv.write_text("t [s],turns [turn],length [mm],resistance [ohm]\n"
                   + "".join(f"{i * 0.1:.1f},{i % 20},{100 + i % 7},{5 + i % 3}\n" for i in range(200)))
    out = tmp_path / "runs" / "imported.h5"
    res = cli("import", str(csv), "--out", str(out), "--meta", "sample=S9")
    assert res.returncode == 0, res.stderr
    row = _one_row(out.parent)
    assert row.kind == "imported" and row.sample == "S9" and row.samples == 200 and row.sha256 == sha256_of(out)
    assert row.status == "success" and row.backend == "import"
