"""Errors raised by the bench client; each message says what happened and what to check."""

from __future__ import annotations


class DeviceError(RuntimeError):
    """Base class for problems talking to a bench device."""


class DeviceNotFound(DeviceError):
    """Nothing answered the handshake on the port."""


class DeviceMismatch(DeviceError):
    """The device speaks another protocol version or catalogue."""


class ConnectionLost(DeviceError):
    """The port failed or the device fell silent mid-run."""


class CommandRefused(DeviceError):
    """The device answered a command with a negative acknowledgement."""

    def __init__(self, command: str, status: int, detail: str) -> None:
        super().__init__(detail)
        self.command = command
        self.status = status


class NoAcknowledgement(DeviceError):
    """A command was retransmitted the maximum number of times without an ACK."""
