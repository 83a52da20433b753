"""The fast simulated path gives the same run file as the framed one.

``sim://`` hands decoded frames to the client (no framing, CRC or decoding) and the
runner hands samples to the writer in coalesced blocks. The framed path - bytes through
the codec and the link layer, a document block at every read, as over a pty or simavr -
must record exactly the same samples, segments and events, and the writer's running
statistics must say what reading the file back says."""

from __future__ import annotations

import h5py
import numpy as np

from tests.runner.helpers import BENCH, open_sim, plan_from_text, run_plan
from tsa_bench.console.summary import format_run_info
from tsa_bench.store import RunWriter
from tsa_bench.store.inspect import inspect_run

PLAN = """name: mixed
load_g: 300
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 4, accel_turns_per_s2: 40}
steps:
  - move_to: {turns: 5}
  - hold: {duration_s: 2}
  - repeat:
      count: 4
      steps:
        - rotation_sequence: {targets_turns: [7, 9, 7, 5], hold_s: 0.3}
        - heater: {voltage_V: 2}
        - hold: {duration_s: 1}
        - heater: {voltage_V: 0}
        - sampling: {period_s: 0.1}
        - hold_until_settled: {max_duration_s: 4, window_s: 2, max_dL_dt_mm_per_s: 1.0}
        - sampling: {period_s: 0.05}
  - prompt: {text: "hang 500 g", load_g: 500}
  - move_to: {turns: 2}
  - hold: {duration_s: 1}
"""


class BytesOnly:
    """The sim:// port seen through its byte interface only (the framed path)."""

    def __init__(self, port) -> None:
        self._port = port

    def __getattr__(self, name):
        if name in ("read_frames", "write_frame"):
            raise AttributeError(name)
        return getattr(self._port, name)

    @property
    def in_waiting(self) -> int:
        return self._port.in_waiting

    def read(self, size: int = 1) -> bytes:
        return self._port.read(size)

    def write(self, data: bytes) -> int:
        return self._port.write(data)


def _contents(path) -> dict:
    with h5py.File(path) as f:
        out = {f"samples/{k}": f["samples"][k][()] for k in f["samples"]}
        out["segments"] = f["segments"][()].tolist()
        out["events"] = f["events"][()].tolist()
        out["samples_lost"] = int(f.attrs["samples_lost"])
    return out


def _assert_same_file(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key in a:
        if key.startswith("samples/"):
            assert np.array_equal(a[key], b[key], equal_nan=a[key].dtype.kind == "f"), key
        else:
            assert a[key] == b[key], key


def test_fast_and_framed_paths_record_the_same_file(tmp_path):
    plan = plan_from_text(PLAN)
    (tmp_path / "fast").mkdir()
    (tmp_path / "framed").mkdir()
    fast_stop, fast_client, fast = run_plan(plan, tmp_path / "fast", seed=3)
    port = BytesOnly(open_sim(3))
    framed_stop, framed_client, framed = run_plan(plan, tmp_path / "framed", port=port, block_samples=1)
    assert fast_stop.exit_status == framed_stop.exit_status == "success"
    assert fast_client._read_frames is not None and framed_client._read_frames is None  # the two paths
    a, b = _contents(fast), _contents(framed)
    _assert_same_file(a, b)
    assert len(a["samples/t"]) > 500 and any(e[1] == b"settled" or e[1] == b"not_settled" for e in a["events"])


OPEN_LOOP = """name: open-loop-stretches
load_g: 300
sampling_period_s: 0.1
defaults: {rate_turns_per_s: 4, accel_turns_per_s2: 40}
steps:
  - move_to: {turns: 5}
  - repeat:
      count: 12
      steps:
        - rotation_sequence: {targets_turns: [6, 7, 6, 5], hold_s: 0.2}
        - heater: {voltage_V: 1}
        - heater: {voltage_V: 0}
  - hold_until_settled: {max_duration_s: 3, window_s: 1, max_dL_dt_mm_per_s: 1.0}
  - repeat:
      count: 10
      steps:
        - rotation_sequence: {targets_turns: [6, 5], hold_s: 0.3}
  - prompt: {text: "hang 500 g", load_g: 500}
  - repeat:
      count: 10
      steps:
        - rotation_sequence: {targets_turns: [7, 5], hold_s: 0.1}
  - hold: {duration_s: 5}
"""


def test_batched_delivery_records_the_same_file_as_the_framed_path(tmp_path):
    """Long open-loop stretches (where sim:// delivers in batches) around a settling hold
    and a prompt (where it must not): the same file as frame by frame over bytes."""
    plan = plan_from_text(OPEN_LOOP)
    (tmp_path / "fast").mkdir()
    (tmp_path / "framed").mkdir()
    fast_port = open_sim(5)
    fast_stop, _, fast = run_plan(plan, tmp_path / "fast", port=fast_port)
    framed_stop, _, framed = run_plan(plan, tmp_path / "framed", port=BytesOnly(open_sim(5)), block_samples=1)
    assert fast_stop.exit_status == framed_stop.exit_status == "success"
    assert fast_port.batched_steps >= 10          # batching was on for a good part of the run
    a, b = _contents(fast), _contents(framed)
    _assert_same_file(a, b)
    assert len(a["segments"]) == len(plan.segments)


def test_the_writers_running_statistics_match_the_file(tmp_path):
    writer = RunWriter(tmp_path / "run.h5")
    stop, _, path = run_plan(plan_from_text(PLAN), tmp_path, seed=4, writer=writer)
    assert stop.exit_status == "success"
    kept, read = writer.summary(), inspect_run(path)
    assert format_run_info(kept) == format_run_info(read)
    assert kept.n_samples == read.n_samples and kept.counter_gaps == read.counter_gaps == 0
    for name, c in read.columns.items():
        k = kept.columns[name]
        assert (k.count, k.finite) == (c.count, c.finite), name
        assert np.allclose([k.min, k.max, k.mean], [c.min, c.max, c.mean], rtol=1e-12, equal_nan=True), name
    assert BENCH.name  # the shipped simulated bench ran


SPARSE = """name: sparse-samples
load_g: 300
sampling_period_s: 5
defaults: {rate_turns_per_s: 4, accel_turns_per_s2: 40}
steps:
  - move_to: {turns: 3}
  - hold: {duration_s: 40}
  - repeat:
      count: 40
      steps:
        - rotation_sequence: {targets_turns: [4, 3], hold_s: 0.5}
  - hold: {duration_s: 20}
"""


def test_in_process_the_watchdog_is_kept_by_the_device_clock_with_few_heartbeats(tmp_path):
    """Samples 5 s apart (their timestamps say little about the device clock) through long
    holds and batched stretches: the in-process runner heartbeats by the device's own
    clock, so the 2 s watchdog never trips, and the commands that feed the queue make
    most heartbeats unnecessary."""
    port = open_sim(8)
    heartbeats = []
    real = port.write_frame

    def counting(data, seq, message):
        heartbeats.append(type(message).__name__ == "Heartbeat")
        return real(data, seq, message)

    port.write_frame = counting
    stop, client, path = run_plan(plan_from_text(SPARSE), tmp_path, port=port)
    assert stop.exit_status == "success", stop.reason
    device_s = stop.t_end
    assert device_s > 100 and port.device.fault == 0
    # at most one heartbeat per half watchdog (1 s) of device time, and far fewer frames than reads
    assert 0 < sum(heartbeats) <= device_s / 1.0
