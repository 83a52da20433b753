"""The bench client against scripted exchanges (no device): handshake, refusals, retries."""

from __future__ import annotations

import time

import pytest
import serial

from tsa_bench.device import BenchClient, CommandRefused, DeviceMismatch, DeviceNotFound, NoAcknowledgement
from tsa_bench.protocol import MessageDecoder, encode, msg


class ScriptedPort:
    """A port that answers host frames with scripted device frames: ``script`` maps a
    host message class to a function returning the messages to send back."""

    def __init__(self, script, boot: bool = True, port: str = "/dev/ttyFAKE", baudrate: int = 250000):
        self.script = script
        self.port, self.baudrate = port, baudrate
        self._rx = bytearray(encode(msg.Boot(0, 1, 0, 2), 1) if boot else b"")
        self._dec = MessageDecoder()
        self._seq = 1
        self.received: list = []

    @property
    def in_waiting(self) -> int:
        return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self._rx[:size])
        del self._rx[:size]
        return out

    def write(self, data: bytes) -> int:
        for frame in self._dec.feed(data):
            self.received.append(frame)
            for reply in self.script.get(type(frame.message), lambda f: [])(frame):
                self._seq += 1
                self._rx += encode(reply, self._seq)
        return len(data)

    def reset_input_buffer(self) -> None:
        self._rx.clear()


def identity(**changes) -> msg.Identity:
    base = msg.Identity(msg.PROTOCOL_VERSION, 0, 1, 0, msg.CATALOGUE_HASH, 3200, -32000, 320000, 16000, 320000,
                        12000, 16, 2000, 0, 3000, 10000)
    return base._replace(**changes)


def ack(frame, status=msg.Status.OK):
    return [msg.Ack(frame.seq, 0x10, int(status), 15)]


def test_handshake_waits_for_boot_and_returns_identity():
    port = ScriptedPort({msg.Hello: lambda f: [identity()]})
    client = BenchClient(port, ack_timeout_s=0.05)
    ident = client.connect(boot_timeout_s=0.5)
    assert ident.steps_per_turn == 3200 and client.boot is not None
    hello = port.received[0].message
    assert hello == msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH)


def test_catalogue_mismatch_is_refused_with_a_fix():
    port = ScriptedPort({msg.Hello: lambda f: [identity(catalogue_hash=0x12345678, fw_minor=9)]})
    with pytest.raises(DeviceMismatch) as info:
        BenchClient(port, ack_timeout_s=0.05).connect(boot_timeout_s=0.2)
    text = str(info.value)
    assert "0x12345678" in text and "0.9.0" in text and "flash" in text


def test_device_refusing_hello_is_a_mismatch():
    port = ScriptedPort({msg.Hello: lambda f: [msg.Ack(f.seq, 0x01, int(msg.Status.BAD_ARGUMENT), 16)]})
    with pytest.raises(DeviceMismatch, match="refused our HELLO"):
        BenchClient(port, ack_timeout_s=0.05).connect(boot_timeout_s=0.2)


def test_silent_port_names_port_baud_and_what_to_check():
    port = ScriptedPort({}, boot=False, port="/dev/ttyUSB7", baudrate=115200)
    with pytest.raises(DeviceNotFound) as info:
        BenchClient(port, ack_timeout_s=0.02).connect(boot_timeout_s=0.05, baud=115200)
    text = str(info.value)
    assert "/dev/ttyUSB7" in text and "115200" in text and "firmware" in text and "no boot announcement" in text


def test_loopback_port_echoing_our_own_frames_is_not_a_device():
    port = serial.serial_for_url("loop://", timeout=0.01)
    with pytest.raises(DeviceNotFound):
        BenchClient(port, ack_timeout_s=0.02).connect(boot_timeout_s=0.05)


def test_stale_input_before_the_handshake_is_discarded():
    port = ScriptedPort({msg.Hello: lambda f: [identity()]})
    port._rx += encode(msg.Sample(1, 2, 3, 4, 5, 0, 0, 0, 0), 9)  # left over from an earlier session
    client = BenchClient(port, ack_timeout_s=0.05)
    client.connect(boot_timeout_s=0.2)
    assert client.poll() == []


def test_command_retransmits_the_same_frame_until_acknowledged():
    answered = {"n": 0}

    def flaky(frame):
        answered["n"] += 1
        return [] if answered["n"] < 3 else ack(frame)

    port = ScriptedPort({msg.Hello: lambda f: [identity()], msg.Dwell: flaky})
    client = BenchClient(port, ack_timeout_s=0.02)
    client.connect(boot_timeout_s=0.2)
    result = client.command(msg.Dwell(0, 1000))
    dwell_frames = [f for f in port.received if isinstance(f.message, msg.Dwell)]
    assert result.status == msg.Status.OK and client.retransmissions == 2
    assert len({f.seq for f in dwell_frames}) == 1 and len(dwell_frames) == 3


def test_no_ack_is_retried_for_the_whole_watchdog_period_then_raises():
    """The retry budget follows the device's watchdog (IDENTITY.watchdog_ms): a stall
    shorter than it never fails a command; a silence longer than it does, saying so."""
    port = ScriptedPort({msg.Hello: lambda f: [identity(watchdog_ms=100)]})
    client = BenchClient(port, ack_timeout_s=0.01)
    client.connect(boot_timeout_s=0.2)
    assert client.retry_budget_s == pytest.approx(0.12)
    t0 = time.monotonic()
    with pytest.raises(NoAcknowledgement, match="watchdog") as info:
        client.command(msg.Heartbeat())
    assert time.monotonic() - t0 >= client.retry_budget_s  # never gives up before the budget
    sent = [f for f in port.received if isinstance(f.message, msg.Heartbeat)]
    assert len(sent) >= 2 and len({f.seq for f in sent}) == 1 and f"{len(sent)} transmissions" in str(info.value)


def test_nak_raises_with_the_status_name():
    port = ScriptedPort({msg.Hello: lambda f: [identity()],
                         msg.MoveTo: lambda f: ack(f, msg.Status.LIMIT_EXCEEDED)})
    client = BenchClient(port, ack_timeout_s=0.05)
    client.connect(boot_timeout_s=0.2)
    with pytest.raises(CommandRefused, match="limit_exceeded"):
        client.command(msg.MoveTo(0, 10**6, 100, 100))


def test_messages_arriving_with_the_ack_are_kept_in_order():
    port = ScriptedPort({msg.Hello: lambda f: [identity()],
                         msg.Heartbeat: lambda f: [msg.Ack(f.seq, 0x02, 0, 16), msg.QueueStatus(5, 16, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)]})
    client = BenchClient(port, ack_timeout_s=0.05)
    client.connect(boot_timeout_s=0.2)
    client.command(msg.Heartbeat())
    assert client.poll() == [msg.QueueStatus(5, 16, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)]


def test_status_returns_the_queue_status_answering_a_heartbeat_and_keeps_it_for_poll():
    qs = msg.QueueStatus(7, 16, 0, 0, 0, int(msg.DeviceState.POSITION_UNKNOWN), 1234, 2, 3, 4, 5, 0, 0, 0)
    port = ScriptedPort({msg.Hello: lambda f: [identity()],
                         msg.Heartbeat: lambda f: [msg.Ack(f.seq, 0x02, 0, 16), qs]})
    client = BenchClient(port, ack_timeout_s=0.05)
    client.connect(boot_timeout_s=0.2)
    assert client.status() == qs
    assert client.poll() == [qs]


def test_status_raises_when_no_queue_status_follows_the_ack():
    port = ScriptedPort({msg.Hello: lambda f: [identity(watchdog_ms=50)],
                         msg.Heartbeat: lambda f: [msg.Ack(f.seq, 0x02, 0, 16)]})
    client = BenchClient(port, ack_timeout_s=0.01)
    client.connect(boot_timeout_s=0.2)
    with pytest.raises(NoAcknowledgement, match="QUEUE_STATUS"):
        client.status()


def test_set_position_sends_the_steps_and_raises_on_refusal():
    port = ScriptedPort({msg.Hello: lambda f: [identity()],
                         msg.SetPosition: lambda f: [msg.Ack(f.seq, 0x06, int(msg.Status.OK if f.message.position_steps == 0
                                                                             else msg.Status.BAD_STATE), 16)]})
    client = BenchClient(port, ack_timeout_s=0.05)
    client.connect(boot_timeout_s=0.2)
    assert client.set_position(0).status == msg.Status.OK
    assert [f.message for f in port.received if isinstance(f.message, msg.SetPosition)] == [msg.SetPosition(0)]
    with pytest.raises(CommandRefused, match="bad_state"):
        client.set_position(5)
