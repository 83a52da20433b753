"""Scripted host for the simulated-device tests: speaks encoded frames to a SimDevice."""

from __future__ import annotations

from typing import NamedTuple

from tsa_bench.protocol import MessageDecoder, encode, msg
from tsa_bench.sim import SimDevice

HELLO = msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH)


class Host:
    """Drives a :class:`SimDevice` with encoded frames and decodes everything it says.

    ``frames`` keeps every decoded device frame (seq and message), in order.
    """

    def __init__(self, device: SimDevice) -> None:
        self.dev = device
        self.seq = 0
        self._dec = MessageDecoder()
        self.frames: list = []
        self.last_tx_s = device.now_s

    def _collect(self) -> list[NamedTuple]:
        frames = self._dec.feed(self.dev.take_output())
        assert not self._dec.errors, self._dec.errors
        self.frames.extend(frames)
        return [f.message for f in frames]

    def send(self, message: NamedTuple, seq: int | None = None) -> list[NamedTuple]:
        """Send one command; return what the device answered at once."""
        if seq is None:
            self.seq = (self.seq + 1) & 0xFFFF
            seq = self.seq
        self.dev.receive(encode(message, seq))
        self.last_tx_s = self.dev.now_s
        return self._collect()

    def send_bytes(self, data: bytes) -> list[NamedTuple]:
        self.dev.receive(data)
        if data:
            self.last_tx_s = self.dev.now_s
        return self._collect()

    def ack(self, message: NamedTuple, seq: int | None = None) -> msg.Ack:
        """Send and return the ACK (there must be exactly one)."""
        acks = [m for m in self.send(message, seq) if isinstance(m, msg.Ack)]
        assert len(acks) == 1, acks
        return acks[0]

    def run(self, duration_s: float, heartbeat_s: float | None = 0.5) -> list[NamedTuple]:
        """Advance ``duration_s`` of virtual time, heartbeating whenever the host has been
        silent for ``heartbeat_s`` (None: never). Heartbeat replies are left out.
        """
        end = self.dev.now_s + duration_s
        out: list[NamedTuple] = []
        while self.dev.now_s < end - 1e-12:
            if heartbeat_s is not None and self.dev.now_s - self.last_tx_s >= heartbeat_s - 1e-12:
                self.send(msg.Heartbeat())
            limit = end - self.dev.now_s
            if heartbeat_s is not None:
                limit = min(limit, self.last_tx_s + heartbeat_s - self.dev.now_s)
            self.dev.advance(max(limit, 0.0), 1 << 20)
            out.extend(self._collect())
        return out

    def run_until(self, predicate, max_s: float = 60.0, heartbeat_s: float | None = 0.5) -> list[NamedTuple]:
        """Run in 0.1 s steps until a message satisfies ``predicate``; return all seen."""
        seen: list[NamedTuple] = []
        end = self.dev.now_s + max_s
        while self.dev.now_s < end:
            chunk = self.run(0.1, heartbeat_s)
            seen.extend(chunk)
            if any(predicate(m) for m in chunk):
                return seen
        raise AssertionError(f"condition not met within {max_s} s; last messages {seen[-5:]}")


def events(messages, kind: msg.EventKind | None = None) -> list[msg.Event]:
    return [m for m in messages if isinstance(m, msg.Event) and (kind is None or m.kind == kind)]


def samples(messages) -> list[msg.Sample]:
    return [m for m in messages if isinstance(m, msg.Sample)]
