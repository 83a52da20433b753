"""Run-file format 1.2: /segments coded (kind a number named by ``kind_names``, source and
params row numbers of /segment_texts, each distinct text stored once) and compressed.
Files of the earlier layout (texts in every row) read the same; a damaged coded table is
refused with one line naming the file and what is wrong."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from tests.runner.helpers import plan_from_text, run_plan
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.store import RunFileError, read_run
from tsa_bench.store.csv_export import export_csv
from tsa_bench.store.hdf5 import SEGMENT_DTYPE
from tsa_bench.store.inspect import inspect_run
from tsa_bench.store.listing import list_runs

PLAN = """name: cycles
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - heater: {voltage_V: 0}
  - repeat:
      count: 12
      steps:
        - rotation_sequence: {targets_turns: [2, 4, 2], hold_s: 0.3}
  - move_to: {turns: 0}
"""


@pytest.fixture(scope="module")
def coded(tmp_path_factory):
    stop, _, path = run_plan(plan_from_text(PLAN), tmp_path_factory.mktemp("run"), seed=2)
    assert stop.exit_status == "success"
    return path


def _as_old_layout(src, dst):
    """``src`` rewritten by plain h5py in the 1.1 layout: texts in every row of /segments."""
    segs = read_run(src).segments
    dst.write_bytes(src.read_bytes())
    with h5py.File(dst, "a") as f:
        units = {k: v for k, v in f["segments"].attrs.items() if k.endswith("_units")}
        del f["segments"], f["segment_texts"]
        old = f.create_dataset("segments", data=segs.astype(SEGMENT_DTYPE), maxshape=(None,), chunks=(1024,))
        for k, v in units.items():
            old.attrs[k] = v
        f.attrs["format_version"] = "1.1"
    return dst


def test_segments_are_stored_coded_and_each_text_once(coded):
    with h5py.File(coded, "r") as f:
        assert tuple(int(v) for v in f.attrs["format_version"].split(".")) >= (1, 2)   # 1.3 keeps this layout
        seg = f["segments"]
        assert seg.dtype["kind"].kind == "u" and seg.dtype["source"].kind == "u"
        assert seg.compression == "gzip" and seg.shuffle
        texts = f["segment_texts"][()]
        assert len(texts) == len(set(texts))            # each distinct text once
        assert len(texts) < len(seg) // 4               # 12 cycles repeat the same sources and params
        kinds = json.loads(seg.attrs["kind_names"])
        assert {kinds[c] for c in seg["kind"]} == {"heater", "move", "hold"}


def test_an_old_layout_file_reads_the_same(coded, tmp_path):
    new = tmp_path / "run.h5"
    new.write_bytes(coded.read_bytes())
    (tmp_path / "old").mkdir()
    old = _as_old_layout(coded, tmp_path / "old" / "run.h5")
    a, b = read_run(coded), read_run(old)
    assert a.segments.dtype == b.segments.dtype == SEGMENT_DTYPE
    assert len(a.segments) == 2 + 12 * 6
    for field in SEGMENT_DTYPE.names:
        assert list(a.segments[field]) == list(b.segments[field]), field
    assert [json.loads(p) for p in a.segments["params"][:2]] == [{"voltage_V": 0}, {
        "target_turns": 2, "rate_turns_per_s": 3, "accel_turns_per_s2": 30}]
    for name in SAMPLE_COLUMNS:
        assert np.array_equal(a.samples[name], b.samples[name], equal_nan=True), name
    ia, ib = inspect_run(coded), inspect_run(old)
    assert ia.segment_kinds == ib.segment_kinds and ia.n_segments == ib.n_segments == len(a.segments)
    listed = [r.segments for r in list_runs(tmp_path) + list_runs(tmp_path / "old")]
    assert listed == [f"{len(a.segments)}/{len(a.segments)}"] * 2
    export_csv(new, tmp_path / "csv-new")
    export_csv(old, tmp_path / "csv-old")
    assert (tmp_path / "csv-new" / "run.segments.csv").read_text() == \
        (tmp_path / "csv-old" / "run.segments.csv").read_text()


@pytest.mark.parametrize("edit, says", [
    (lambda f: f["segments"].attrs.__delitem__("kind_names"), "kind_names"),
    (lambda f: f["segments"].attrs.__setitem__("kind_names", "[1, 2]"), "kind_names"),
    (lambda f: f.__delitem__("segment_texts"), "/segment_texts must be a 1-D text dataset"),
    (lambda f: f["segments"].__setitem__(0, (0, 99, 0.0, 0.1, 1, -1, 0, 0)), "row 0 field 'kind' is 99"),
    (lambda f: f["segments"].__setitem__(1, (1, 0, 0.0, 0.1, 1, -1, 0, 10 ** 6)), "row 1 field 'params' is 1000000"),
])
def test_a_damaged_coded_table_is_refused_in_one_line(coded, tmp_path, edit, says):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(coded.read_bytes())
    with h5py.File(bad, "a") as f:
        edit(f)
    with pytest.raises(RunFileError, match=says) as info:
        read_run(bad)
    assert str(bad) in str(info.value) and "\n" not in str(info.value)


def test_new_kinds_and_texts_beyond_the_remembered_ones_read_back(tmp_path, monkeypatch):
    """A kind the writer does not know yet gets the next code (kind_names grows); once it
    remembers MAX_REMEMBERED_TEXTS texts, new texts are stored each time, still readable."""
    from tests.store.test_hdf5 import block, start_doc
    from tsa_bench.rundocs import RunStop, SegmentRecord
    from tsa_bench.store import RunWriter, hdf5

    monkeypatch.setattr(hdf5, "MAX_REMEMBERED_TEXTS", 3)
    path = tmp_path / "run.h5"
    w = RunWriter(path, flush_interval_s=0.0, min_flush_interval_s=0.0)
    w.on_start(start_doc())
    w.on_samples(block(0, 5))
    records = [SegmentRecord(i, "twist_heat" if i % 3 == 0 else "hold", i, i + 1.0, {"n": i % 5}, "p.yaml:3",
                             i % 2, i != 9) for i in range(10)]
    for r in records:
        w.on_segment(r)
    w.on_stop(RunStop("success", "all segments done", 10.0, 5, 0, 10, 0.1))
    segs = read_run(path).segments
    assert [k.decode() for k in segs["kind"]] == [r.kind for r in records]
    assert [json.loads(p) for p in segs["params"]] == [r.params for r in records]
    assert list(segs["completed"]) == [1] * 9 + [0] and list(segs["cycle"]) == [i % 2 for i in range(10)]
    with h5py.File(path, "r") as f:
        assert json.loads(f["segments"].attrs["kind_names"])[-1] == "twist_heat"
        assert len(f["segment_texts"]) > 5      # beyond 3 remembered texts, repeats are stored again
    assert inspect_run(path).segment_kinds == w.summary().segment_kinds == {"twist_heat": 4, "hold": 6}
