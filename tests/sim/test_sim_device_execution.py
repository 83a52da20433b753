"""Simulated device, execution: segments, samples, heater, STOP, CLEAR_QUEUE, watchdog."""

from __future__ import annotations

import pytest
from simhost import events, samples

from tsa_bench.motion import TrapezoidProfile
from tsa_bench.protocol import msg
from tsa_bench.sim.sensors import CS5513_SETTLE_S

S, E = msg.Status, msg.EventKind
SPT = 3200
RATE, ACCEL = 10_000, 40_000


def is_event(kind):
    return lambda m: isinstance(m, msg.Event) and m.kind == kind


def test_segment_events_in_order_with_times(host):
    host.send(msg.SetSampling(0, 50_000))
    host.send(msg.MoveBy(1, 2 * SPT, RATE, ACCEL))
    host.send(msg.Dwell(2, 1_500_000))
    host.send(msg.SetHeater(3, 3000))
    host.send(msg.SetHeater(4, 0))
    host.send(msg.MoveTo(5, 0, RATE, ACCEL))
    host.run_until(is_event(E.QUEUE_EMPTY), max_s=10)
    ev = [(e.kind, e.segment) for e in events(m for _, m in host.frames)]
    assert ev == [(E.SEGMENT_STARTED, 0), (E.SEGMENT_DONE, 0), (E.QUEUE_EMPTY, 0),
                  (E.SEGMENT_STARTED, 1), (E.SEGMENT_DONE, 1),
                  (E.SEGMENT_STARTED, 2), (E.SEGMENT_DONE, 2),
                  (E.SEGMENT_STARTED, 3), (E.SEGMENT_DONE, 3),
                  (E.SEGMENT_STARTED, 4), (E.SEGMENT_DONE, 4),
                  (E.SEGMENT_STARTED, 5), (E.SEGMENT_DONE, 5), (E.QUEUE_EMPTY, 5)]
    t = {(e.kind, e.segment): e.t_us for e in events(m for _, m in host.frames)}
    move_us = round(TrapezoidProfile(2 * SPT, RATE, ACCEL).duration * 1e6)
    assert t[E.SEGMENT_DONE, 1] - t[E.SEGMENT_STARTED, 1] == move_us
    assert t[E.SEGMENT_DONE, 2] - t[E.SEGMENT_STARTED, 2] == 1_500_000
    assert t[E.SEGMENT_STARTED, 3] == t[E.SEGMENT_DONE, 3] == t[E.SEGMENT_DONE, 2]   # instantaneous
    assert t[E.QUEUE_EMPTY, 5] == t[E.SEGMENT_DONE, 5]
    done = {e.segment: e.value for e in events(m for _, m in host.frames) if e.kind == E.SEGMENT_DONE}
    assert done[1] == 2 * SPT and done[5] == 0


def test_ack_comes_before_the_events_it_causes(host):
    reply = host.send(msg.MoveBy(7, SPT, RATE, ACCEL), seq=30)
    assert reply == [msg.Ack(30, 0x11, S.OK, 16), msg.Event(0, E.SEGMENT_STARTED, 7, 0, 0)]


def test_samples_at_the_period_with_consecutive_counters(host):
    assert host.send(msg.Heartbeat())[1].segment == 0xFFFF       # before any segment
    host.dev.advance(0.3, 1 << 20)                                # sampling off: nothing
    assert host.dev.take_output() == b""
    host.send(msg.SetSampling(0, 20_000))
    got = samples(host.run(1.0))
    assert len(got) == 50
    assert [s.counter for s in got] == list(range(50))
    assert [s.t_us for s in got] == [300_000 + 20_000 * (i + 1) for i in range(50)]
    assert all(s.segment == 0 and s.motor_moving == 0 for s in got)
    # The sense current comes on with the first sample; the CS5513's sinc4 filter needs
    # four conversions before a word is valid, so the slots that end (0.5 ms margin)
    # before that keep their position but say resistance_not_measured.
    settled_s = got[0].t_us * 1e-6 + CS5513_SETTLE_S
    unsettled = [s.t_us * 1e-6 + 0.020 - 0.0005 < settled_s for s in got]
    assert 2 <= sum(unsettled) <= 4 and unsettled == sorted(unsettled, reverse=True)
    assert [s.adc_flags for s in got] == [int(msg.AdcFlags.RESISTANCE_NOT_MEASURED) if u else 0 for u in unsettled]
    host.send(msg.SetSampling(1, 0))
    assert samples(host.run(1.0)) == []
    host.send(msg.SetSampling(2, 100_000))
    assert samples(host.run(0.5))[0].counter == 50                # counter runs on


def test_motion_follows_the_trapezoid(host):
    host.send(msg.SetSampling(0, 10_000))
    host.send(msg.MoveTo(1, 3 * SPT, RATE, ACCEL))
    got = samples(host.run(2.0))
    profile = TrapezoidProfile(3 * SPT, RATE, ACCEL)
    for s in got:
        t = s.t_us / 1e6
        if t < profile.duration:
            assert s.motor_moving == 1 and s.step_position == round(profile.position(t))
        else:
            assert s.motor_moving == 0 and s.step_position == 3 * SPT
    positions = [s.step_position for s in got]
    assert positions == sorted(positions)


def test_samples_measure_the_plant(host, bench):
    host.send(msg.SetSampling(0, 100_000))
    host.send(msg.MoveTo(1, 20 * SPT, 16_000, 320_000))
    host.run(125.0)  # past the ~2 min resistance transient after the stop
    got = samples(host.run(1.0))
    plant = host.dev.plant
    expected = plant.quasi_static(20.0)
    for s in got:
        assert bench.position.length_mm(s.position_raw) == pytest.approx(expected.length_mm, abs=0.3)
        assert bench.resistance.resistance_ohm(s.resistance_raw) == pytest.approx(expected.resistance_ohm, abs=0.01)


def test_heater_on_means_resistance_not_measured(host):
    host.send(msg.SetSampling(0, 100_000))
    host.send(msg.SetHeater(1, 6000))
    hot = samples(host.run(1.0))
    assert hot and all(s.heater_mV == 6000 and s.resistance_raw == 0
                       and s.adc_flags & msg.AdcFlags.RESISTANCE_NOT_MEASURED for s in hot)
    host.send(msg.SetHeater(2, 0))
    cold = samples(host.run(1.0))
    assert cold and all(s.heater_mV == 0 and s.resistance_raw > 0 and s.adc_flags == 0 for s in cold)


def test_stop_mid_move(host):
    host.send(msg.SetSampling(0, 50_000))
    host.send(msg.SetHeater(1, 2000))
    host.send(msg.MoveTo(2, 50 * SPT, RATE, ACCEL))
    host.send(msg.Dwell(3, 1_000_000))
    host.run(2.0)
    reply = host.send(msg.Stop(), seq=900)
    assert reply[0] == msg.Ack(900, 0x03, S.OK, 16)
    stopped = reply[1]
    assert (stopped.kind, stopped.segment, stopped.t_us) == (E.STOPPED, 2, 2_000_000)
    assert 0 < stopped.value < 50 * SPT
    # it decelerates at the device's limit from where it was: value = where it comes to rest
    profile, a_max = TrapezoidProfile(50 * SPT, RATE, ACCEL), host.dev.limits.max_accel_steps_per_s2
    v = profile.velocity(2.0)
    assert stopped.value == round(profile.position(2.0)) + int(v * v / (2 * a_max))
    after = host.run(1.0)
    assert not events(after)                                          # no SEGMENT_DONE, dwell dropped
    assert all(s.heater_mV == 0 for s in samples(after))              # the heater went off at once
    at_rest = [s for s in samples(after) if s.t_us > 2_000_000 + 1e6 * v / a_max]
    assert at_rest and all(s.step_position == stopped.value and s.motor_moving == 0 for s in at_rest)
    status = host.send(msg.Heartbeat())[1]
    assert (status.queue_free, status.executing, status.fault, status.state) == (16, 0, 0, 0)
    assert (status.step_position, host.dev.executor.heater_mV) == (stopped.value, 0)
    assert not host.dev.active and host.dev.watchdog_armed            # only sampling still runs


def test_clear_queue_lets_the_running_segment_finish(host):
    host.send(msg.MoveBy(0, 2 * SPT, RATE, ACCEL))
    host.send(msg.Dwell(1, 5_000_000))
    host.send(msg.MoveBy(2, SPT, RATE, ACCEL))
    assert host.send(msg.ClearQueue())[0].queue_free == 16
    seen = host.run(3.0)
    assert [(e.kind, e.segment) for e in events(seen)] == [(E.SEGMENT_DONE, 0), (E.QUEUE_EMPTY, 0)]
    assert host.dev.executor.position_steps == 2 * SPT
    # the dropped MOVE_BY no longer counts toward the projected position
    assert host.ack(msg.MoveBy(3, 98 * SPT, RATE, ACCEL)).status == S.OK


def test_watchdog_fault_and_recovery(host):
    host.send(msg.SetSampling(0, 100_000))
    host.send(msg.SetHeater(1, 5000))
    host.send(msg.MoveTo(2, 40 * SPT, RATE, ACCEL), seq=77)
    host.send(msg.Dwell(3, 1_000_000))
    seen = host.run(3.0, heartbeat_s=None)
    fault = events(seen, E.FAULT)
    assert len(fault) == 1
    assert (fault[0].t_us, fault[0].code, fault[0].segment) == (2_000_000, msg.Fault.WATCHDOG, 2)
    profile, a_max = TrapezoidProfile(40 * SPT, RATE, ACCEL), host.dev.limits.max_accel_steps_per_s2
    v = profile.velocity(2.0)
    assert fault[0].value == round(profile.position(2.0)) + int(v * v / (2 * a_max))   # a controlled stop
    after = [s for s in samples(seen) if s.t_us > 2_000_000 + 1e6 * v / a_max]
    assert after and all(s.motor_moving == 0 and s.heater_mV == 0 and s.step_position == fault[0].value
                         for s in after)                              # sampling survives the fault
    assert host.send(msg.Heartbeat())[1].fault == msg.Fault.WATCHDOG
    reply = host.send(msg.ClearQueue())
    assert reply[0].status == S.OK
    assert (reply[1].kind, reply[1].code) == (E.FAULT_CLEARED, msg.Fault.WATCHDOG)
    assert host.send(msg.Heartbeat())[1].fault == 0
    assert host.ack(msg.MoveTo(4, 0, RATE, ACCEL)).status == S.OK
    host.run_until(is_event(E.QUEUE_EMPTY))
    assert host.dev.executor.position_steps == 0


def test_heartbeats_keep_a_long_run_alive(host):
    host.send(msg.MoveTo(0, 60 * SPT, 2000, ACCEL))                 # 96 s
    host.run_until(is_event(E.QUEUE_EMPTY), max_s=120, heartbeat_s=0.5)
    assert host.dev.fault == 0


def test_idle_device_never_trips_the_watchdog(host):
    host.send(msg.SetSampling(0, 500_000))
    host.send(msg.SetSampling(1, 0))
    host.run(30.0, heartbeat_s=None)
    assert host.dev.fault == 0 and not host.dev.active


def test_sampling_alone_arms_the_watchdog_and_the_release_stops_it(host):
    """A host that leaves sampling on and vanishes: fault watchdog after watchdog_ms, and
    fault_release_ms later sampling, the sense current and the motor are off."""
    host.send(msg.SetSampling(0, 100_000))
    assert host.dev.watchdog_armed and not host.dev.active
    lim = host.dev.limits
    seen = host.run(lim.watchdog_s + lim.fault_release_s + 1.0, heartbeat_s=None)
    assert [e.code for e in events(seen, E.FAULT)] == [msg.Fault.WATCHDOG]
    released = events(seen, E.MOTOR_RELEASED)
    assert len(released) == 1 and released[0].code == msg.Fault.WATCHDOG
    assert released[0].t_us == pytest.approx((lim.watchdog_s + lim.fault_release_s) * 1e6, abs=1)
    assert max(s.t_us for s in samples(seen)) <= released[0].t_us   # no sample after the release
    status = host.send(msg.Heartbeat())[1]
    assert status.state == msg.DeviceState.POSITION_UNKNOWN | msg.DeviceState.MOTOR_RELEASED
    assert host.ack(msg.SetPosition(0)).status == S.BAD_STATE       # the motor is off
    host.send(msg.ClearQueue())
    assert host.send(msg.Heartbeat())[1].state == msg.DeviceState.POSITION_UNKNOWN
    assert host.ack(msg.MoveTo(1, SPT, RATE, ACCEL)).status == S.BAD_STATE
    assert host.ack(msg.SetPosition(0)).status == S.OK
    assert host.ack(msg.MoveTo(1, SPT, RATE, ACCEL)).status == S.OK


def test_heater_alone_arms_the_watchdog(host):
    host.send(msg.SetHeater(0, 4000))
    assert host.dev.active
    seen = host.run(2.5, heartbeat_s=None)
    assert [e.code for e in events(seen, E.FAULT)] == [msg.Fault.WATCHDOG]
    assert host.dev.executor.heater_mV == 0


def test_81_turns_breaks_nothing(host, bench):
    host.send(msg.SetSampling(0, 200_000))
    host.send(msg.MoveTo(1, 81 * SPT, 16_000, 320_000))
    host.send(msg.MoveTo(2, 100 * SPT, 16_000, 320_000))
    seen = host.run_until(is_event(E.QUEUE_EMPTY), max_s=30)
    got = samples(seen)
    lengths = [bench.position.length_mm(s.position_raw) for s in got]
    assert all(140 < x < 300 for x in lengths)
    full = host.dev.plant.quasi_static(100.0).length_mm
    assert lengths[-1] == pytest.approx(full, abs=0.3)


def test_advance_stops_at_the_first_non_sample_frame(host):
    host.send(msg.SetSampling(0, 10_000))
    host.send(msg.Dwell(1, 1_000_000))
    advanced = host.dev.advance(5.0, 1 << 20)
    assert advanced == pytest.approx(1.0)
    frames = host.send_bytes(b"")
    assert isinstance(frames[-1], msg.Event) and frames[-1].kind == E.QUEUE_EMPTY
    assert len(samples(frames)) == 99          # the sample due at 1.0 s comes after the segment end
    host.dev.advance(0.0, 1 << 20)
    assert [s.t_us for s in samples(host.send_bytes(b""))] == [1_000_000]
    # and at the byte budget
    host.dev.advance(5.0, 200)
    assert 200 <= len(host.dev.take_output()) < 260
