"""Retransmission, duplicate suppression, gap recording, lost connection, device refusal."""

from __future__ import annotations

import h5py
import numpy as np

from tests.runner.faults import LossyPort
from tests.runner.helpers import open_sim, plan_from_text, run_plan
from tsa_bench.store import read_run

SHORT = """
name: short
steps:
  - move_to: {turns: 10, rate_turns_per_s: 2, accel_turns_per_s2: 20}
  - hold: {duration_s: 5}
  - move_by: {turns: 5, rate_turns_per_s: 2, accel_turns_per_s2: 20}
  - hold: {duration_s: 5}
  - repeat:
      count: 20
      steps:
        - move_by: {turns: 1, rate_turns_per_s: 2, accel_turns_per_s2: 20}
        - hold: {duration_s: 0.5}
        - move_by: {turns: -1, rate_turns_per_s: 2, accel_turns_per_s2: 20}
        - hold: {duration_s: 0.5}
  - move_to: {turns: 0, rate_turns_per_s: 2, accel_turns_per_s2: 20}
"""


def assert_executed_once_in_order(plan, path, end_tolerance_s: float = 0.05):
    """Every segment once, back to back, each as long as planned (a repeated DWELL or
    move would show as a gap or a stretched segment). ``end_tolerance_s`` bounds the
    error of the last segment's end time, which is only known to the next heartbeat's
    QUEUE_STATUS when its SEGMENT_DONE event was lost on the line."""
    segs = read_run(path).segments
    assert list(segs["index"]) == list(range(len(plan.segments)))
    planned = [s.action.duration_s if s.kind == "hold" else None for s in plan.segments]
    for row, hold_s in zip(segs, planned):
        if hold_s is not None:
            assert abs(row["t_end"] - row["t_start"] - hold_s) < 1e-5
    gaps = segs["t_start"][1:] - segs["t_end"][:-1]
    assert np.all(gaps >= -1e-9) and np.all(gaps < 0.05), f"largest gap {gaps.max():.3f} s"
    span = segs["t_end"][-1] - segs["t_start"][0]
    assert -0.05 < span - plan.summary().duration_s < end_tolerance_s


def test_dropped_commands_are_retransmitted(tmp_path):
    plan = plan_from_text(SHORT)
    port = LossyPort(open_sim(), drop_tx_every=5)
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "success", stop.reason
    assert port.dropped > 10 and client.retransmissions >= port.dropped
    assert_executed_once_in_order(plan, path)


def test_corrupted_device_frames_are_recorded_as_gaps(tmp_path):
    plan = plan_from_text(SHORT)
    port = LossyPort(open_sim(), corrupt_rx_every=7)
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "success", stop.reason
    assert port.corrupted > 0 and sum(client.frame_errors.values()) > 0
    # lost ACKs made the host retransmit commands the device had already executed:
    # the device recognised them and did not execute them again
    assert port._port.device.duplicates > 0
    # heartbeat every watchdog/8 = 0.25 s of device time, seen up to one 0.5 s sim quantum late
    assert_executed_once_in_order(plan, path, end_tolerance_s=0.8)
    with h5py.File(path) as f:
        counter = f["samples/counter"][()].astype(np.int64)
        events = f["events"][()]
        lost_attr = f.attrs["samples_lost"]
    gaps = int((np.diff(counter) - 1).sum())
    assert gaps > 0 and gaps == stop.samples_lost == lost_attr
    gap_events = [e for e in events if e["kind"] == b"sample_gap"]
    assert sum(int(e["detail"].split()[0]) for e in gap_events) == gaps


def test_lost_connection_fails_the_run_and_keeps_data(tmp_path):
    plan = plan_from_text(SHORT)
    port = LossyPort(open_sim(), fail_after_reads=300)
    stop, client, path = run_plan(plan, tmp_path, port=port)
    assert stop.exit_status == "failed" and "lost the connection" in stop.reason
    with h5py.File(path) as f:
        assert f.attrs["exit_status"] == "failed"
        assert "lost the connection" in f.attrs["reason"]
        assert len(f["samples/t"]) > 0


def test_device_refusal_fails_the_run_without_executing_it(tmp_path):
    """A plan beyond the device's own twist limit is refused by the device itself."""
    from tsa_bench.benchdata import Limits
    from tsa_bench.plan import load_plan_text

    plan = load_plan_text("name: far\nsteps:\n  - move_to: {turns: 150, rate_turns_per_s: 5, accel_turns_per_s2: 50}\n",
                          Limits(), "far.yaml")  # host-side limits switched off on purpose
    stop, client, path = run_plan(plan, tmp_path)
    assert stop.exit_status == "failed" and "limit_exceeded" in stop.reason
    with h5py.File(path) as f:
        turns = f["samples/turns"][()]
    assert len(turns) == 0 or np.abs(turns).max() == 0


class FaultAfter:
    """Lets the simulated device latch a hardware fault after some reads."""

    def __init__(self, port, reads: int, fault):
        self._port, self.reads, self.fault = port, reads, fault

    def __getattr__(self, name):
        return getattr(self._port, name)

    @property
    def in_waiting(self) -> int:
        return self._port.in_waiting

    def read(self, size: int = 1) -> bytes:
        self.reads -= 1
        if self.reads == 0:
            self._port.device.inject_fault(self.fault)
        return self._port.read(size)


def test_device_fault_fails_the_run_and_keeps_the_data(tmp_path):
    from tsa_bench.protocol import msg

    plan = plan_from_text(SHORT)
    stop, client, path = run_plan(plan, tmp_path, port=FaultAfter(open_sim(), 200, msg.Fault.POSITION_SENSOR))
    assert stop.exit_status == "failed" and "position_sensor" in stop.reason
    with h5py.File(path) as f:
        assert f.attrs["exit_status"] == "failed" and "position_sensor" in f.attrs["reason"]
        assert len(f["samples/t"]) > 10
        segs = f["segments"][()]
    assert 0 < len(segs) < len(plan.segments) and segs["completed"][:-1].all()


def test_a_failing_consumer_stops_the_device_and_the_file_still_closes(tmp_path):
    """A consumer that raises (a full disk, a bug) ends the run as failed after STOP."""
    from tsa_bench.device import BenchClient
    from tsa_bench.runner import AutoOperator, Runner
    from tsa_bench.rundocs import SampleBlock
    from tsa_bench.store import RunWriter
    from tests.runner.helpers import BENCH

    class Exploding:
        def __init__(self):
            self.blocks = 0

        def on_start(self, start): pass
        def on_segment(self, segment): pass
        def on_event(self, event): pass
        def on_stop(self, stop): raise RuntimeError("also broken at stop")

        def on_samples(self, block: SampleBlock):
            self.blocks += 1
            if (block.columns["heater_voltage"] > 0).any():   # during the heated hold, motor at rest
                raise OSError("No space left on device")

    plan = plan_from_text(SHORT.replace("- move_to: {turns: 0", "- heater: {voltage_V: 3}\n  - hold: {duration_s: 30}\n  - move_to: {turns: 0"))
    port = open_sim()
    client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s)
    client.connect(BENCH.boot_timeout_s)
    stop = Runner(client, plan, BENCH, [RunWriter(tmp_path / "r.h5"), Exploding()], AutoOperator(),
                  backend="sim", port_name="sim://", block_samples=1).run()  # a block per read
    assert stop.exit_status == "failed" and "No space left" in stop.reason
    assert port.device.executor.heater_mV == 0 and not port.device.active
    with h5py.File(tmp_path / "r.h5") as f:
        assert f.attrs["exit_status"] == "failed"


def test_segment_indices_unwrap_past_the_16_bit_wire_field():
    """Plan indices travel modulo 65535 (0xFFFF = no segment); the host restores them as
    the plan index nearest the oldest segment not done, across the wrap, ahead (queued)
    and behind (a late sample or event of a segment already done: never + 65535)."""
    from tsa_bench.runner.commands import NO_SEGMENT, WIRE_SEGMENTS, plan_segment

    n = 300_000
    for oldest in (0, 1, 5, 65_530, 65_534, 65_535, 65_536, 131_060, 200_000):
        for idx in range(max(0, oldest - 16), oldest + 16):
            assert plan_segment(idx % WIRE_SEGMENTS, oldest, n) == idx, (idx, oldest)
    assert plan_segment(NO_SEGMENT, 7, n) == -1
    assert plan_segment(21, 22, 22) == 21          # samples after the last segment of a 22-segment plan
    assert plan_segment(0, 1, 65_540) == 0         # QUEUE_EMPTY of segment 0 once segment 1 is the oldest
    assert plan_segment(30, 0, 22) == -1           # no segment of the plan
