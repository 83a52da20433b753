"""Run-file format 1.1: sample columns gzip+shuffle compressed, `t` a dimension scale of
the others; 1.0 files (uncompressed, no scales) are still read the same way."""

from __future__ import annotations

import h5py
import numpy as np

from tests.runner.helpers import plan_from_text, run_plan
from tsa_bench.rundocs import SAMPLE_COLUMNS
from tsa_bench.store import RunWriter, read_run
from tsa_bench.store.inspect import inspect_run

PLAN = """name: small
sampling_period_s: 0.01
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - move_to: {turns: 10}
  - hold: {duration_s: 20}
  - move_to: {turns: 0}
"""


def test_new_files_are_compressed_with_time_as_their_dimension(tmp_path):
    stop, _, path = run_plan(plan_from_text(PLAN), tmp_path, seed=3)
    assert stop.exit_status == "success"
    with h5py.File(path) as f:
        assert tuple(int(p) for p in f.attrs["format_version"].split(".")) >= (1, 1)
        g = f["samples"]
        assert g["t"].is_scale
        for name in SAMPLE_COLUMNS:
            assert g[name].compression == "gzip" and g[name].shuffle, name
            if name != "t":
                assert [s.name for s in g[name].dims[0].values()] == ["/samples/t"], name
        stored = sum(g[n].id.get_storage_size() for n in SAMPLE_COLUMNS)
        raw = sum(g[n].size * g[n].dtype.itemsize for n in SAMPLE_COLUMNS)
        assert stored < raw / 2, (stored, raw)   # the columns shrink (the simulated noise still costs)
    run = read_run(path)
    assert len(run) > 2000 and set(run.samples) == set(SAMPLE_COLUMNS)


def test_old_uncompressed_files_and_other_settings_read_the_same(tmp_path):
    plan = plan_from_text(PLAN)
    _, _, new = run_plan(plan, tmp_path, seed=3)
    old_writer = RunWriter(tmp_path / "old.h5", compression_level=0, chunk_rows=1000)
    _, _, old = run_plan(plan, tmp_path, seed=3, writer=old_writer)
    with h5py.File(old, "a") as f:   # make it exactly a 1.0 file: no compression, no scales
        f.attrs["format_version"] = "1.0"
        g = f["samples"]
        assert g["length"].compression is None and g["length"].chunks == (1000,)
        for name in SAMPLE_COLUMNS:
            if name != "t":
                g[name].dims[0].detach_scale(g["t"])
        for key in ("CLASS", "NAME", "REFERENCE_LIST"):
            if key in g["t"].attrs:
                del g["t"].attrs[key]
    a, b = read_run(new), read_run(old)
    for name in SAMPLE_COLUMNS:
        assert np.array_equal(a.samples[name], b.samples[name], equal_nan=True), name
    assert inspect_run(old).n_samples == inspect_run(new).n_samples
