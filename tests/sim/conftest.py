"""Fixtures for the simulated-device tests."""

from __future__ import annotations

import pytest
from simhost import HELLO, Host

from tsa_bench.bench import load_bench
from tsa_bench.benchdata import BenchConfig
from tsa_bench.protocol import msg
from tsa_bench.sim import SimDevice


@pytest.fixture
def bench() -> BenchConfig:
    return load_bench(None)


@pytest.fixture
def device(bench: BenchConfig) -> SimDevice:
    return SimDevice(bench, seed=0)


@pytest.fixture
def host(device: SimDevice) -> Host:
    """A host that has done the handshake and declared the twist zero (SET_POSITION 0),
    as the runner does on a device whose position is unknown (the BOOT, IDENTITY and
    that ACK are consumed)."""
    h = Host(device)
    device.boot()
    h.send(HELLO)
    h.send(msg.SetPosition(0))
    h.frames.clear()
    return h
