"""The firmware core (built natively, on a simulated board) against the simulated
device, which is the protocol's executable specification: the same exchanges get the
same answers, and the host's runner drives a whole plan on the firmware."""

from __future__ import annotations

import subprocess
import time

import h5py
import numpy as np
import pytest
import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tests.firmware.native_port import NativeFirmwarePort
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan_text
from tsa_bench.protocol import MessageDecoder, encode, encode_raw, msg
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

BENCH = load_bench(None)


@pytest.fixture(scope="module")
def native_binary(repo_root):
    result = subprocess.run(["make", "-C", "firmware", "native"], cwd=repo_root, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    return repo_root / "firmware" / "build" / "tsa_bench_native"


class Exchange:
    """Sends host frames to a device port and collects its replies (no SAMPLEs)."""

    def __init__(self, port, settle_s: float):
        self.port, self.settle_s = port, settle_s
        self.decoder = MessageDecoder()
        self.seq = 100

    def replies(self) -> list:
        out, deadline = [], time.monotonic() + self.settle_s
        while True:  # the simulated device answers at once; the firmware process within ms
            data = self.port.read(self.port.in_waiting or 1) if self.settle_s else self.port.read(4096)
            out += [f.message for f in self.decoder.feed(data)]
            if time.monotonic() >= deadline:
                break
        return [normalise(m) for m in out if not isinstance(m, (msg.Sample, msg.Boot))]

    def send(self, message=None, *, raw: bytes | None = None, seq: int | None = None) -> list:
        if seq is None:
            self.seq += 1
            seq = self.seq
        self.port.write(raw if raw is not None else encode(message, seq))
        return self.replies()


def normalise(m):
    """What must agree between firmware and simulation (not times, sensors or versions)."""
    if isinstance(m, msg.Ack):
        return ("ACK", m.acked_id, msg.Status(m.status).name, m.queue_free)
    if isinstance(m, msg.Identity):
        return ("IDENTITY", m.protocol_version, m.catalogue_hash, m.steps_per_turn, m.min_twist_steps,
                m.max_twist_steps, m.max_rate_steps_per_s, m.max_accel_steps_per_s2, m.max_heater_mV,
                m.queue_slots, m.watchdog_ms)
    if isinstance(m, msg.QueueStatus):
        return ("QUEUE_STATUS", m.queue_free, m.executing, m.segment, m.fault)
    if isinstance(m, msg.Event):
        return ("EVENT", msg.EventKind(m.kind).name, m.segment, m.code)
    return (type(m).__name__,)


def scenario(ex: Exchange) -> list:
    """A session touching every message and every refusal; returns all replies."""
    log = []
    log.append(ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH ^ 1)))
    log.append(ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH)))
    log.append(ex.send(msg.Heartbeat()))
    log.append(ex.send(raw=encode_raw(0x7E, 5, b"\x01\x02")))                  # unknown id
    log.append(ex.send(raw=encode_raw(0x10, 6, b"\x01\x02\x03")))  # bad length
    log.append(ex.send(msg.MoveTo(1, 10_000_000, 1000, 1000)))                # beyond max twist
    log.append(ex.send(msg.MoveTo(1, 1000, 0, 1000)))                         # zero rate
    log.append(ex.send(msg.MoveTo(1, 1000, 10**6, 1000)))                     # rate beyond max
    log.append(ex.send(msg.MoveBy(1, -10**6, 1000, 1000)))                    # projected below min
    log.append(ex.send(msg.SetHeater(1, 60_000)))                            # heater beyond max
    log.append(ex.send(msg.SetSampling(1, 500)))                              # period too short
    log.append(ex.send(msg.Dwell(2, 60_000_000), seq=4000))                   # starts at once
    log.append(ex.send(msg.Dwell(2, 60_000_000), seq=4000))                   # duplicate: same ACK again
    for i in range(17):                                                        # fill the queue, then one more
        log.append(ex.send(msg.Dwell(3 + i, 60_000_000)))
    log.append(ex.send(msg.ClearQueue()))
    log.append(ex.send(msg.Heartbeat()))
    log.append(ex.send(msg.Stop()))
    log.append(ex.send(msg.Heartbeat()))
    return log


def test_firmware_answers_like_the_simulated_device(native_binary):
    sim_port = serial.serial_for_url("sim://?seed=1", timeout=0)
    sim_log = scenario(Exchange(sim_port, settle_s=0))
    fw_port = NativeFirmwarePort(native_binary, "--speed", "1")
    try:
        fw_port.read(64)  # its BOOT
        fw_log = scenario(Exchange(fw_port, settle_s=0.08))
    finally:
        fw_port.close()
    assert len(fw_log) == len(sim_log)
    for i, (fw, sim) in enumerate(zip(fw_log, sim_log)):
        assert fw == sim, f"exchange {i}: firmware {fw} != simulated device {sim}"
    # the scenario really exercised the refusals
    statuses = {r[2] for step in sim_log for r in step if r[0] == "ACK"}
    assert {"OK", "QUEUE_FULL", "BAD_ARGUMENT", "LIMIT_EXCEEDED", "UNKNOWN_MESSAGE", "BAD_LENGTH"} <= statuses


def test_runner_drives_a_plan_on_the_firmware_core(native_binary, tmp_path):
    plan = load_plan_text("""name: on-firmware
load_g: 300
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - move_to: {turns: 10}
  - hold: {duration_s: 2}
  - heater: {voltage_V: 4}
  - hold: {duration_s: 1}
  - heater: {voltage_V: 0}
  - prompt: {text: "hang 400 g", load_g: 400}
  - move_by: {turns: -4}
  - hold: {duration_s: 1}
  - move_to: {turns: 0}
""", BENCH.limits, "on-firmware.yaml")
    port = NativeFirmwarePort(native_binary, "--virtual")
    try:
        client = BenchClient(port, ack_timeout_s=0.25)
        client.connect(1.0)
        stop = Runner(client, plan, BENCH, [RunWriter(tmp_path / "fw.h5")], AutoOperator(),
                      backend="native", port_name=port.port).run()
    finally:
        port.close()
    assert stop.exit_status == "success", stop.reason
    with h5py.File(tmp_path / "fw.h5") as f:
        segs = f["segments"][()]
        turns, seg, heater = f["samples/turns"][()], f["samples/segment"][()], f["samples/heater_voltage"][()]
        resistance = f["samples/resistance"][()]
    assert list(segs["index"]) == list(range(len(plan.segments))) and segs["completed"].all()
    holds = segs[segs["kind"] == b"hold"]
    assert np.allclose(holds["t_end"] - holds["t_start"], [2, 1, 1], atol=1e-3)
    assert np.allclose(turns[seg == 1], 10) and np.allclose(turns[seg == 7], 6)
    assert np.all(np.isnan(resistance[heater > 0])) and np.all(np.isfinite(resistance[heater == 0]))
    assert stop.samples_lost == 0
