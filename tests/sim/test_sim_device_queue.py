"""Simulated device, acceptance of queued commands: every NAK status and the FIFO."""

from __future__ import annotations

import pytest

from simhost import events

from tsa_bench.protocol import msg

S = msg.Status
SPT = 3200
MAX_RATE, MAX_ACCEL = 5 * SPT, 100 * SPT


@pytest.mark.parametrize("command, status", [
    (msg.MoveTo(0, SPT, 0, 1000), S.BAD_ARGUMENT),
    (msg.MoveTo(0, SPT, 1000, 0), S.BAD_ARGUMENT),
    (msg.MoveBy(0, SPT, 0, 1000), S.BAD_ARGUMENT),
    (msg.MoveBy(0, SPT, 1000, 0), S.BAD_ARGUMENT),
    (msg.MoveTo(0, SPT, MAX_RATE + 1, 1000), S.LIMIT_EXCEEDED),
    (msg.MoveTo(0, SPT, 1000, MAX_ACCEL + 1), S.LIMIT_EXCEEDED),
    (msg.MoveBy(0, SPT, MAX_RATE + 1, 1000), S.LIMIT_EXCEEDED),
    (msg.MoveTo(0, 100 * SPT + 1, 1000, 1000), S.LIMIT_EXCEEDED),
    (msg.MoveTo(0, -10 * SPT - 1, 1000, 1000), S.LIMIT_EXCEEDED),
    (msg.MoveBy(0, -10 * SPT - 1, 1000, 1000), S.LIMIT_EXCEEDED),
    (msg.SetHeater(0, 12001), S.LIMIT_EXCEEDED),
    (msg.SetSampling(0, 1162), S.TOO_FAST_FOR_SENSOR),            # below one ADS1115 conversion
    (msg.SetSampling(0, 1), S.TOO_FAST_FOR_SENSOR),
    # accepted at the edges
    (msg.MoveTo(0, 100 * SPT, MAX_RATE, MAX_ACCEL), S.OK),
    (msg.MoveBy(0, -10 * SPT, MAX_RATE, MAX_ACCEL), S.OK),
    (msg.SetHeater(0, 12000), S.OK),
    (msg.SetSampling(0, 1163), S.OK),                             # continuous, 860 samples/s
    (msg.SetSampling(0, 2326), S.OK),                             # continuous, every other conversion
    (msg.SetSampling(0, 1500), S.BETWEEN_CONVERSIONS),             # never rounded to a conversion
    (msg.SetSampling(0, 2999), S.BETWEEN_CONVERSIONS),
    (msg.SetSampling(0, 3000), S.OK),
    (msg.SetSampling(0, 0), S.OK),
    (msg.Dwell(0, 0), S.OK),
])
def test_acceptance(host, command, status):
    ack = host.ack(command)
    assert ack.status == status
    if status != S.OK:
        assert ack.queue_free == 16
        assert not host.dev.active and host.dev.executor.heater_mV == 0


def test_move_by_is_checked_against_the_projected_position(host):
    assert host.ack(msg.MoveBy(0, 90 * SPT, MAX_RATE, MAX_ACCEL)).status == S.OK      # runs for ~18 s
    assert host.ack(msg.MoveBy(1, 20 * SPT, MAX_RATE, MAX_ACCEL)).status == S.LIMIT_EXCEEDED
    assert host.ack(msg.MoveBy(1, 10 * SPT, MAX_RATE, MAX_ACCEL)).status == S.OK       # lands on 100 turns
    assert host.ack(msg.MoveBy(2, 1, MAX_RATE, MAX_ACCEL)).status == S.LIMIT_EXCEEDED
    assert host.ack(msg.MoveTo(3, 0, MAX_RATE, MAX_ACCEL)).status == S.OK              # absolute resets it
    assert host.ack(msg.MoveBy(4, -10 * SPT, MAX_RATE, MAX_ACCEL)).status == S.OK


def test_queue_full_at_capacity(host):
    assert host.ack(msg.Dwell(0, 10_000_000)).queue_free == 16     # started at once: not in the FIFO
    frees = [host.ack(msg.Dwell(1 + i, 1_000_000)).queue_free for i in range(16)]
    assert frees == list(range(15, -1, -1))
    refused = host.ack(msg.SetHeater(17, 1000))
    assert (refused.status, refused.queue_free) == (S.QUEUE_FULL, 0)
    assert host.dev.executor.heater_mV == 0


def test_fault_latched_refuses_queued_commands(host):
    host.send(msg.MoveBy(0, 20 * SPT, 1000, 1000))
    host.run(3.0, heartbeat_s=None)                                  # silent host: watchdog
    assert host.dev.fault == msg.Fault.WATCHDOG
    for command in (msg.MoveBy(1, SPT, 1000, 1000), msg.Dwell(1, 1000), msg.SetHeater(1, 0),
                    msg.SetSampling(1, 0), msg.MoveTo(1, 0, 1000, 1000)):
        assert host.ack(command).status == S.BAD_STATE
    # immediate commands still work
    assert host.ack(msg.Stop()).status == S.OK
    assert host.ack(msg.SimSetLoad(1000)).status == S.OK


def _advance_to_stop(host, batch: bool) -> list:
    """One advance (up to 10 s) with or without batched segment events; what it produced."""
    host.dev.batch_segment_events = batch
    try:
        host.dev.advance(10.0, 1 << 20)
    finally:
        host.dev.batch_segment_events = False
    return host._collect()


def test_batched_advance_stops_only_where_the_queue_needs_feeding(host):
    """With batch_segment_events, SEGMENT_DONE and SEGMENT_STARTED with more commands
    waiting do not stop an advance; the start of the last queued command and
    QUEUE_EMPTY do. Without it, every event does."""
    E = msg.EventKind
    for i in range(4):
        host.ack(msg.Dwell(i, 100_000))          # 0 runs at once, 1..3 wait
    plain = _advance_to_stop(host, batch=False)
    # stopped at the first end (the next start comes in the same instant)
    assert [(m.kind, m.segment) for m in events(plain)] == [(E.SEGMENT_DONE, 0), (E.SEGMENT_STARTED, 1)]
    batched = _advance_to_stop(host, batch=True)
    # 1 done, 2 started (3 waits: on), 2 done, 3 started: the last queued, stop
    assert [(m.kind, m.segment) for m in events(batched)] == [
        (E.SEGMENT_DONE, 1), (E.SEGMENT_STARTED, 2), (E.SEGMENT_DONE, 2), (E.SEGMENT_STARTED, 3)]
    assert abs(host.dev.now_s - 0.3) < 1e-9     # at segment 3's start, as an unbatched host would see it
    last = _advance_to_stop(host, batch=True)
    assert [(m.kind, m.segment) for m in events(last)] == [(E.SEGMENT_DONE, 3), (E.QUEUE_EMPTY, 3)]
    assert abs(host.dev.now_s - 0.4) < 1e-9
