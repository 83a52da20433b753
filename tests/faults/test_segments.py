"""The segment index of every stored sample over a real link: frames swapped and delayed,
at segment boundaries above all (the worst instant: the last sample of a segment after
its SEGMENT_DONE, the next segment's samples before its SEGMENT_STARTED), on the
simulated bench over a pty and on the firmware; and a plan longer than the 16-bit wire
field. Every stored index is a segment of the plan and the one the device named, never
one 65,535 away (scripts/link_campaign.py runs 60 of the relay runs)."""

from __future__ import annotations

import sys

import h5py
import numpy as np
import pytest

from tests.faults.checks import check_rows_against_device
from tests.faults.ptybench import quick_bench, relayed_sim
from tests.faults.relay import REORDER, FaultyPort, LinkFaults
from tests.faults.test_link_firmware import native_binary  # noqa: F401 (fixture)
from tests.faults.test_real_link import _run_over
from tests.firmware.native_port import NativeFirmwarePort
from tests.runner.helpers import BENCH, plan_from_text, run_plan
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

#: Many short segments, instant ones among them: a boundary every ~0.1 s of device time.
BOUNDARIES = """name: boundaries
sampling_period_s: {period}
defaults: {{rate_turns_per_s: 5, accel_turns_per_s2: 50}}
steps:
  - repeat:
      count: 12
      steps:
        - move_by: {{turns: 0.5}}
        - hold: {{duration_s: 0.1}}
        - heater: {{voltage_V: 1}}
        - hold: {{duration_s: 0.06}}
        - heater: {{voltage_V: 0}}
        - move_by: {{turns: -0.5}}
"""


def _moved(stats) -> int:
    return stats["boundary_before"] + stats["boundary_event"]


@pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty")
@pytest.mark.parametrize("seed", [31, 32])
def test_frames_reordered_at_segment_boundaries_over_a_pty_keep_every_segment_index(tmp_path, seed):
    bench = load_bench(quick_bench(tmp_path))
    plan = plan_from_text(BOUNDARIES.format(period=0.02))
    with relayed_sim(quick_bench(tmp_path), LinkFaults(to_host=REORDER, seed=seed)) as relay:
        stop = _run_over(relay, bench, plan, tmp_path / "r.h5")
        device_samples = relay.link.device_frames.samples()
    assert stop.exit_status == "success", stop.reason
    stats = relay.link.stats["to_host"]
    assert _moved(stats) > 20 and stats["delayed"] > 5 and stats["swapped"] > 5, stats
    counts = check_rows_against_device(tmp_path / "r.h5", device_samples)
    assert counts["rows"] > 100


@pytest.mark.parametrize("period", [0.02, 0.002326])
def test_frames_reordered_at_segment_boundaries_on_the_firmware_keep_every_segment_index(
        native_binary, tmp_path, period):  # noqa: F811
    """The firmware sends a segment's EVENTs as they happen and its samples in blocks of
    up to six (continuous sampling, every other conversion: 2.326 ms): without any fault a segment's last samples
    already reach the host after its SEGMENT_DONE."""
    port = FaultyPort(NativeFirmwarePort(native_binary, "--virtual"), LinkFaults(to_host=REORDER, seed=41))
    try:
        client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s, watchdog_s=BENCH.watchdog_s)
        client.connect(2.0)
        stop = Runner(client, plan_from_text(BOUNDARIES.format(period=period)), BENCH,
                      [RunWriter(tmp_path / "fw.h5")], AutoOperator(), backend="native", port_name="native").run()
    finally:
        port.close()
    assert stop.exit_status == "success", stop.reason
    assert _moved(port.link.stats["to_host"]) > 20
    counts = check_rows_against_device(tmp_path / "fw.h5", port.link.device_frames.samples())
    assert counts["rows"] > 100


WRAP = """name: past-the-wire-wrap
sampling_period_s: 0.01
defaults: {rate_turns_per_s: 2, accel_turns_per_s2: 20}
steps:
  - heater: {voltage_V: 0}
  - move_to: {turns: 0}
  - repeat:
      count: 32800
      steps:
        - hold: {duration_s: 0.004}
        - hold: {duration_s: 0.003}
  - hold: {duration_s: 0.05}
"""


def test_a_plan_past_the_16_bit_wire_field_stores_every_sample_in_its_segment(tmp_path):
    """65,603 segments (indices travel modulo 65,535): each sample is stored with the
    segment that ran when it was taken (by the device's own segment start times), up to
    the last; no QUEUE_EMPTY of the first, instant segments is taken for an underrun
    (they were recorded "after segment 65535/65536" at t = 0 in the 10x lifetime run)."""
    plan = plan_from_text(WRAP)
    n = len(plan.segments)
    assert n > 65_536
    stop, _, path = run_plan(plan, tmp_path)
    assert stop.exit_status == "success", stop.reason
    with h5py.File(path) as f:
        t, seg = f["samples"]["t"][()], f["samples"]["segment"][()].astype(np.int64)
        segments = f["segments"][()]
        events = f["events"][()]
    assert np.all((seg >= -1) & (seg < n)), np.unique(seg[(seg < -1) | (seg >= n)])[:5]
    assert len(segments) == n
    start = np.full(n + 1, np.inf)
    start[segments["index"]] = segments["t_start"]
    mine = seg >= 0
    k = seg[mine]
    # taken in its segment: after that segment started and not after the next one started
    assert np.all(t[mine] >= start[k] - 1e-9) and np.all(t[mine] <= start[k + 1] + 1e-9)
    assert k.max() == n - 1 and np.any(k > 65_535)   # samples on both sides of the wrap, to the end
    assert not np.any(events["kind"] == b"queue_underrun"), events[events["kind"] == b"queue_underrun"][:3]


def test_a_segment_index_outside_the_plan_is_never_stored(tmp_path, monkeypatch):
    """The runner's last check before a block reaches the writer: a sample naming a
    segment the plan does not have (a host bug) is stored as -1, its data kept, and the
    run ends failed saying so."""
    from tsa_bench.runner import engine

    real = engine.sample_block
    state = {"blocks": 0}

    def shifted(*args, **kwargs):
        block = real(*args, **kwargs)
        state["blocks"] += 1
        if state["blocks"] == 2:
            block.columns["segment"][:3] += 65_535   # the old unwrap's mistake
        return block

    monkeypatch.setattr(engine, "sample_block", shifted)
    plan = plan_from_text(BOUNDARIES.format(period=0.02))
    stop, _, path = run_plan(plan, tmp_path, block_samples=16)
    assert stop.exit_status == "failed" and "outside the plan" in stop.reason, stop.reason
    with h5py.File(path) as f:
        seg = f["samples"]["segment"][()]
        assert len(seg) == stop.samples   # nothing dropped
    assert seg.max() < len(plan.segments) and seg.min() >= -1
