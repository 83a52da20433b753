"""Simulated device, session level: boot, handshake, ACKs, duplicate filter, bad frames."""

from __future__ import annotations

import struct

import pytest
from simhost import HELLO, Host, events

from tsa_bench.protocol import encode, encode_raw, msg
from tsa_bench.sim import SimDevice

S = msg.Status
SPT = 3200


def test_boot_announcement(device):
    h = Host(device)
    device.boot()
    assert h.send_bytes(b"") == [msg.Boot(0, 2, 0, int(msg.BootReason.POWER_ON))]   # a fresh device


def test_hello_answers_identity_from_the_bench(device):
    assert Host(device).send(HELLO) == [msg.Identity(
        protocol_version=msg.PROTOCOL_VERSION, fw_major=0, fw_minor=2, fw_patch=0,
        catalogue_hash=msg.CATALOGUE_HASH, steps_per_turn=3200,
        min_twist_steps=-10 * SPT, max_twist_steps=100 * SPT,       # limits in turns x steps/turn
        max_rate_steps_per_s=5 * SPT, max_accel_steps_per_s2=100 * SPT,
        max_heater_mV=12000, queue_slots=16, watchdog_ms=2000, flags=int(msg.DeviceFlags.SIMULATED),
        min_sample_period_us=1163, fault_release_ms=10000)]


@pytest.mark.parametrize("hello", [msg.Hello(msg.PROTOCOL_VERSION + 1, msg.CATALOGUE_HASH),
                                   msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH ^ 1)])
def test_hello_mismatch_is_refused_without_identity(device, hello):
    h = Host(device)
    assert h.send(hello, seq=9) == [msg.Ack(9, 0x01, S.BAD_ARGUMENT, 16)]


def test_commands_before_hello_are_fine(device):
    h = Host(device)
    assert h.ack(msg.SetPosition(0)).status == S.OK
    assert h.ack(msg.MoveBy(3, SPT, 1000, 10000)).status == S.OK


def test_position_unknown_until_set(device):
    """A fresh device does not know its twist: moves are refused until SET_POSITION."""
    h = Host(device)
    device.boot()
    h.send(HELLO)
    assert h.send(msg.Heartbeat())[1].state == msg.DeviceState.POSITION_UNKNOWN
    assert h.ack(msg.MoveTo(1, SPT, 1000, 10000)).status == S.BAD_STATE
    assert h.ack(msg.MoveBy(1, SPT, 1000, 10000)).status == S.BAD_STATE
    assert h.ack(msg.Dwell(1, 1000)).status == S.OK                  # the rest works
    assert h.ack(msg.SetPosition(100 * SPT + 1)).status == S.LIMIT_EXCEEDED
    assert h.ack(msg.SetPosition(5 * SPT)).status == S.OK
    status = h.send(msg.Heartbeat())[1]
    assert (status.state, status.step_position) == (0, 5 * SPT)
    assert h.ack(msg.MoveBy(2, SPT, 1000, 10000)).status == S.OK
    assert h.ack(msg.SetPosition(0)).status == S.BAD_STATE            # a move runs
    h.run_until(lambda m: isinstance(m, msg.Event) and m.kind == msg.EventKind.QUEUE_EMPTY)
    assert device.executor.position_steps == 6 * SPT


def test_every_command_is_acked_and_heartbeat_gets_queue_status(host):
    reply = host.send(msg.Heartbeat(), seq=41)
    assert reply == [msg.Ack(41, 0x02, S.OK, 16), msg.QueueStatus(0, 16, 0, 0xFFFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0)]
    for m in (msg.Stop(), msg.ClearQueue(), msg.SimSetLoad(500_000), msg.Dwell(0, 0), msg.SetHeater(1, 0),
              msg.SetSampling(2, 0), msg.MoveTo(3, 0, 100, 100), msg.MoveBy(4, 0, 100, 100), msg.SetPosition(0)):
        reply = host.send(m, seq=100)
        assert isinstance(reply[0], msg.Ack) and reply[0].status == S.OK, (m, reply)
        assert reply[0].acked_seq == 100 and reply[0].acked_id == msg.SPEC_BY_CLASS[type(m)].id
        host.send(msg.Heartbeat())  # a different command, so the next one is not a duplicate


def test_device_frames_carry_a_running_seq(host):
    host.send(msg.SetSampling(0, 10_000))
    host.send(msg.MoveBy(1, SPT, 16000, 320000))
    host.run(1.0)
    seqs = [f.seq for f in host.frames]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))


def test_duplicate_move_is_not_executed_twice(host):
    first = host.send(msg.MoveBy(1, 2 * SPT, 16000, 320000), seq=7)
    again = host.send(msg.MoveBy(1, 2 * SPT, 16000, 320000), seq=7)
    assert again == [first[0]]                        # the stored ACK, nothing else
    seen = host.run(2.0)
    assert len(events(seen, msg.EventKind.SEGMENT_STARTED)) == 0   # started once, before the repeat
    assert [e.value for e in events(seen, msg.EventKind.SEGMENT_DONE)] == [2 * SPT]
    assert host.dev.executor.position_steps == 2 * SPT
    assert host.dev.duplicates == 1


def test_duplicate_heartbeat_resends_ack_and_a_fresh_status(host):
    host.send(msg.Heartbeat(), seq=5)
    host.dev.advance(0.25, 1 << 20)
    reply = host.send(msg.Heartbeat(), seq=5)
    assert reply[0] == msg.Ack(5, 0x02, S.OK, 16)
    assert reply[1].t_us == 250_000


def test_same_seq_with_another_id_is_a_new_command(host):
    host.send(msg.Dwell(0, 5_000_000), seq=3)
    assert host.ack(msg.SetHeater(1, 0), seq=3) == msg.Ack(3, 0x13, S.OK, 15)
    assert host.dev.duplicates == 0


def test_hello_resets_the_duplicate_filter(host):
    host.send(msg.MoveBy(1, SPT, 16000, 320000), seq=7)
    host.run(1.0)
    host.send(HELLO, seq=8)
    host.send(msg.MoveBy(1, SPT, 16000, 320000), seq=7)
    host.run(1.0)
    assert host.dev.executor.position_steps == 2 * SPT


def test_refused_command_is_evaluated_again_when_repeated(host):
    host.send(msg.Dwell(0, 1_000_000))                       # executing
    for i in range(16):
        host.send(msg.Dwell(1 + i, 1_000_000))
    assert host.ack(msg.Dwell(99, 1_000), seq=500).status == S.QUEUE_FULL
    host.run_until(lambda m: isinstance(m, msg.Event) and m.kind == msg.EventKind.SEGMENT_DONE)
    assert host.ack(msg.Dwell(99, 1_000), seq=500).status == S.OK


def test_invalid_frames_are_dropped_silently_and_counted(host):
    good = encode(msg.Heartbeat(), 1)
    corrupt = bytearray(good)
    corrupt[2] ^= 0x40
    assert host.send_bytes(b"\x07garbage\x00" + bytes(corrupt)) == []
    assert sum(host.dev.frame_errors.values()) == 2
    # a good frame right after is still handled
    assert isinstance(host.send_bytes(good)[0], msg.Ack)


def test_unknown_message_id_is_nakked(host):
    assert host.send_bytes(encode_raw(0x7E, 12, b"\x01\x02")) == [msg.Ack(12, 0x7E, S.UNKNOWN_MESSAGE, 16)]
    # a device-to-host message sent by the host is not accepted either
    sample = encode_raw(0x83, 13, bytes(msg.MESSAGES[0x83].struct.size))
    assert host.send_bytes(sample) == [msg.Ack(13, 0x83, S.UNKNOWN_MESSAGE, 16)]


def test_wrong_payload_length_is_nakked(host):
    short = struct.pack("<Hi", 1, 3200)  # MOVE_TO without rate and accel
    assert host.send_bytes(encode_raw(0x10, 14, short)) == [msg.Ack(14, 0x10, S.BAD_LENGTH, 16)]
    assert host.dev.executor.queued == 0 and not host.dev.executor.executing


def test_sim_set_load_changes_the_length(host, bench):
    host.send(msg.SetSampling(0, 100_000))
    before = [s.position_raw for s in host.run(1.0) if isinstance(s, msg.Sample)]
    host.send(msg.SimSetLoad(900_000))
    after = [s.position_raw for s in host.run(1.0) if isinstance(s, msg.Sample)]
    assert min(after) > max(before)
    assert host.dev.plant.load_g == pytest.approx(900.0)


def test_set_load_g_is_the_operator_shortcut(bench):
    d = SimDevice(bench, seed=0)
    d.set_load_g(123.0)
    assert d.plant.load_g == 123.0


def test_arm_reset_only_at_rest_and_the_sensor_period_while_continuous(host):
    """ARM_RESET as the firmware judges it (the simulated device never resets); QUEUE_STATUS
    carries the ADS1115's conversion period while sampling continuously, 0 otherwise."""
    assert host.ack(msg.ArmReset()).status == S.OK                       # at rest, the position declared
    host.dev.position_known = False                                      # as after a power-on
    assert host.ack(msg.ArmReset()).status == S.BAD_STATE
    assert host.ack(msg.SetPosition(0)).status == S.OK
    assert host.ack(msg.MoveBy(1, SPT, 1000, 10000)).status == S.OK
    assert host.ack(msg.ArmReset()).status == S.BAD_STATE                # a move runs
    assert host.send(msg.Heartbeat())[1].sensor_period_ns == 0
    assert host.ack(msg.SetSampling(2, 1163)).status == S.OK
    host.run_until(lambda m: isinstance(m, msg.Event) and m.kind == msg.EventKind.QUEUE_EMPTY)
    status = [m for m in host.send(msg.Heartbeat()) if isinstance(m, msg.QueueStatus)][0]
    assert status.sensor_period_ns == 1_162_791 and status.max_pass_us == 0 and status.sensor_restarts == 0
