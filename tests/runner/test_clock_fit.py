"""The device-clock and sensor-clock fits (runner/clock_fit.py) against synthetic clocks
made here from first principles (an oscillator's offset and drift, a line's random
delays, an interrupt's latency), and the fits a continuous-sampling run stores."""

from __future__ import annotations

import json
import random

import h5py
import pytest

from tests.runner.helpers import plan_from_text, run_plan
from tsa_bench.runner.clock_fit import MIN_FIT_SAMPLES, DeviceClockFit, RunClocks, SensorClockFit


def test_device_clock_follows_offset_and_drift_through_line_delays():
    """A device clock 80 ppm fast with an offset, read when the HEARTBEAT has crossed the
    250 kbaud line (9 bytes, 0.36 ms, plus the host's jitter), its reply 43 bytes
    (1.72 ms plus jitter); every 17th reply held up 40 ms: the fit predicts the device
    clock within 1 ms (the reply's asymmetry is not known to it) and the drift within
    10 ppm."""
    rng = random.Random(3)
    drift, offset_us = 80e-6, 12_345_678.0

    def device_at(host_s: float) -> float:
        return offset_us + host_s * 1e6 * (1 + drift)

    fit = DeviceClockFit()
    t = 100.0
    for i in range(300):
        out = 0.00036 + rng.expovariate(1 / 0.0003)  # host -> device: the frame, the OS
        back = 0.00172 + rng.expovariate(1 / 0.0003) + (0.040 if i % 17 == 5 else 0.0)
        fit.add(t, t + out + back, device_at(t + out))
        t += 0.125 + rng.uniform(0, 0.01)
    assert fit.dropped <= 3    # a reply late on the way back is only a long round trip (a rare long OS delay on the way out is dropped)
    for probe in (t - 5.0, t - 0.5):
        assert abs(fit.device_us(probe) - device_at(probe)) < 1000.0
    s = fit.summary()
    assert abs(s["drift_ppm"] - 80) < 10
    assert 2.08 < s["min_round_trip_ms"] < 2.3                  # the two frames on the wire, and a little
    assert DeviceClockFit().device_us(1.0) is None


def test_device_clock_drops_a_reply_whose_clock_was_read_late():
    """A QUEUE_STATUS whose clock reading itself came 50 ms late (it was produced behind a
    stalled line) is no clock sample: dropped, and the prediction is unharmed."""
    fit = DeviceClockFit()
    for i in range(100):                              # the device clock is the host's (us); read 0.5 ms after sending
        t = i * 0.1
        late = 0.05 if i == 60 else 0.0
        fit.add(t, t + 0.001, (t + 0.0005 + late) * 1e6)
    assert fit.dropped == 1
    assert abs(fit.device_us(10.0) - 10.0e6) < 100


def _stamps(rng, n, period_us, t0_us, counter0=0, spike_every=0):
    """(counter, true start, device stamp) of n conversions: the stamp is the true start
    plus an interrupt latency of 2..14 us, now and then 60 us (the ISR waited)."""
    out = []
    for i in range(n):
        true = t0_us + i * period_us
        latency = rng.uniform(2.0, 14.0) + (60.0 if spike_every and i % spike_every == 7 else 0.0)
        out.append((counter0 + i, true, true + latency))
    return out


def test_sensor_clock_smooths_interrupt_latency_and_measures_the_chip():
    """An ADS1115 0.6 % slow (1169.8 us a conversion) stamped with 2..14 us of latency and
    a 60 us outlier now and then: the fitted times lie within 10 us of the true starts
    plus the mean latency, closer than the raw stamps; the period comes out right."""
    rng = random.Random(5)
    period = 1e6 / 860 * 1.006
    fit = SensorClockFit()
    rows = _stamps(rng, 3000, period, 5_000_000.0, spike_every=97)
    out = [fit.stamp(c, stamp) for c, _, stamp in rows]
    assert all(b > a for a, b in zip(out, out[1:]))
    settled = range(MIN_FIT_SAMPLES + 50, len(rows))
    fitted_err = max(abs(out[i] - rows[i][1] - 8.0) for i in settled)
    raw_err = max(abs(rows[i][2] - rows[i][1] - 8.0) for i in settled)
    assert fitted_err < 10.0 < raw_err
    s = fit.summary()
    assert abs(s["conversion_period_us"] - period) < 0.05
    assert abs(s["rate_error_ppm"] - 6000) < 60
    assert s["stretches"] == 1 and 55 < s["max_residual_us"] < 75


def test_sensor_clock_starts_afresh_after_a_restart_and_for_every_other_conversion():
    """A restarted sensor (its grid shifted by a third of a period), then sampling every
    other conversion: each is a new stretch, stamps never go back, the first ones of a
    stretch are the device's own."""
    rng = random.Random(7)
    period = 1e6 / 860
    fit = SensorClockFit()
    a = _stamps(rng, 200, period, 1e6)
    b = _stamps(rng, 200, period, a[-1][1] + 20 * period + period / 3, counter0=a[-1][0] + 21)
    c = _stamps(rng, 200, 2 * period, b[-1][1] + 2 * period, counter0=b[-1][0] + 1)
    out = [fit.stamp(n, stamp) for n, _, stamp in a + b + c]
    assert all(y > x for x, y in zip(out, out[1:]))
    assert fit.summary()["stretches"] == 3
    first_of_b = len(a)
    assert out[first_of_b + 1] == b[1][2]              # raw until the new stretch has its samples
    assert fit.summary()["conversion_period_us"] == pytest.approx(period, abs=0.1)


def test_single_shot_samples_keep_the_device_stamps():
    clocks = RunClocks(in_process=False)
    stamps = [1_000_000 + 10_000 * i + (i % 3) for i in range(50)]
    assert [clocks.stamp(i, t) for i, t in enumerate(stamps)] == stamps
    assert clocks.sensor.summary()["samples_fitted"] == 0


def test_host_events_use_the_device_clock_fit_only_when_it_predicts_well():
    clocks = RunClocks(in_process=False)
    assert clocks.event_us(500, 1.0) == 500                      # no round trip yet
    for i in range(10):
        t = 10 + i * 0.1
        clocks.device.add(t, t + 0.001, (t - 10) * 1e6 + 1e6)
    assert clocks.event_us(0, 12.0) == pytest.approx(3e6, abs=1000)
    assert RunClocks(in_process=True).event_us(500, 12.0) == 500  # in process: the device clock is exact


CONTINUOUS = """
name: continuous
sampling_period_s: 0.001163
steps:
  - move_to: {turns: 2, rate_turns_per_s: 2, accel_turns_per_s2: 20}
  - hold: {duration_s: 0.5}
"""


def test_a_continuous_run_stores_both_fits_and_the_longest_pass(tmp_path):
    """The run file keeps the fits (JSON attribute clock_fit) and max_pass_us; samples at
    860/s are stored with the sensor fit's times, strictly increasing."""
    stop, _, path = run_plan(plan_from_text(CONTINUOUS), tmp_path)
    assert stop.exit_status == "success"
    with h5py.File(path, "r") as f:
        fits = json.loads(f.attrs["clock_fit"])
        assert f.attrs["format_version"] == "1.3"
        assert int(f.attrs["max_pass_us"]) == 0           # the simulated device has no main loop
        t = f["samples/t"][()]
    sensor = fits["sensor"]
    assert sensor["samples_fitted"] > 1000 and sensor["stretches"] >= 1
    assert sensor["conversion_period_us"] == pytest.approx(1e6 / 860, abs=0.5)
    assert sensor["max_residual_us"] < 2.0                # the simulation stamps on its grid
    assert fits["device"]["round_trips"] > 0
    assert (t[1:] > t[:-1]).all()
