"""Fixtures for the simulated-device tests."""

from __future__ import annotations

import pytest
from simhost import HELLO, Host

from tsa_bench.bench import BenchConfig, load_bench
from tsa_bench.sim import SimDevice


@pytest.fixture
def bench() -> BenchConfig:
    return load_bench(None)


@pytest.fixture
def device(bench: BenchConfig) -> SimDevice:
    return SimDevice(bench, seed=0)


@pytest.fixture
def host(device: SimDevice) -> Host:
    """A host that has done the handshake (the BOOT and IDENTITY are consumed)."""
    h = Host(device)
    device.boot()
    h.send(HELLO)
    return h
