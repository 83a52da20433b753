"""pty server end to end: a real serial.Serial on the slave side."""

from __future__ import annotations

import queue
import sys
import threading
import time

import pytest
import serial
from simhost import HELLO

from tsa_bench.bench import load_bench
from tsa_bench.protocol import MessageDecoder, encode, msg
from tsa_bench.transport.pty_server import serve_pty

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="needs a POSIX pty")


@pytest.fixture
def pty_path():
    ready: queue.Queue[str] = queue.Queue()
    stop = threading.Event()
    thread = threading.Thread(target=serve_pty, args=(load_bench(None), None, 1, ready.put, stop), daemon=True)
    thread.start()
    yield ready.get(timeout=5)
    stop.set()
    thread.join(timeout=5)
    assert not thread.is_alive()


def read_until(port, dec, predicate, timeout_s=5.0, heartbeat_s=0.2):
    seen, seq = [], 60000
    deadline = time.monotonic() + timeout_s
    last_hb = time.monotonic()
    while time.monotonic() < deadline:
        if heartbeat_s and time.monotonic() - last_hb > heartbeat_s:
            seq += 1
            port.write(encode(msg.Heartbeat(), seq))
            last_hb = time.monotonic()
        got = [f.message for f in dec.feed(port.read(max(1, port.in_waiting)))]
        seen += got
        if any(predicate(m) for m in got):
            return seen
    raise AssertionError(f"not seen within {timeout_s} s: {seen[-3:]}")


def test_handshake_move_and_samples_over_a_pty(pty_path):
    with serial.Serial(pty_path, 250000, timeout=0.1) as port:
        dec = MessageDecoder()
        # pyserial flushes its input on open, so the BOOT sent at server start is gone;
        # a client simply says HELLO
        port.write(encode(HELLO, 1))
        ident = read_until(port, dec, lambda m: isinstance(m, msg.Identity))[-1]
        assert ident.flags & msg.DeviceFlags.SIMULATED
        port.write(encode(msg.SetPosition(0), 5) + encode(msg.SetSampling(0, 10_000), 2)
                   + encode(msg.MoveBy(1, 3200, 16_000, 320_000), 3))
        seen = read_until(port, dec, lambda m: isinstance(m, msg.Event) and m.kind == msg.EventKind.QUEUE_EMPTY
                          and m.segment == 1)
        acks = [m for m in seen if isinstance(m, msg.Ack) and m.acked_seq in (2, 3)]
        assert [a.status for a in acks] == [msg.Status.OK, msg.Status.OK]
        samples = [m for m in seen if isinstance(m, msg.Sample)]
        assert len(samples) >= 10
        assert [s.counter for s in samples] == list(range(samples[0].counter, samples[0].counter + len(samples)))
        assert any(s.motor_moving for s in samples)
        done = [m for m in seen if isinstance(m, msg.Event) and m.kind == msg.EventKind.SEGMENT_DONE]
        assert done[-1].segment == 1 and done[-1].value == 3200      # events carry the step position
        assert not dec.errors
        port.write(encode(msg.SetSampling(2, 0), 4))
        read_until(port, dec, lambda m: isinstance(m, msg.Ack) and m.acked_seq == 4)

    # a new client just says HELLO; the device kept its state
    with serial.Serial(pty_path, 250000, timeout=0.1) as port:
        port.reset_input_buffer()
        dec = MessageDecoder()
        port.write(encode(HELLO, 1) + encode(msg.Heartbeat(), 2))
        seen = read_until(port, dec, lambda m: isinstance(m, msg.QueueStatus))
        assert any(isinstance(m, msg.Identity) for m in seen)
        assert seen[-1].fault == 0 and seen[-1].t_us > 0
        # binary-clean both ways: CR, LF, XON/XOFF, ^C, ^Z survive in fields and replies
        tricky = msg.SetSampling(0x0D0A, 0x1311030D)
        port.write(encode(tricky, 0x0A0D) + encode(msg.SetSampling(0x1A03, 0), 0x1113))
        seen = read_until(port, dec, lambda m: isinstance(m, msg.Ack) and m.acked_seq == 0x1113)
        acks = [(m.acked_seq, m.status) for m in seen if isinstance(m, msg.Ack) and m.acked_id == 0x14]
        assert acks == [(0x0A0D, msg.Status.OK), (0x1113, msg.Status.OK)]
        assert not dec.errors
