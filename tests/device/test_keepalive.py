"""The keepalive thread against a scripted device: never between a command and its
retransmission (the device's repeat filter remembers only the last frame, so a heartbeat
there would make a retransmitted MOVE_BY run twice), its ACKs never reach the owner."""

from __future__ import annotations

import time

import pytest

from tests.device.test_client import ScriptedPort, identity
from tsa_bench.device import BenchClient, NoAcknowledgement
from tsa_bench.device.keepalive import Keepalive
from tsa_bench.protocol import encode, msg


def _status(f):
    return [msg.Ack(f.seq, 0x02, int(msg.Status.OK), 16), msg.QueueStatus(1000, 16, 0, 0xFFFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)]


def _connected(script) -> tuple[BenchClient, ScriptedPort]:
    port = ScriptedPort({msg.Hello: lambda f: [identity(watchdog_ms=300)], **script})
    client = BenchClient(port, ack_timeout_s=0.05)
    client.connect(boot_timeout_s=0.5)
    return client, port


def test_no_keepalive_goes_out_while_a_command_waits_for_its_ack():
    client, port = _connected({msg.Heartbeat: _status})   # MOVE_BY: its ACKs are all lost
    with Keepalive(client, period_s=0.005) as keepalive:
        with pytest.raises(NoAcknowledgement):
            client.command(msg.MoveBy(0, 100, 1000, 1000))
        before = keepalive.sent
        _until(lambda: keepalive.sent > before, "a keepalive once the command gave up")
    kinds = [type(f.message) for f in port.received[1:]]
    first, last = kinds.index(msg.MoveBy), len(kinds) - 1 - kinds[::-1].index(msg.MoveBy)
    assert last > first   # retransmitted
    assert msg.Heartbeat not in kinds[first:last], kinds[first:last + 1]
    assert msg.Heartbeat in kinds[last:]


def test_a_keepalive_ack_never_reaches_the_owner_its_status_does():
    client, port = _connected({msg.Heartbeat: _status})
    with Keepalive(client, period_s=0.005) as keepalive:
        deadline = time.monotonic() + 10
        while keepalive.sent < 3 and time.monotonic() < deadline:
            time.sleep(0.01)
    got = client.poll() + client.poll()
    assert keepalive.sent >= 3
    assert not any(isinstance(m, msg.Ack) for m in got), got
    assert sum(isinstance(m, msg.QueueStatus) for m in got) == keepalive.sent


def _until(condition, what: str) -> None:
    deadline = time.monotonic() + 20
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.005)


def test_the_keepalive_stops_when_the_owner_has_not_read_for_its_limit():
    client, port = _connected({msg.Heartbeat: _status})
    with Keepalive(client, period_s=0.005, max_stall_s=5.0) as keepalive:
        _until(lambda: keepalive.sent > 0, "a keepalive while the owner reads")
        client.last_read_wall = time.monotonic() - 10   # the owner has not read for 10 s
        after = keepalive.checks + 1
        _until(lambda: keepalive.checks > after, "the thread looking")
        stalled, checks = keepalive.sent, keepalive.checks
        _until(lambda: keepalive.checks > checks + 20, "the thread looking again")
        assert keepalive.sent == stalled      # 20 looks, none sent
        with keepalive.attended():   # waiting for a person: on again however long it takes
            _until(lambda: keepalive.sent > stalled, "a keepalive while the owner waits for a person")


def test_a_backlog_after_a_busy_host_is_not_a_device_that_stopped_answering():
    """After a 3 s stall of the host the port holds 3 s of samples: reading them takes no
    time, the device waited for nothing. A command whose first two transmissions go
    unanswered is retransmitted within the retry budget (wall time), not given up
    because the backlog's timestamps span more than the budget (it was, after two)."""
    transmissions = []

    def heartbeat(f):
        transmissions.append(f.seq)
        return _status(f) if len(transmissions) >= 3 else []

    client, port = _connected({msg.Heartbeat: heartbeat})
    client.watchdog_s = 2.0                        # retry budget 2.1 s

    def sample(i: int) -> bytes:                   # the device's next frame: a sample every 50 ms
        port._seq += 1
        return encode(msg.Sample(i, 1_000_000 + 50_000 * i, 0, 0, 0, 0, 0, 0, 0), port._seq)

    port._rx += sample(0)
    assert len(client.poll()) == 1                 # the last sample read before the stall
    for i in range(1, 61):                         # 3 s of samples, waiting in the port
        port._rx += sample(i)
    ack = client.command(msg.Heartbeat())
    assert ack.status == msg.Status.OK and len(transmissions) == 3
    assert [m.counter for m in client.poll() if isinstance(m, msg.Sample)] == list(range(1, 61))  # kept, in order
