"""The HDF5 writer against the run-file contract, fed with synthetic documents."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from tsa_bench.rundocs import (
    SAMPLE_COLUMNS, EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord,
)
from tsa_bench.store import RunWriter, read_run
from tsa_bench.store.inspect import RunFileError, inspect_run
from tsa_bench.store.live import LiveTail, sidecar_path

REQUIRED_UNITS = {"t": "s", "turns": "turn", "length": "mm", "resistance": "ohm", "heater_voltage": "V",
                  "load": "N", "segment": "1", "motor_moving": "1"}


def start_doc() -> RunStart:
    return RunStart(plan_name="p", protocol_text="name: p\nsteps: []\n", protocol_path="p.yaml",
                    bench_text="name: b\n", bench_path="b.yaml", backend="sim", port="sim://", firmware="0.1.0",
                    identity={"steps_per_turn": 3200}, n_segments=2, estimated_duration_s=10.0,
                    metadata={"ply": 4})


def block(t0: float, n: int) -> SampleBlock:
    t = t0 + 0.1 * np.arange(n)
    cols = {name: np.zeros(n, dtype=dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
    cols["t"] = t
    cols["length"] = 280 - t
    cols["resistance"] = np.where(np.arange(n) % 2, np.nan, 20.0)
    cols["counter"] = (t0 * 10 + np.arange(n)).astype("u4")
    return SampleBlock(cols)


def test_file_meets_contract(tmp_path):
    path = tmp_path / "run.h5"
    w = RunWriter(path)
    w.on_start(start_doc())
    with h5py.File(path, "r") as f:  # readable while running, status says so
        assert f.attrs["exit_status"] == "running"
    w.on_samples(block(0, 10))
    w.on_segment(SegmentRecord(0, "move", 0.0, 0.5, {"target_turns": 1.0}, "p.yaml:3", None, True))
    w.on_samples(block(1.0, 5))
    w.on_event(EventRecord(1.2, "prompt", "hang 200 g"))
    w.on_segment(SegmentRecord(1, "hold", 0.5, 1.4, {"duration_s": 0.9}, "p.yaml:4", 2, True))
    w.on_stop(RunStop("success", "all segments done", 1.4, 15, 0, 2, 0.1))
    with h5py.File(path, "r") as f:
        a = f.attrs
        assert a["format"] == "tsa-bench/run" and a["exit_status"] == "success"
        for key in ("format_version", "created", "backend", "firmware", "reason"):
            assert key in a
        assert f["config/protocol"][()].decode() == "name: p\nsteps: []\n"
        lengths = {name: len(ds) for name, ds in f["samples"].items()}
        assert set(lengths.values()) == {15}
        for name, units in REQUIRED_UNITS.items():
            assert f["samples"][name].attrs["units"] == units
            assert f["samples"][name].chunks is not None and f["samples"][name].maxshape == (None,)
        assert np.isnan(f["samples/resistance"][1])
        segs = f["segments"][()]   # coded: kind names in an attribute, texts stored once in /segment_texts
        kinds, texts = json.loads(f["segments"].attrs["kind_names"]), f["segment_texts"][()]
        assert list(segs["index"]) == [0, 1] and kinds[segs["kind"][1]] == "hold"
        assert json.loads(texts[segs["params"][0]]) == {"target_turns": 1.0}
        assert texts[segs["source"][1]] == b"p.yaml:4"
        assert segs["cycle"][0] == -1 and segs["cycle"][1] == 2
        assert f["segments"].compression == "gzip"
        assert f["events"][0]["kind"] == b"prompt"
    segs = read_run(path).segments   # read back with texts in every row
    assert list(segs["kind"]) == [b"move", b"hold"] and list(segs["source"]) == [b"p.yaml:3", b"p.yaml:4"]
    assert json.loads(segs["params"][1]) == {"duration_s": 0.9}


def test_segment_end_flushes_the_journal_and_the_file_gets_whole_chunks_only(tmp_path):
    """A segment end flushes: the journal (RUN.h5.live) holds every sample and the segment at
    once; the file gets compressed chunks only when whole (each written exactly once, so a
    kill inside a later flush cannot corrupt them), the rest when it closes."""
    path = tmp_path / "run.h5"
    w = RunWriter(path, flush_interval_s=1e9, min_flush_interval_s=0.0, chunk_rows=10, live=True)
    w.on_start(start_doc())
    w.on_samples(block(0, 7))
    w.on_segment(SegmentRecord(0, "move", 0.0, 0.7, {}, "p.yaml:3", None, True))
    tail = LiveTail(sidecar_path(path), documents=True)
    assert len(tail.poll()) == 7 and [s[0] for s in tail.segments] == [0] and tail.start["plan_name"] == "p"
    with h5py.File(path, "r") as f:
        assert len(f["samples/t"]) == 0 and w.flushes == 2   # at start and at the segment end
    w.on_samples(block(0.7, 8))                             # 15 waiting: one whole chunk of 10 goes
    w.on_segment(SegmentRecord(1, "hold", 0.7, 1.5, {}, "p.yaml:4", None, True))
    with h5py.File(path, "r") as f:
        assert len(f["samples/t"]) == 10 and f["samples/t"].id.get_num_chunks() == 1
        np.testing.assert_array_equal(f["samples/counter"][()], np.arange(10))
    assert len(tail.poll()) == 8
    w.on_stop(RunStop("success", "done", 1.5, 15, 0, 2, 0.1))
    run = read_run(path)
    assert len(run) == 15 and len(run.segments) == 2 and not sidecar_path(path).exists()
    np.testing.assert_array_equal(run.samples["counter"], np.arange(15))
    tail.close()


def test_inspect_reports_gaps_and_status(tmp_path):
    path = tmp_path / "run.h5"
    w = RunWriter(path)
    w.on_start(start_doc())
    b = block(0, 10)
    b.columns["counter"][5:] += 3
    w.on_samples(b)
    w.on_stop(RunStop("aborted", "Ctrl-C", 1.0, 10, 3, 0, 0.1))
    info = inspect_run(path)
    assert info.counter_gaps == 3 and info.attrs["exit_status"] == "aborted" and info.n_samples == 10


def test_inspect_rejects_non_run_files(tmp_path):
    with pytest.raises(RunFileError, match="no such file"):
        inspect_run(tmp_path / "missing.h5")
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(RunFileError, match="not a readable HDF5"):
        inspect_run(tmp_path / "text.h5")
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f.attrs["format"] = "something-else"
    with pytest.raises(RunFileError, match="format"):
        inspect_run(tmp_path / "other.h5")
