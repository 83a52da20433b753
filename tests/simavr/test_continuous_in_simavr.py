"""The continuous sampler (860 samples/s) of the firmware ELF in simavr, where a real Mega
is unforgiving: stamps against the emulated ADS1115's true conversion starts, a burst of
host frames during a move at the top rate, a silent ALERT/RDY line, a NACK while
switching into continuous mode. Each test failed on the firmware before these were
fixed (noted per test). Device times are kept short: simavr runs near real time here."""

from __future__ import annotations

import bisect
import time

from tests.simavr.conftest import simavr_port
from tsa_bench.device import BenchClient
from tsa_bench.protocol import encode, msg
from tsa_bench.protocol.blocks import ADS1115_CONVERSION_US

E = msg.EventKind
TOP_RATE, TOP_ACCEL = 16_000, 320_000


def session(port) -> BenchClient:
    client = BenchClient(port, ack_timeout_s=1.0)
    client.connect(10.0)
    client.set_position(0)
    return client


def collect(client: BenchClient, done, timeout_s: float = 120.0) -> tuple[list, list]:
    """(samples, events) until ``done(samples, events)``, heartbeating every 0.2 s of wall time."""
    samples: list[msg.Sample] = []
    events: list[msg.Event] = []
    deadline, beat = time.monotonic() + timeout_s, time.monotonic()
    while not done(samples, events):
        assert time.monotonic() < deadline, f"timed out; events {events[-5:]}"
        for m in client.poll():
            if isinstance(m, msg.Sample):
                samples.append(m)
            elif isinstance(m, msg.Event):
                events.append(m)
        if time.monotonic() - beat > 0.2:
            client.command(msg.Heartbeat())
            beat = time.monotonic()
    return samples, events


def trace_starts(bench) -> tuple[list[float], list[int]]:
    """The emulated ADS1115's conversion starts (firmware clock, us) and the A4988's step
    count at each, from the harness trace."""
    rows = [line.split() for line in (bench.trace_text or "").splitlines() if line.startswith("ads_start")]
    rows.sort(key=lambda r: float(r[1]))
    return [float(r[1]) for r in rows], [int(r[2]) for r in rows]


def gaps(samples: list[msg.Sample]) -> int:
    return sum(b.counter - a.counter - 1 for a, b in zip(samples, samples[1:]))


def moved_to(target: int, segment: int):
    return lambda s, e: any(ev.kind == E.SEGMENT_DONE and ev.segment == segment for ev in e)


def test_stamps_are_the_true_conversion_starts_while_moving_at_the_top_rate(firmware_dir):
    """At 860 samples/s while the motor turns at 16,000 steps/s, every sample's t_us is
    within 100 us of its conversion's true start and its step position is the A4988's
    count at that instant (within the ISR's few microseconds: 2 steps); none is lost.
    (Before: stamps -2.6 ms .. +0.93 ms off, 10 % beyond 100 us, the position a median 22
    steps ahead.)"""
    with simavr_port(firmware_dir, trace=True) as (port, bench):
        client = session(port)
        client.command(msg.SetSampling(1, ADS1115_CONVERSION_US))
        client.command(msg.MoveBy(2, 24_000, TOP_RATE, TOP_ACCEL))
        samples, _ = collect(client, moved_to(24_000, 2))
        client.command(msg.SetSampling(3, 0))
    starts, steps = trace_starts(bench)
    moving = [s for s in samples if s.motor_moving]
    assert len(moving) > 1000 and gaps(samples) == 0
    worst_t = worst_steps = 0.0
    for s in samples:
        i = bisect.bisect_left(starts, s.t_us)
        j = min((k for k in (i - 1, i) if 0 <= k < len(starts)), key=lambda k: abs(starts[k] - s.t_us))
        worst_t = max(worst_t, abs(starts[j] - s.t_us))
        worst_steps = max(worst_steps, abs(steps[j] - s.step_position))
    assert worst_t <= 100.0, worst_t
    assert worst_steps <= 2, worst_steps
    assert max(b.step_position - a.step_position for a, b in zip(moving, moving[1:])) > 15   # really at speed


def test_a_burst_of_heartbeats_during_a_top_rate_move_costs_no_step_and_no_sample(firmware_dir):
    """300 HEARTBEATs back to back while sampling at 860/s and moving at 16,000 steps/s:
    no step underrun, no sample lost (host frames wait while samples need the line; at
    most two frames a main-loop pass, steps fed after each). (Before: 4 underruns, passes
    up to 20 ms, 87 samples lost.)"""
    with simavr_port(firmware_dir) as (port, bench):
        client = session(port)
        client.command(msg.SetSampling(1, ADS1115_CONVERSION_US))
        client.command(msg.MoveBy(2, 64_000, TOP_RATE, TOP_ACCEL))
        first, _ = collect(client, lambda s, e: sum(x.motor_moving for x in s) > 200)
        port.write(b"".join(encode(msg.Heartbeat(), 1000 + i) for i in range(300)))
        rest, events = collect(client, moved_to(64_000, 2))
        status = client.status()
    samples = first + rest
    assert status.step_underruns == 0
    assert not [e for e in events if e.kind == E.STEP_UNDERRUN]
    assert gaps(samples) == 0
    assert status.max_pass_us < 10_000                 # within the 10 ms of queued steps
    assert bench.summary["steps"]["total"] == 64_000


def test_an_unwired_ready_line_restarts_the_sensor_then_faults_by_name(firmware_dir):
    """ALERT/RDY never reaches D2: the ADS1115 is set up again after three silent
    conversions (EVENT sensor_restarted, once), and 200 ms on fault position_sensor.
    (Before: no sample, no event, no fault.)"""
    with simavr_port(firmware_dir, rdy_cuts=("0",)) as (port, bench):
        client = session(port)
        client.command(msg.SetSampling(1, ADS1115_CONVERSION_US))
        samples, events = collect(client, lambda s, e: any(x.kind == E.FAULT for x in e))
        status = client.status()
    fault = next(e for e in events if e.kind == E.FAULT)
    assert msg.Fault(fault.code) == msg.Fault.POSITION_SENSOR
    restarted = [e for e in events if e.kind == E.SENSOR_RESTARTED]
    assert len(restarted) == 1 and restarted[0].t_us < fault.t_us
    assert not samples
    assert status.fault == msg.Fault.POSITION_SENSOR and status.sensor_restarts >= 40
    assert bench.summary["adc"]["ads1115_rdy_pulses_cut"] > 100


def test_a_nack_while_switching_into_continuous_mode_is_retried(firmware_dir):
    """The ADS1115 refuses its config write three times as continuous mode is set up: the
    switch is retried and every later sample is valid, with one EVENT sensor_restarted and
    no fault. (Before: every later sample position_invalid, 1,985 of 1,985.)"""
    with simavr_port(firmware_dir, twi_faults=("nackcfg:3",)) as (port, bench):
        client = session(port)
        client.command(msg.SetSampling(1, ADS1115_CONVERSION_US))
        samples, events = collect(client, lambda s, e: len(s) > 500)
        status = client.status()
    assert bench.summary["twi"]["naks_injected"] == 3
    assert not [s for s in samples if s.adc_flags & msg.AdcFlags.POSITION_INVALID]
    assert [e.kind for e in events if e.kind in (E.SENSOR_RESTARTED, E.FAULT)] == [E.SENSOR_RESTARTED]
    assert status.sensor_restarts == 3 and status.fault == 0
    assert status.sensor_period_ns == 0 or abs(status.sensor_period_ns - 1e9 / 860) < 2000


def test_a_slow_stop_is_no_step_underrun(firmware_dir):
    """STOP at 500 steps/s (below the start/stop speed, 800 steps/s) stops at once with no
    STEP_UNDERRUN. (Before: a false one, every time.)"""
    with simavr_port(firmware_dir) as (port, bench):
        client = session(port)
        client.command(msg.SetSampling(1, 20_000))
        client.command(msg.MoveBy(2, 10_000, 500, 1_000))
        _, events = collect(client, lambda s, e: sum(x.motor_moving for x in s) > 20)
        client.stop()
        stopped, more = collect(client, lambda s, e: any(x.kind == E.STOPPED for x in e))
        time.sleep(0.3)
        status = client.status()
        events += more + [m for m in client.poll() if isinstance(m, msg.Event)]
    assert status.step_underruns == 0 and not status.state & msg.DeviceState.POSITION_SUSPECT
    assert not [e for e in events if e.kind in (E.STEP_UNDERRUN, E.POSITION_SUSPECT)]
    assert bench.summary["steps"]["position"] == status.step_position
