"""Bench client: the host side of the framed protocol."""

from tsa_bench.device.client import BenchClient
from tsa_bench.device.errors import (
    CommandRefused, ConnectionLost, DeviceError, DeviceMismatch, DeviceNotFound, NoAcknowledgement,
)

__all__ = ["BenchClient", "CommandRefused", "ConnectionLost", "DeviceError", "DeviceMismatch", "DeviceNotFound",
           "NoAcknowledgement"]
