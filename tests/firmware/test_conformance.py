"""The firmware core (built natively, on a simulated board) against the simulated
device, which is the protocol's executable specification: the same exchanges get the
same answers, and the host's runner drives a whole plan on the firmware."""

from __future__ import annotations

import os
import signal
import subprocess
import threading

import h5py
import numpy as np
import pytest
import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tests.conformance_scenarios import Exchange, every_command_and_refusal
from tests.firmware.native_port import NativeFirmwarePort
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan_text
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter, read_run

BENCH = load_bench(None)


@pytest.fixture(scope="module")
def native_binary(repo_root):
    result = subprocess.run(["make", "-C", "firmware", "native"], cwd=repo_root, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    return repo_root / "firmware" / "build" / "tsa_bench_native"


def test_firmware_answers_like_the_simulated_device(native_binary):
    sim_port = serial.serial_for_url("sim://?seed=1", timeout=0)
    sim_ex = Exchange(sim_port, settle_s=0)
    sim_log = every_command_and_refusal(sim_ex)
    fw_port = NativeFirmwarePort(native_binary, "--speed", "1")
    try:
        fw_port.read(64)  # its BOOT
        # as many replies as the simulated device gave at each step, however busy the machine
        fw_log = every_command_and_refusal(Exchange(fw_port, settle_s=0.05, follows=sim_ex))
    finally:
        fw_port.close()
    assert len(fw_log) == len(sim_log)
    for i, (fw, sim) in enumerate(zip(fw_log, sim_log)):
        assert fw == sim, f"exchange {i}: firmware {fw} != simulated device {sim}"
    # the scenario really exercised the refusals
    statuses = {r[2] for step in sim_log for r in step if r[0] == "ACK"}
    assert {"OK", "QUEUE_FULL", "BAD_ARGUMENT", "LIMIT_EXCEEDED", "UNKNOWN_MESSAGE", "BAD_LENGTH"} <= statuses


class _SlowFirmware:
    """The native firmware's port, the firmware frozen (SIGSTOP) for ``stall_s`` after every
    write: a machine so busy that no reply comes within a fixed window of wall time."""

    def __init__(self, port: NativeFirmwarePort, stall_s: float) -> None:
        self.port, self.stall_s = port, stall_s

    def __getattr__(self, name):
        return getattr(self.port, name)

    def write(self, data: bytes) -> int:
        os.kill(self.port.proc.pid, signal.SIGSTOP)
        threading.Timer(self.stall_s, os.kill, (self.port.proc.pid, signal.SIGCONT)).start()
        return self.port.write(data)


def test_firmware_answers_alike_when_the_machine_is_busy(native_binary):
    """Issue 35, defect 6: every reply 0.15 s late (the firmware frozen after each frame):
    the exchange waits for as many replies as the simulated device gave, not for a quiet
    window, so the logs still agree (a fixed 80 ms window read the replies one step late)."""
    sim_ex = Exchange(serial.serial_for_url("sim://?seed=1", timeout=0), settle_s=0)
    sim_log = every_command_and_refusal(sim_ex)
    fw_port = NativeFirmwarePort(native_binary, "--speed", "1")
    try:
        fw_port.read(64)  # its BOOT
        fw_log = every_command_and_refusal(Exchange(_SlowFirmware(fw_port, 0.15), settle_s=0.05, follows=sim_ex))
    finally:
        os.kill(fw_port.proc.pid, signal.SIGCONT)
        fw_port.close()
    assert fw_log == sim_log


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
        turns, seg, heater = f["samples/turns"][()], f["samples/segment"][()], f["samples/heater_voltage"][()]
        resistance = f["samples/resistance"][()]
    segs = read_run(tmp_path / "fw.h5").segments
    assert list(segs["index"]) == list(range(len(plan.segments))) and segs["completed"].all()
    holds = segs[segs["kind"] == b"hold"]
    assert np.allclose(holds["t_end"] - holds["t_start"], [2, 1, 1], atol=1e-3)
    assert np.allclose(turns[seg == 1], 10) and np.allclose(turns[seg == 7], 6)
    assert np.all(np.isnan(resistance[heater > 0])) and np.all(np.isfinite(resistance[heater == 0]))
    assert stop.samples_lost == 0


@pytest.mark.parametrize("scenario", ["stop_at_speed", "heater_applied"])
def test_firmware_core_agrees_on_the_new_behaviours(native_binary, scenario):
    """The controlled stop and the applied heater voltage, on the firmware core built
    natively against the simulated device."""
    from tests import conformance_scenarios as sc

    run = getattr(sc, scenario)
    sim_ex = Exchange(serial.serial_for_url("sim://?seed=1", timeout=0), settle_s=0)
    sim = run(sim_ex)
    fw_port = NativeFirmwarePort(native_binary, "--virtual")
    try:
        fw_port.read(64)  # its BOOT
        fw = run(Exchange(fw_port, settle_s=0.05, follows=sim_ex))
    finally:
        fw_port.close()
    assert fw["log"] == sim["log"]
    if scenario == "stop_at_speed":
        for obs in (sim, fw):
            assert obs["stopped_once"] and obs["ends_at_rest_value"]
            assert 300 <= obs["coasted_steps"] <= 700          # ~400 steps of deceleration (+ sample lag)
    else:
        from tsa_bench.sim.heater import applied_mV

        assert fw["reported_mV"] == sim["reported_mV"] == [applied_mV(v) for v in sc.HEATER_REQUESTS_MV]
        assert sim["reported_mV"][0] == 1984 and sim["reported_mV"][1] == 992   # 2 V, 1 V: not off, not 2.12 V
        assert fw["off_mV"] == sim["off_mV"] == 0


def test_firmware_core_samples_continuously_like_the_simulated_device(native_binary):
    """One ADS1115 conversion as the period: both send 860 samples/s in SAMPLE_BLOCK
    frames without a counter gap, with resistance words at the CS5513's rate."""
    from tests import conformance_scenarios as sc

    sim_ex = Exchange(serial.serial_for_url("sim://?seed=1", timeout=0), settle_s=0)
    sim = sc.continuous_sampling(sim_ex)
    fw_port = NativeFirmwarePort(native_binary, "--virtual", "--cs5513-us", "19125")
    try:
        fw_port.read(64)  # its BOOT
        fw = sc.continuous_sampling(Exchange(fw_port, settle_s=0.05, follows=sim_ex))
    finally:
        fw_port.close()
    assert fw["log"] == sim["log"]
    for obs in (sim, fw):
        assert obs["continuous"] and obs["samples"] > 700
        assert obs["rate_per_s"] == pytest.approx(860, rel=0.01)
        assert obs["blocks"] <= obs["samples"] / 6 + 2
        assert obs["resistance_per_s"] == pytest.approx(52.3, rel=0.1)
