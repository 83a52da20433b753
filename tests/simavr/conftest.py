"""Fixtures for the firmware-in-the-loop tests: the ELF and harness built once, and
ports onto the simulated device and onto the firmware in simavr."""

from __future__ import annotations

import subprocess
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tsa_bench.bench import load_bench
from tsa_bench.protocol import MessageDecoder, msg
from tsa_bench.bench.simavr_section import SimavrSettings
from tsa_bench.simavr import SimavrBench

ROOT = Path(__file__).resolve().parents[2]
SIMAVR_BENCH = load_bench(ROOT / "configs" / "bench" / "simavr.yaml")


@pytest.fixture(scope="session")
def firmware_dir() -> Path:
    """firmware/ with build/tsa_bench.elf and build/tsa_simavr up to date."""
    fw = ROOT / "firmware"
    result = subprocess.run(["make", "-C", str(fw), "harness"], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
    return fw


@contextmanager
def simavr_port(firmware_dir: Path, **settings):
    """(port, bench) on the firmware in simavr, after its BOOT (kept as
    ``bench.boot_message``); the bench's ``summary`` is filled once the block exits."""
    with SimavrBench(SIMAVR_BENCH, SimavrSettings(firmware_dir=firmware_dir, build=False, **settings),
                     seed=1) as bench:
        port = serial.Serial(bench.port_path, 250000, timeout=0.02)
        try:
            bench.start()
            # As on a real board, host bytes before the device is up are lost (the UART
            # receives before interrupts are on): wait for BOOT, as BenchClient does.
            decoder, deadline = MessageDecoder(), time.monotonic() + 10
            bench.boot_message = None
            while bench.boot_message is None:
                assert time.monotonic() < deadline, "no BOOT from the firmware in simavr"
                boots = [f.message for f in decoder.feed(port.read(64)) if isinstance(f.message, msg.Boot)]
                bench.boot_message = boots[0] if boots else None
            yield port, bench
        finally:
            port.close()


def sim_port():
    return serial.serial_for_url("sim://?seed=1", timeout=0)
