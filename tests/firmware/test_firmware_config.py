"""The firmware's compiled-in constants agree with the bench file that describes the rig."""

from __future__ import annotations

import re

import pytest

from tsa_bench.bench import load_bench
from tsa_bench.protocol import msg

CONST = re.compile(r"static const \w+ (\w+) = (-?\d+)U?L?;")


def firmware_constants(repo_root) -> dict[str, int]:
    text = (repo_root / "firmware" / "config.h").read_text()
    return {name: int(value) for name, value in CONST.findall(text)}


@pytest.mark.parametrize("bench_file", ["arduino-mega.yaml", "simavr.yaml"])
def test_config_h_matches_the_firmware_bench_files(repo_root, bench_file):
    c = firmware_constants(repo_root)
    bench = load_bench(repo_root / "configs" / "bench" / bench_file)
    spt = bench.steps_per_turn
    assert c["STEPS_PER_TURN"] == spt
    assert c["MIN_TWIST_STEPS"] == round(bench.limits.min_twist_turns * spt)
    assert c["MAX_TWIST_STEPS"] == round(bench.limits.max_twist_turns * spt)
    assert c["MAX_RATE_STEPS_PER_S"] == round(bench.limits.max_rate_turns_per_s * spt)
    assert c["MAX_ACCEL_STEPS_PER_S2"] == round(bench.limits.max_accel_turns_per_s2 * spt)
    assert c["MAX_HEATER_MV"] == round(bench.limits.max_heater_voltage_V * 1000)
    assert c["QUEUE_SLOTS"] == bench.queue_slots
    assert c["WATCHDOG_MS"] == round(bench.watchdog_s * 1000)
    assert c["BAUD"] == bench.baud


def test_simulated_bench_reports_the_same_identity_as_the_firmware(repo_root):
    """The default simulated bench stands in for the real one: same limits and geometry."""
    from tsa_bench.sim.device import SimDevice

    c = firmware_constants(repo_root)
    ident = SimDevice(load_bench(None), seed=0).identity
    assert isinstance(ident, msg.Identity)
    assert (ident.steps_per_turn, ident.min_twist_steps, ident.max_twist_steps, ident.max_rate_steps_per_s,
            ident.max_accel_steps_per_s2, ident.max_heater_mV, ident.queue_slots, ident.watchdog_ms) == (
        c["STEPS_PER_TURN"], c["MIN_TWIST_STEPS"], c["MAX_TWIST_STEPS"], c["MAX_RATE_STEPS_PER_S"],
        c["MAX_ACCEL_STEPS_PER_S2"], c["MAX_HEATER_MV"], c["QUEUE_SLOTS"], c["WATCHDOG_MS"])


def test_simulated_device_constants_are_the_firmware_ones(repo_root):
    """The simulated device mirrors device properties no bench file holds: the sampling
    floor, the fault release time and the heater's duty scale."""
    from tsa_bench.sim import heater, identity

    c = firmware_constants(repo_root)
    assert identity.MIN_SAMPLING_PERIOD_US == c["MIN_SAMPLE_PERIOD_US"]
    assert identity.FAULT_RELEASE_MS == c["FAULT_RELEASE_MS"]
    assert heater.HEATER_SUPPLY_MV == c["HEATER_SUPPLY_MV"]
    assert heater.MAX_HEATER_MV == c["MAX_HEATER_MV"]
    scale = (repo_root / "firmware" / "drivers" / "heater_dither.h").read_text()
    assert f"HEATER_DUTY_STEPS = {heater.DUTY_STEPS};" in scale
    ident = _sim_identity()
    assert (ident.min_sample_period_us, ident.fault_release_ms) == (c["MIN_SAMPLE_PERIOD_US"], c["FAULT_RELEASE_MS"])


def _sim_identity():
    from tsa_bench.sim.device import SimDevice

    return SimDevice(load_bench(None), seed=0).identity
