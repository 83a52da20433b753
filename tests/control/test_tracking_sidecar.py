"""A killed track_length run keeps its controller's columns: the live sidecar carries them."""

from __future__ import annotations

import multiprocessing
import os
import json
import struct
from pathlib import Path

import numpy as np
import pytest

from tests.control.helpers import STEPS_TEXT, run_text
from tests.runner.helpers import KillWhen
from tsa_bench.store import RunWriter
from tsa_bench.store.live import RECORD, LiveFormatError, LiveSidecar, LiveTail, sidecar_path
from tsa_bench.store.recover import recover_killed_run
from tsa_bench.store.reader import read_run


def _killed_tracking_child(out: str) -> None:
    """Run the tracking protocol; die like `kill -9` once the controller has made estimates."""
    path = os.path.join(out, "run.h5")
    side = LiveSidecar(path)

    kill = KillWhen(side, lambda block: (block.columns["controller_state"] > 0).sum(), 300)

    run_text(STEPS_TEXT, Path(out), consumers=[side, kill], writer=RunWriter(path, flush_interval_s=600),
             block_samples=1)   # one sample per block: killed mid-run
    os._exit(0)


def test_a_killed_tracking_run_recovers_estimate_target_and_state_from_the_sidecar(tmp_path):
    child = multiprocessing.get_context("fork").Process(target=_killed_tracking_child, args=(str(tmp_path),))
    child.start()
    child.join(300)
    assert child.exitcode == 9
    path = tmp_path / "run.h5"
    tail = LiveTail(sidecar_path(path))
    live = tail.poll()
    tail.close()
    assert {"length_estimate", "length_target", "controller_state"} <= set(live.dtype.names)
    tracked = live["controller_state"] > 0
    assert np.isfinite(live["length_target"][tracked]).sum() >= 30
    assert np.isfinite(live["length_estimate"]).sum() > 100
    recovered = recover_killed_run(path)
    assert recovered > 0
    run = read_run(path)
    assert len(run) == len(live)
    for name in ("length_estimate", "length_target", "controller_state"):
        np.testing.assert_array_equal(run.samples[name], live[name].astype(run.samples[name].dtype))
    assert run.units["length_estimate"] == "mm"


def _header(version: int, layout: list, size: int) -> bytes:
    text = json.dumps({"version": version, "record_dtype": layout, "record_size": size}).encode()
    return b"TSALIVE1" + struct.pack("<I", len(text)) + text


@pytest.mark.parametrize("version, extra, message", [
    (2, [["length_estimate", "<f8"]], "another record layout"),      # version 2 had no extras
    (3, [["t", "<f8"]], "not a numeric column"),                     # a base name again
    (3, [["note", "|O"]], "not a numeric column"),                   # not a fixed numeric type
    (3, [["x; rm", "<f8"]], "not a numeric column"),
    (5, [], "another record layout"),                                # a version from the future
])
def test_a_sidecar_layout_this_version_cannot_read_is_refused_with_the_reason(tmp_path, version, extra, message):
    base = [list(d) for d in RECORD.descr]
    side = tmp_path / "x.h5.live"
    side.write_bytes(_header(version, base + extra, RECORD.itemsize + 8 * len(extra)))
    with pytest.raises(LiveFormatError, match=message):
        LiveTail(side)


def test_a_version_2_sidecar_is_still_read(tmp_path):
    base = [list(d) for d in RECORD.descr]
    rec = np.zeros(3, dtype=RECORD)
    rec["t"] = [0.0, 0.1, 0.2]
    side = tmp_path / "x.h5.live"
    side.write_bytes(_header(2, base, RECORD.itemsize) + rec.tobytes())
    tail = LiveTail(side)
    np.testing.assert_array_equal(tail.poll()["t"], rec["t"])
    tail.close()
