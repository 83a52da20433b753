"""Fault-injecting wrappers around a pyserial-like port, for reliability tests."""

from __future__ import annotations

import serial


class LossyPort:
    """Wraps a port: drops every ``drop_tx_every``-th host write, corrupts every
    ``corrupt_rx_every``-th chunk read from the device, or fails after ``fail_after_reads`` reads."""

    def __init__(self, port, *, drop_tx_every: int = 0, corrupt_rx_every: int = 0, fail_after_reads: int = 0):
        self._port = port
        self.drop_tx_every = drop_tx_every
        self.corrupt_rx_every = corrupt_rx_every
        self.fail_after_reads = fail_after_reads
        self.writes = self.reads = self.dropped = self.corrupted = 0

    def __getattr__(self, name):
        return getattr(self._port, name)

    @property
    def in_waiting(self) -> int:
        return self._port.in_waiting

    def write(self, data: bytes) -> int:
        self.writes += 1
        if self.drop_tx_every and self.writes % self.drop_tx_every == 0:
            self.dropped += 1
            return len(data)
        return self._port.write(data)

    def read(self, size: int = 1) -> bytes:
        self.reads += 1
        if self.fail_after_reads and self.reads > self.fail_after_reads:
            raise serial.SerialException("device disconnected (injected)")
        data = self._port.read(size)
        if self.corrupt_rx_every and data and self.reads % self.corrupt_rx_every == 0:
            self.corrupted += 1
            b = bytearray(data)
            b[len(b) // 2] ^= 0x5A
            if b[len(b) // 2] == 0:
                b[len(b) // 2] = 0x01
            data = bytes(b)
        return data
