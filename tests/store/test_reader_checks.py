"""The run reader against files that break the contract in ways a killed run or
another tool produces."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from tests.runner.helpers import plan_from_text, run_plan
from tsa_bench.store import RunFileError, read_run

PLAN = """name: short
defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}
steps:
  - move_to: {turns: 3}
  - hold: {duration_s: 5}
  - move_to: {turns: 0}
"""


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    stop, _, path = run_plan(plan_from_text(PLAN), tmp_path_factory.mktemp("run"))
    assert stop.exit_status == "success"
    return path


def _copy(src, dst, edit):
    dst.write_bytes(src.read_bytes())
    with h5py.File(dst, "a") as f:
        edit(f)
    return dst


def _shorten(f, name, by=3):
    data, units = f[f"samples/{name}"][()], f[f"samples/{name}"].attrs["units"]
    del f[f"samples/{name}"]
    f["samples"].create_dataset(name, data=data[:-by]).attrs["units"] = units


def test_a_killed_run_keeps_the_rows_every_column_has(run_file, tmp_path):
    """Killed between two column appends: still "running", readable, whole rows only."""
    def edit(f):
        f.attrs["exit_status"] = "running"
        _shorten(f, "length")
    run = read_run(_copy(run_file, tmp_path / "killed.h5", edit))
    n = len(read_run(run_file))
    assert len(run) == n - 3 and run.extra["truncated_rows"] == 3
    assert all(len(a) == n - 3 for a in run.samples.values())


def test_a_killed_run_is_read_as_far_as_its_chunks_were_stored(tmp_path):
    """Killed inside a flush: the declared length ran ahead of the stored chunks (which read
    back as fill values, 0 in an integer column) and a chunk index entry points at bytes that
    do not decode. Read as far as every column was stored and decodes, never the fill values."""
    from tsa_bench.rundocs import SAMPLE_COLUMNS, RunStart, RunStop, SampleBlock
    from tsa_bench.store import RunWriter

    path = tmp_path / "killed.h5"
    w = RunWriter(path, chunk_rows=100)
    w.on_start(RunStart("p", "", None, "", None, "sim", "sim://", "1.0.0", {}, 1, 1.0))
    cols = {name: (np.arange(1000) + 1).astype(dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
    cols["t"] = np.arange(1000) * 0.01
    w.on_samples(SampleBlock(cols))
    w.on_stop(RunStop("success", "done", 10.0, 1000, 0, 0, 1.0))
    with h5py.File(path, "a") as f:
        f.attrs["exit_status"] = "running"
        for name in f["samples"]:
            f["samples"][name].resize((1500,))           # rows declared, never stored
        chunk = f["samples/counter"].id.get_chunk_info_by_coord((900,))
    with open(path, "r+b") as f:                           # and its last stored chunk does not decode
        f.seek(chunk.byte_offset)
        f.write(b"\xff" * chunk.size)
    run = read_run(path)
    assert len(run) == 900 and run.extra["truncated_rows"] == 600
    assert run.samples["counter"][-1] == 900 and (run.samples["segment"] > 0).all()


def test_a_closed_run_with_unequal_columns_is_refused(run_file, tmp_path):
    with pytest.raises(RunFileError, match="differ in length"):
        read_run(_copy(run_file, tmp_path / "bad.h5", lambda f: _shorten(f, "length")))


def test_tables_from_another_tool_are_normalised(run_file, tmp_path):
    def edit(f):
        del f["segments"], f["events"]
        f.create_dataset("segments", data=np.array([(0, b"hold", 0.0, 1.5)], dtype=[
            ("index", "i8"), ("kind", "S8"), ("t_start", "f4"), ("t_end", "f8")]))
        f.create_dataset("events", data=np.array([(0.5, b"note")], dtype=[("t", "f8"), ("kind", "S4")]))
    run = read_run(_copy(run_file, tmp_path / "foreign.h5", edit))
    seg = run.segments
    assert seg["index"][0] == 0 and seg["kind"][0] == b"hold" and seg["completed"][0] == 1 and seg["cycle"][0] == -1
    assert run.events["detail"][0] == b"" and run.events["kind"][0] == b"note"


@pytest.mark.parametrize("edit, message", [
    (lambda f: f.attrs.__setitem__("format", np.arange(3)), "root attribute 'format'"),
    (lambda f: f["samples"].__setitem__("extra", h5py.SoftLink("/samples/t")), "/samples/extra is a soft link"),
    (lambda f: f["samples"].create_dataset("words", data=np.array([b"a"] * 3)), "not a 1-D numeric column"),
    (lambda f: (f.__delitem__("segments"), f.create_dataset("segments", data=np.zeros(3))), "1-D table"),
    (lambda f: (f.__delitem__("config/protocol"), f.create_dataset("config/protocol", data=np.arange(4))),
     "must be one text"),
])
def test_contract_breaks_are_named(run_file, tmp_path, edit, message):
    with pytest.raises(RunFileError, match=message):
        read_run(_copy(run_file, tmp_path / "bad.h5", edit))


def test_a_truncated_file_is_refused_cleanly(run_file, tmp_path):
    bad = tmp_path / "cut.h5"
    bad.write_bytes(run_file.read_bytes()[: run_file.stat().st_size // 2])
    with pytest.raises(RunFileError) as info:
        read_run(bad)
    assert str(bad) in str(info.value) and "\n" not in str(info.value)
