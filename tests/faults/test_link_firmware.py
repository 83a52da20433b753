"""The relay between the host and the firmware core built natively (the real C++ frame,
queue, watchdog and sampling code on a simulated board)."""

from __future__ import annotations

import subprocess

import pytest

from tests.faults.checks import check_rows_against_device
from tests.faults.relay import CAMPAIGN, FaultyPort, LinkFaults
from tests.firmware.native_port import NativeFirmwarePort
from tests.runner.helpers import BENCH, plan_from_text
from tsa_bench.device import BenchClient
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

PLAN = """name: on-firmware
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - move_to: {turns: 5}
  - hold: {duration_s: 2}
  - heater: {voltage_V: 3}
  - hold: {duration_s: 1}
  - heater: {voltage_V: 0}
  - move_by: {turns: -3}
  - hold: {duration_s: 1}
  - move_to: {turns: 0}
"""


@pytest.fixture(scope="module")
def native_binary(repo_root):
    result = subprocess.run(["make", "-C", "firmware", "native"], cwd=repo_root, capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    return repo_root / "firmware" / "build" / "tsa_bench_native"


def _run(native_binary, tmp_path, faults: LinkFaults, *args: str):
    port = FaultyPort(NativeFirmwarePort(native_binary, *args), faults)
    try:
        client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s, watchdog_s=BENCH.watchdog_s)
        client.connect(2.0)
        path = tmp_path / "fw.h5"
        stop = Runner(client, plan_from_text(PLAN), BENCH, [RunWriter(path)], AutoOperator(),
                      backend="native", port_name="native").run()
    finally:
        port.close()
    return stop, port, path


@pytest.mark.parametrize("seed", [11, 12])
def test_campaign_faults_on_the_firmware_store_only_what_it_sent(native_binary, tmp_path, seed):
    stop, port, path = _run(native_binary, tmp_path, LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, seed=seed),
                            "--virtual")
    assert stop.exit_status == "success", stop.reason
    counts = check_rows_against_device(path, port.link.device_frames.samples())
    assert counts["rows"] > 100 and port.link.stats["to_host"]["dropped"] > 0


def test_a_wall_clock_stall_of_1_5_s_on_the_firmware_does_not_fail_the_run(native_binary, tmp_path):
    """The firmware keeps wall-clock time (--speed 1): 1.5 s without a byte either way is
    within its 2 s watchdog, so neither it nor the host (retrying for the watchdog
    period) may end the run."""
    stop, port, path = _run(native_binary, tmp_path, LinkFaults(stalls=((2.0, 1.5),), seed=13), "--speed", "1")
    assert stop.exit_status == "success", stop.reason
    assert port.link.now_s() > 3.5  # the run outlasted the stall
    check_rows_against_device(path, port.link.device_frames.samples())
