"""The device's watchdog fed from a thread of its own (tsa_bench.device.keepalive): a host
whose main thread stalls for 3 s (a consumer that sleeps: a slow flush, a slow disk, a
loaded machine) keeps a healthy run healthy on a wall-clock device; a host stalled past
the keepalive's limit is left to the device's watchdog; an operator prompt of any length
is not a stall; the thread ends on every way out of a run, and STOP still goes out."""

from __future__ import annotations

import os
import re
import signal
import sys
import threading
import time

import h5py
import numpy as np
import pytest
import serial

from tests.faults.checks import check_rows_against_device
from tests.faults.ptybench import quick_bench, relayed_sim
from tests.faults.relay import FaultyPort, LinkFaults
from tests.faults.test_link_firmware import native_binary  # noqa: F401 (fixture)
from tests.firmware.native_port import NativeFirmwarePort
from tests.runner.helpers import BENCH, plan_from_text
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.protocol import msg
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

#: 60 holds of 0.05 s: the device's 16-command queue lasts 0.8 s, less than the stall,
#: and the plan lasts longer than the first 1.5 s (the host has more to send when it stalls).
HOLDS = """name: holds
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 5, accel_turns_per_s2: 50}
steps:
  - move_to: {turns: 1}
  - repeat:
      count: 60
      steps:
        - hold: {duration_s: 0.05}
  - move_to: {turns: 0}
"""


class Stall:
    """A consumer that sleeps ``stall_s`` in its first sample block after ``after_s`` of
    device time (the main thread is then busy: no read, no command, no heartbeat)."""

    def __init__(self, stall_s: float, after_s: float = 0.5) -> None:
        self.stall_s, self.after_s = stall_s, after_s
        self.stalled_at: float | None = None

    def on_samples(self, block) -> None:
        if self.stalled_at is None and len(block) and block.columns["t"][-1] >= self.after_s:
            self.stalled_at = float(block.columns["t"][-1])
            time.sleep(self.stall_s)

    def on_start(self, _) -> None: ...
    def on_segment(self, _) -> None: ...
    def on_event(self, _) -> None: ...
    def on_stop(self, _) -> None: ...


def _keepalive_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "tsa-bench keepalive"]


def _on_firmware(binary, tmp_path, consumer, plan_text=HOLDS, operator=None):
    """The run on the firmware core keeping wall-clock time (its watchdog is real)."""
    port = FaultyPort(NativeFirmwarePort(binary, "--speed", "1"), LinkFaults())
    try:
        client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s, watchdog_s=BENCH.watchdog_s)
        client.connect(2.0)
        stop = Runner(client, plan_from_text(plan_text), BENCH, [RunWriter(tmp_path / "fw.h5"), consumer],
                      operator or AutoOperator(), backend="native", port_name="native").run()
    finally:
        port.close()
    return stop, port


def test_a_main_thread_stalled_for_3_s_keeps_the_run_healthy(native_binary, tmp_path):  # noqa: F811
    stall = Stall(3.0)
    stop, port = _on_firmware(native_binary, tmp_path, stall)
    assert stall.stalled_at is not None
    assert stop.exit_status == "success", stop.reason
    check_rows_against_device(tmp_path / "fw.h5", port.link.device_frames.samples())
    with h5py.File(tmp_path / "fw.h5") as f:
        events = f["events"][()]
        n = int(f.attrs["n_segments"])
    # the device ran its queue dry meanwhile: an underrun, after a segment of the plan
    underruns = [e["detail"].decode() for e in events if e["kind"] == b"queue_underrun"]
    assert underruns, "the 3 s stall outlasted the 0.8 s queue: the device must have run dry"
    for detail in underruns:
        idx = int(detail.split("after segment ")[1].split()[0])
        assert 0 <= idx < n - 1, detail
    assert not _keepalive_threads()


def test_a_host_stalled_past_the_keepalive_limit_is_left_to_the_device_watchdog(
        native_binary, tmp_path, monkeypatch):  # noqa: F811
    """The keepalive is for a host that is alive: stalled longer than its limit (here 1 s)
    it stops, and the device stops motor and heater itself after its 2 s watchdog."""
    monkeypatch.setattr("tsa_bench.device.keepalive.MAX_STALL_S", 1.0)
    stop, port = _on_firmware(native_binary, tmp_path, Stall(4.0))
    assert stop.exit_status == "failed" and "watchdog" in stop.reason, stop.reason
    # the fault names the plan segment the device was in (the last one it ran, done
    # before the host read the fault: it was named 65,535 further on)
    named = re.search(r"\(segment (\d+)\)", stop.reason)
    assert named and int(named.group(1)) < len(plan_from_text(HOLDS).segments), stop.reason
    check_rows_against_device(tmp_path / "fw.h5", port.link.device_frames.samples())
    assert not _keepalive_threads()


def test_an_operator_prompt_longer_than_the_watchdog_is_not_a_stall(native_binary, tmp_path, monkeypatch):  # noqa: F811
    """The device samples while the operator changes the load: a 3 s answer (more than
    the watchdog, more than the keepalive's stall limit, here 1 s) keeps the run going."""
    monkeypatch.setattr("tsa_bench.device.keepalive.MAX_STALL_S", 1.0)
    text = HOLDS.replace("  - repeat:", "  - prompt: {text: hang 100 g, load_g: 100}\n  - repeat:")
    operator = SlowOperator(3.0)
    stop, port = _on_firmware(native_binary, tmp_path, Stall(0.0), text, operator)
    assert operator.prompts and stop.exit_status == "success", stop.reason
    with h5py.File(tmp_path / "fw.h5") as f:
        t = f["samples"]["t"][()]
        prompt_t = float(f["events"]["t"][f["events"]["kind"] == b"prompt"][0])
    assert np.any((t > prompt_t + 2.5) & (t < prompt_t + 3.0)), "the device kept sampling through the prompt"


class SlowOperator(AutoOperator):
    """Answers a prompt after ``answer_s`` (a person hanging a mass)."""

    def __init__(self, answer_s: float) -> None:
        super().__init__()
        self.answer_s = answer_s

    def answer(self, text: str, load_g: float | None) -> None:
        time.sleep(self.answer_s)
        super().answer(text, load_g)


class _Raising:
    def __init__(self, what: str) -> None:
        self.what, self.blocks = what, 0

    def on_samples(self, block) -> None:
        self.blocks += 1
        if self.blocks == 3:
            if self.what == "ctrl-c":
                os.kill(os.getpid(), signal.SIGINT)
            else:
                raise RuntimeError("a consumer bug")

    def on_start(self, _) -> None: ...
    def on_segment(self, _) -> None: ...
    def on_event(self, _) -> None: ...
    def on_stop(self, _) -> None: ...


@pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty")
@pytest.mark.parametrize("way", ["success", "ctrl-c", "host error", "dead line"])
def test_the_keepalive_thread_ends_on_every_way_out_and_stop_still_goes_out(tmp_path, way):
    bench = load_bench(quick_bench(tmp_path))
    plan = plan_from_text(HOLDS)
    consumers = [RunWriter(tmp_path / "r.h5")]
    if way in ("ctrl-c", "host error"):
        consumers.append(_Raising(way))
    faults = LinkFaults(stalls=((1.0, 30.0),)) if way == "dead line" else LinkFaults()  # a dead line
    with relayed_sim(quick_bench(tmp_path), faults, speed=1.0 if way == "dead line" else None) as relay:
        with serial.Serial(relay.path, bench.baud, timeout=0.05) as ser:
            client = BenchClient(ser, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
            client.connect(bench.boot_timeout_s)
            runner = Runner(client, plan, bench, consumers, AutoOperator(), backend="serial", port_name=relay.path,
                            block_samples=4)
            assert runner._keepalive is not None
            stop = runner.run()
        stops = relay.link.host_frames.count(msg.Stop)
    expected = {"success": "success", "ctrl-c": "aborted", "host error": "failed", "dead line": "failed"}[way]
    assert stop.exit_status == expected, stop.reason
    assert not runner._keepalive.running and not _keepalive_threads()
    if way in ("ctrl-c", "host error"):
        assert stops >= 1   # STOP reached the wire
