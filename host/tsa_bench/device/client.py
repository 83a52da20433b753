"""Bench client: the host end of the framed protocol over any pyserial-like port.

Contract: ``connect()`` waits for the device's BOOT announcement (opening a real
Mega's port resets it through DTR), discards stale input, and completes the
HELLO/IDENTITY handshake, refusing a device with another protocol version or
catalogue. ``command()`` sends one host command with a fresh sequence number and
waits for its ACK, retransmitting the identical frame on timeout (the device
recognises the repeated sequence number and does not execute it twice) for as long
as the device's watchdog could still be waiting for it (the retry budget: the
watchdog period plus two ACK timeouts; IDENTITY's ``watchdog_ms``, the bench file's
``watchdog_s`` before the handshake, in wall time: after a busy spell of the host, what
waited in the port spans device time the device did not spend waiting), so a line that
stalls for less than the watchdog never fails a command. Every other message that arrives meanwhile is kept,
in order, for ``poll()``. A port that offers ``read_frames``/``write_frame`` (``sim://``: the simulated device
in this process) hands over decoded frames instead of bytes, read in the same sizes.
Device frames pass the link layer first
(:class:`~tsa_bench.device.link.FrameSequencer`): duplicates are dropped and
reordered frames put back in order; its counters are :attr:`BenchClient.link`.
The client never sleeps on wall time except while waiting for bytes from the port;
``on_wait`` (if set) is called while it waits, so a caller can break a long wait
(the runner raises KeyboardInterrupt from it when the user asked to stop).
Each QUEUE_STATUS that answers a HEARTBEAT is a clock sample ``(sent_s, received_s,
device_us)`` (host ``time.monotonic`` at the HEARTBEAT's last transmission and at the
reply's arrival, the device's t_us), kept for :meth:`BenchClient.take_round_trips`
(the runner fits the device clock with them: runner/clock_fit.py).
:meth:`BenchClient.arm_reset` tells the device the host is about to reopen the port on
purpose, so the position survives that reset.

Threads: the port is used under one lock, so :meth:`send_keepalive` may be called from
another thread (:mod:`tsa_bench.device.keepalive`) while the owner reads or sends; every
other method belongs to the thread that owns the session. A keepalive is never sent
while a command waits for its ACK (the device recognises a repeat only as the frame it
processed last, so a frame in between would make a retransmission execute twice) and
its ACK is dropped on arrival (its QUEUE_STATUS is kept for ``poll()``, and is a clock
sample like any other answer to a HEARTBEAT).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any, NamedTuple

import serial

from tsa_bench.device.errors import (
    CommandRefused, ConnectionLost, DeviceMismatch, DeviceNotFound, NoAcknowledgement,
)
from tsa_bench.device.link import FrameSequencer, LinkStats
from tsa_bench.protocol import MessageDecoder, encode, msg, spec_of
from tsa_bench.protocol.blocks import expand, refusal_reason

READ_CHUNK = 4096


class BenchClient:
    """Framed-protocol session on an open port (``serial.Serial`` or ``sim://``)."""

    def __init__(self, port: Any, *, ack_timeout_s: float = 0.25, watchdog_s: float = 2.0) -> None:
        self.port = port
        self.ack_timeout_s = ack_timeout_s
        self.watchdog_s = watchdog_s
        self.identity: msg.Identity | None = None
        self.boot: msg.Boot | None = None
        self.retransmissions = 0
        self.late_dropped = 0
        self.last_tx_wall = time.monotonic()
        self.last_read_wall = time.monotonic()   # when the owner last read the port (wall s)
        self.on_wait: Callable[[], None] | None = None
        self._io = threading.RLock()   # the port, the sequence numbers, _in_flight
        self._in_flight = False        # a command waits for its ACK (no keepalive in between)
        self._keepalive_seqs: deque[int] = deque(maxlen=64)   # keepalives whose ACK is dropped
        self._seq = 0
        self._decoder = MessageDecoder()
        self._sequencer = FrameSequencer()
        self._inbox: deque[NamedTuple] = deque()
        self._last_dev_us: int | None = None
        self._late_acks: list[msg.Ack] = []
        self._heartbeat_sent_s: float | None = None
        self._round_trips: deque[tuple[float, float, int]] = deque(maxlen=256)
        # ports with a simulated device in this process (sim://) pass frames without bytes;
        # looked up on the class, so a wrapper that only forwards attributes (a port that
        # drops or corrupts bytes) keeps the byte path
        frame_port = callable(getattr(type(port), "read_frames", None)) and \
            callable(getattr(type(port), "write_frame", None))
        self._read_frames = port.read_frames if frame_port else None
        self._write_frame = port.write_frame if frame_port else None
        self._set_batching = port.set_batching if frame_port and callable(
            getattr(type(port), "set_batching", None)) else None

    @property
    def retry_budget_s(self) -> float:
        """How long a command is retransmitted without an ACK: the watchdog plus two timeouts."""
        return self.watchdog_s + 2 * self.ack_timeout_s

    @property
    def link(self) -> LinkStats:
        """Link-layer counters (duplicates dropped, frames restored to order, lost, late)."""
        return self._sequencer.stats

    # -- bytes ------------------------------------------------------------
    @property
    def frame_errors(self) -> dict[str, int]:
        """Rejected incoming frames by reason (crc, cobs, short, ...)."""
        return self._decoder.errors

    def _read(self) -> list[NamedTuple]:
        received, heartbeat_s = 0.0, None
        try:
            if self._read_frames is not None:   # an in-process simulated device: frames as they are
                received, heartbeat_s = time.monotonic(), self._heartbeat_sent_s
                frames = self._read_frames(min(max(1, self.port.in_waiting), READ_CHUNK))  # (no keepalive thread)
            else:
                with self._io:
                    # read(1) blocks up to the port timeout when nothing is waiting
                    data = self.port.read(min(max(1, self.port.in_waiting), READ_CHUNK))
                    # taken under the lock: a reply in these bytes answers a HEARTBEAT sent
                    # at or before this stamp, never one a keepalive sends after the read
                    received, heartbeat_s = time.monotonic(), self._heartbeat_sent_s
                frames = self._decoder.feed(data) if data else []
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"lost the connection on {self._port_name()}: {exc}") from None
        self.last_read_wall = time.monotonic()
        if self._read_frames is not None:   # in process: in order and none lost (checked at its ends)
            frames = self._sequencer.push_consecutive(frames)
            out = [f.message for f in frames]
            if msg.SampleBlock in set(map(type, out)):
                out = expand(out)
        else:
            frames = self._sequencer.push(frames)
            out = expand(f.message for f in frames)   # a SAMPLE_BLOCK becomes its samples
            if self._keepalive_seqs:
                out = [m for m in out if not self._keepalive_ack(m)]
        for late in self._sequencer.take_late():
            if isinstance(late.message, msg.Ack):
                self._late_acks.append(late.message)  # may still answer the command awaited now
            else:
                self.late_dropped += 1    # a late sample or event would be out of order
        for m in reversed(out):     # the latest device time seen
            t_us = getattr(m, "t_us", None)
            if t_us is not None:
                self._last_dev_us = t_us
                break
        if heartbeat_s is not None and msg.QueueStatus in set(map(type, out)):
            for m in out:
                if type(m) is msg.QueueStatus:
                    self._round_trips.append((heartbeat_s, received, m.t_us))
            with self._io:
                if self._heartbeat_sent_s == heartbeat_s:   # not a newer keepalive's
                    self._heartbeat_sent_s = None
        return out

    def _write(self, frame: bytes, seq: int | None = None, message: NamedTuple | None = None) -> None:
        try:
            if self._write_frame is not None and message is not None:
                self._write_frame(frame, seq, message)
                self.last_tx_wall = time.monotonic()
            else:
                with self._io:
                    self.port.write(frame)
                    self.last_tx_wall = time.monotonic()
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"lost the connection on {self._port_name()}: {exc}") from None

    def _keepalive_ack(self, m: NamedTuple) -> bool:
        if type(m) is not msg.Ack:
            return False
        with self._io:
            if m.acked_seq in self._keepalive_seqs:
                self._keepalive_seqs.remove(m.acked_seq)
                return True
        return False

    def send_keepalive(self, quiet_s: float) -> bool:
        """From any thread: send HEARTBEAT (not waiting for its ACK) if nothing was sent for
        ``quiet_s`` of wall time and no command waits for its ACK. True if it was sent.
        Only for a byte port (a real line, a pty); False on ``sim://`` in this process."""
        if self._write_frame is not None:
            return False
        with self._io:
            if self._in_flight or time.monotonic() - self.last_tx_wall < quiet_s:
                return False
            seq = self._next_seq()
            self._keepalive_seqs.append(seq)
            self._write(encode(msg.Heartbeat(), seq))
            self._heartbeat_sent_s = self.last_tx_wall   # its QUEUE_STATUS is a clock sample
            return True

    def _port_name(self) -> str:
        return str(getattr(self.port, "port", None) or getattr(self.port, "name", "the port"))

    @property
    def device_now_us(self) -> int | None:
        """In process: the simulated device's clock (us since boot); else None (a real
        device's clock is known only from the timestamps it sends)."""
        return self.port.device_time_us if self._set_batching is not None else None

    def set_batching(self, on: bool) -> bool:
        """Ask an in-process simulated device (``sim://``) for batched delivery: fewer,
        longer steps that do not stop at segment events while more commands wait in its
        queue (``Serial.set_batching``). Only for stretches where nothing the caller
        decides depends on when it sees samples or events. False (and nothing changes)
        on any other port: a real line, a pty, simavr."""
        if self._set_batching is None:
            return False
        self._set_batching(on)
        return True

    # -- session ----------------------------------------------------------
    def connect(self, boot_timeout_s: float = 3.0, baud: int | None = None) -> msg.Identity:
        """Wait for BOOT (up to ``boot_timeout_s`` s of wall time), then handshake; return IDENTITY.

        A missing BOOT is not an error (the port may not reset the device); the HELLO is
        tried three times, each waiting ``4 * ack_timeout_s``. ``baud`` (bit/s) is only named
        in the error message. Raises :class:`~tsa_bench.device.ConnectionLost` when the port
        fails, :class:`~tsa_bench.device.DeviceNotFound` when nothing answers and
        :class:`~tsa_bench.device.DeviceMismatch` for a device of another protocol catalogue.
        """
        deadline = time.monotonic() + boot_timeout_s
        while self.boot is None and time.monotonic() < deadline:
            for m in self._read():
                if isinstance(m, msg.Boot):
                    self.boot = m
        # Whatever arrived before or with the boot announcement is stale.
        self._inbox.clear()
        try:
            self.port.reset_input_buffer()
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"lost the connection on {self._port_name()}: {exc}") from None
        self._sequencer.reset()
        for _attempt in range(3):
            self._write(encode(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH), self._next_seq()))
            reply = self._await(lambda m: isinstance(m, (msg.Identity, msg.Ack)), self.ack_timeout_s * 4)
            if isinstance(reply, msg.Identity):
                self._check_identity(reply)
                self.identity = reply
                self.watchdog_s = reply.watchdog_ms / 1000.0
                return reply
            if isinstance(reply, msg.Ack) and reply.acked_id == 0x01:
                raise DeviceMismatch(
                    f"the device on {self._port_name()} refused our HELLO "
                    f"(status {msg.Status(reply.status).name}): it speaks another protocol version or "
                    "catalogue; flash the firmware built from this checkout (make -C firmware flash, in the source checkout: a wheel carries no firmware)")
        raise DeviceNotFound(
            f"no answer from a tsa-bench device on {self._port_name()} at {baud or getattr(self.port, 'baudrate', '?')} "
            "baud. Check: the port (is it the Arduino Mega? `python -m serial.tools.list_ports`), the baud rate "
            "(the firmware uses 250000), and that the tsa-bench firmware is flashed (make -C firmware flash, in the source checkout: a wheel carries no firmware)"
            + ("" if self.boot else "; no boot announcement was seen either"))

    @staticmethod
    def _check_identity(ident: msg.Identity) -> None:
        if ident.protocol_version != msg.PROTOCOL_VERSION or ident.catalogue_hash != msg.CATALOGUE_HASH:
            raise DeviceMismatch(
                f"device speaks protocol v{ident.protocol_version} catalogue 0x{ident.catalogue_hash:08X}, "
                f"host speaks v{msg.PROTOCOL_VERSION} catalogue 0x{msg.CATALOGUE_HASH:08X} "
                f"(firmware {ident.fw_major}.{ident.fw_minor}.{ident.fw_patch}); rebuild and flash the firmware "
                "from this checkout (make -C firmware flash, in the source checkout: a wheel carries no firmware) or install the matching tsa-bench")

    def _next_seq(self) -> int:
        """The next sequence number (a thread sending on a byte port holds ``_io``)."""
        self._seq = (self._seq + 1) & 0xFFFF
        return self._seq

    def _await(self, predicate, timeout_s: float) -> NamedTuple | None:
        """Read until a message matching ``predicate`` arrives; keep the others.

        Times out after ``timeout_s`` of wall time or of device time (seen in the
        timestamps of what arrives meanwhile), whichever passes first: on a real
        device they agree, and a simulated device in virtual time must not run
        seconds ahead (and trip its own watchdog) while the host waits for an ACK.
        """
        deadline = time.monotonic() + timeout_s
        t0_us: int | None = self._last_dev_us  # device time when the wait began (as last seen)
        while True:
            if self.on_wait is not None:
                self.on_wait()
            found = None
            t_us = None
            for m in self._read():
                if found is None and predicate(m):
                    found = m
                else:
                    self._inbox.append(m)  # everything else, in order, for poll()
                t_us = getattr(m, "t_us", t_us)
            late, self._late_acks = self._late_acks, []
            found = found or next((m for m in late if predicate(m)), None)
            if found is not None:
                return found
            if t_us is not None:
                t0_us = t_us if t0_us is None else t0_us
                if (t_us - t0_us) / 1e6 >= timeout_s:
                    return None
            if time.monotonic() >= deadline:
                return None

    # -- commands ---------------------------------------------------------
    def command(self, message: NamedTuple, *, check: bool = True) -> msg.Ack:
        """Send one command and wait for its ACK (retransmitting on timeout).

        With ``check`` a NAK raises :class:`CommandRefused`; otherwise it is returned.
        """
        spec = spec_of(message)
        if self._write_frame is None:
            with self._io:
                self._in_flight = True
                seq = self._next_seq()
            frame = encode(message, seq)
        else:   # in process: no bytes, no keepalive thread
            seq, frame = self._next_seq(), b""
        try:
            return self._transact(message, spec, seq, frame, check)
        finally:
            self._in_flight = False

    def _transact(self, message: NamedTuple, spec: Any, seq: int, frame: bytes, check: bool) -> msg.Ack:
        wall0 = time.monotonic()
        transmissions = 0
        while True:
            if transmissions:
                self.retransmissions += 1
            self._write(frame, seq, message)
            if type(message) is msg.Heartbeat:
                self._heartbeat_sent_s = self.last_tx_wall
            transmissions += 1
            ack = self._await(lambda m: isinstance(m, msg.Ack) and m.acked_seq == seq, self.ack_timeout_s)
            if ack is not None:
                if check and ack.status != msg.Status.OK:
                    raise CommandRefused(spec.name, ack.status,
                                         f"device refused {spec.name} {tuple(message)}: "
                                         f"{msg.Status(ack.status).name.lower()}"
                                         f"{refusal_reason(message, ack.status)}")
                return ack
            # giving up is judged in wall time only: after the host was busy, what waited in
            # the port spans seconds of device time without the device having waited at all
            waited_s = time.monotonic() - wall0
            if transmissions >= 2 and waited_s >= self.retry_budget_s:
                raise NoAcknowledgement(
                    f"no ACK for {spec.name} after {transmissions} transmissions over {waited_s:.2f} s on "
                    f"{self._port_name()} (retried for the device's {self.watchdog_s:g} s watchdog and two "
                    f"{self.ack_timeout_s:g} s timeouts)")

    def poll(self) -> list[NamedTuple]:
        """Everything received since the last poll (reads the port once if nothing is kept)."""
        if not self._inbox:
            return self._read()
        out = list(self._inbox)
        self._inbox.clear()
        return out

    def stop(self) -> None:
        """Immediate STOP; best effort (retransmitted, but never raises on silence)."""
        try:
            self.command(msg.Stop(), check=False)
        except (NoAcknowledgement, ConnectionLost):
            pass

    # -- position -----------------------------------------------------------
    def status(self) -> msg.QueueStatus:
        """HEARTBEAT and the QUEUE_STATUS that answers it (state bits, step position,
        error counters). The status also stays in the inbox for ``poll()``."""
        self.command(msg.Heartbeat())
        for m in reversed(self._inbox):
            if isinstance(m, msg.QueueStatus):
                return m
        found = self._await(lambda m: isinstance(m, msg.QueueStatus), self.retry_budget_s)
        if found is None:
            raise NoAcknowledgement(f"no QUEUE_STATUS after HEARTBEAT on {self._port_name()}")
        self._inbox.append(found)
        return found  # type: ignore[return-value]

    def take_round_trips(self) -> list[tuple[float, float, int]]:
        """HEARTBEAT round trips since the last call: ``(sent_s, received_s, device_us)``."""
        out = list(self._round_trips)
        self._round_trips.clear()
        return out

    def arm_reset(self) -> bool:
        """ARM_RESET before the port is closed and opened again on purpose (a Mega resets
        when its port opens): the device keeps its position across that reset. Best effort:
        False when the device refused (position unknown, a move under way) or did not answer."""
        try:
            return self.command(msg.ArmReset(), check=False).status == msg.Status.OK
        except (NoAcknowledgement, ConnectionLost):
            return False

    def set_position(self, steps: int) -> msg.Ack:
        """SET_POSITION: declare where the motor is now (steps; 0 = strings untwisted).
        The device refuses it while a move runs or waits (bad_state) or outside its
        twist limits (limit_exceeded): raises :class:`CommandRefused`."""
        return self.command(msg.SetPosition(int(steps)))
