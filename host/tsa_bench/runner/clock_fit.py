"""The device's clock against the host's, and the position sensor's against the device's.

Units: host time in s (``time.monotonic``), device time in us since the device booted,
sensor time in conversions (the sample counter).

The method is Klipper's (klippy/clocksync.py for the MCU clock, klippy/extras/
bulk_sensor.py for a sensor's own clock): a linear regression whose averages decay
exponentially, so it follows a slowly drifting oscillator, with the round trip's
lower bound as the offset between sending and the device reading its clock.

Contract.

* :class:`DeviceClockFit` takes each HEARTBEAT round trip ``(sent_s, received_s,
  device_us)`` (the QUEUE_STATUS that answered it), regresses the device clock on the
  send time (decay 1/30), drops a reply whose clock lies more than 5 standard
  deviations (and 500 us) ahead of the prediction (it waited on the line), and adds the
  smallest half round trip seen (aged by 10 us an hour) as the send-to-read delay.
  :meth:`DeviceClockFit.device_us` maps a host time to device time (None before the
  first round trip); :meth:`DeviceClockFit.summary` is what the run file keeps.
* :class:`SensorClockFit` takes the continuous sampler's samples ``(counter, t_us)``
  (``t_us`` the ALERT/RDY edge the device stamped: the conversion's start, a few
  microseconds of interrupt latency late) and regresses the stamp on the counter (decay
  1/20): the slope is the sensor's own sample period in device us. A run of samples
  (a "stretch") starts afresh where they stop following on: a sample period of
  ``SINGLE_SHOT_MIN_PERIOD_US`` or more (single-shot sampling), a change of conversions
  per sample, or a stamp off the prediction by more than a quarter period (a restarted
  sensor). :meth:`SensorClockFit.stamp` returns the time a sample is stored with: the
  regression's, once the stretch holds ``MIN_FIT_SAMPLES``, else the device's own. Times
  stay strictly increasing: a fitted time is within a quarter period of its stamp (or the
  stretch starts afresh), and stamps are a period or more apart. :meth:`SensorClockFit.summary` gives the period, its error
  against 1/860 s in ppm, and the largest and RMS difference between the device's
  stamps and the fit.
"""

from __future__ import annotations

import json
import math
from typing import Any

from tsa_bench.protocol.blocks import ADS1115_SPS, SINGLE_SHOT_MIN_PERIOD_US

#: Samples a stretch needs before its stamps come from the fit.
MIN_FIT_SAMPLES = 32
_NOMINAL_PERIOD_US = 1e6 / ADS1115_SPS
_RTT_AGE = 10e-6 / 3600.0      # the smallest round trip ages by 10 us an hour (as Klipper)


class DecayingRegression:
    """y against x, averages decaying by ``decay`` per point (Klipper's regression)."""

    def __init__(self, decay: float, slope: float) -> None:
        self.decay = decay
        self.n = 0
        self.x_avg = self.y_avg = 0.0
        self.x_var = self.xy_cov = 0.0
        self._slope0 = slope

    def reset(self, x: float, y: float) -> None:
        self.n = 1
        self.x_avg, self.y_avg = x, y
        self.x_var = self.xy_cov = 0.0

    def update(self, x: float, y: float) -> None:
        if self.n == 0:
            self.reset(x, y)
            return
        d = self.decay
        dx = x - self.x_avg
        self.x_avg += d * dx
        self.x_var = (1 - d) * (self.x_var + dx * dx * d)
        dy = y - self.y_avg
        self.y_avg += d * dy
        self.xy_cov = (1 - d) * (self.xy_cov + dx * dy * d)
        self.n += 1

    @property
    def slope(self) -> float:
        return self.xy_cov / self.x_var if self.x_var > 0 else self._slope0

    def predict(self, x: float) -> float:
        return self.y_avg + (x - self.x_avg) * self.slope


class DeviceClockFit:
    """Device clock (us) against host time (s) from HEARTBEAT round trips (see module)."""

    DECAY = 1.0 / 30

    def __init__(self) -> None:
        self._fit = DecayingRegression(self.DECAY, 1e6)
        self._pred_var = (1000.0) ** 2        # us^2, until predictions are known
        self.min_half_rtt_s = math.inf
        self._min_rtt_at = 0.0
        self.round_trips = 0
        self.dropped = 0

    def add(self, sent_s: float, received_s: float, device_us: float) -> None:
        if received_s < sent_s:
            return
        fit = self._fit
        self.round_trips += 1
        if fit.n:
            err = device_us - fit.predict(sent_s)
            if err * err > 25 * self._pred_var and err * err > 500.0 ** 2:
                if err > 0:            # it waited on the line: not a clock sample
                    self.dropped += 1
                    return
                self._pred_var = 1000.0 ** 2
            else:
                self._pred_var = (1 - self.DECAY) * (self._pred_var + err * err * self.DECAY)
        fit.update(sent_s, device_us)
        half = (received_s - sent_s) / 2
        if half < self.min_half_rtt_s + (sent_s - self._min_rtt_at) * _RTT_AGE:
            self.min_half_rtt_s, self._min_rtt_at = half, sent_s

    def device_us(self, host_s: float) -> float | None:
        """Device time at host time ``host_s`` (None before the first round trip)."""
        if not self._fit.n:
            return None
        return self._fit.predict(host_s - self.min_half_rtt_s)

    def summary(self) -> dict[str, Any]:
        fit = self._fit
        return {"round_trips": self.round_trips, "dropped": self.dropped,
                "rate_us_per_s": fit.slope, "drift_ppm": (fit.slope / 1e6 - 1) * 1e6,
                "host_s": fit.x_avg + (self.min_half_rtt_s if math.isfinite(self.min_half_rtt_s) else 0.0),
                "device_us": fit.y_avg,
                "min_round_trip_ms": 2e3 * self.min_half_rtt_s if math.isfinite(self.min_half_rtt_s) else None,
                "prediction_rms_us": math.sqrt(self._pred_var) if fit.n > 1 else None}


class SensorClockFit:
    """The continuous sampler's stamps against its sample counter (see module)."""

    DECAY = 1.0 / 20

    def __init__(self) -> None:
        self._fit = DecayingRegression(self.DECAY, _NOMINAL_PERIOD_US)
        self._last: tuple[int, float] | None = None   # (counter, device stamp) of the previous sample
        self._k = 0
        self.stretches = 0
        self.samples = 0                  # stamped from the fit
        self.max_residual_us = 0.0
        self._sq_sum = 0.0
        self.period_us: float | None = None

    def stamp(self, counter: int, t_us: float) -> float:
        """The time (device us) the sample with this counter and device stamp is stored with."""
        last, self._last = self._last, (counter, t_us)
        fit = self._fit
        if last is None or counter <= last[0]:
            fit.n = 0
            return t_us
        per = (t_us - last[1]) / (counter - last[0])
        if per >= SINGLE_SHOT_MIN_PERIOD_US:
            fit.n = 0
            return t_us
        k = max(1, round(per / _NOMINAL_PERIOD_US))
        if fit.n:   # fit.predict and fit.slope, inline (once per sample)
            slope = fit.xy_cov / fit.x_var if fit.x_var > 0 else fit._slope0
            if k != self._k or abs(t_us - (fit.y_avg + (counter - fit.x_avg) * slope)) > slope / 4:
                fit.n = 0                 # a restart, a gap off the grid, another period
        if fit.n == 0:
            self._k = k
            self.stretches += 1
            fit.reset(last[0], last[1])
        # fit.update(counter, t_us) and fit.predict(counter), inline: this runs once per sample
        d = fit.decay
        dx = counter - fit.x_avg
        dy = t_us - fit.y_avg
        x_avg = fit.x_avg = fit.x_avg + d * dx
        y_avg = fit.y_avg = fit.y_avg + d * dy
        x_var = fit.x_var = (1 - d) * (fit.x_var + dx * dx * d)
        xy_cov = fit.xy_cov = (1 - d) * (fit.xy_cov + dx * dy * d)
        fit.n += 1
        if fit.n < MIN_FIT_SAMPLES:
            return t_us
        slope = xy_cov / x_var if x_var > 0 else fit._slope0
        fitted = y_avg + (counter - x_avg) * slope
        residual = t_us - fitted
        self.samples += 1
        self._sq_sum += residual * residual
        if abs(residual) > self.max_residual_us:
            self.max_residual_us = abs(residual)
        self.period_us = slope / self._k
        return fitted

    def summary(self) -> dict[str, Any]:
        period = self.period_us
        return {"stretches": self.stretches, "samples_fitted": self.samples,
                "conversion_period_us": period,
                "rate_error_ppm": (period / _NOMINAL_PERIOD_US - 1) * 1e6 if period else None,
                "max_residual_us": self.max_residual_us if self.samples else None,
                "rms_residual_us": math.sqrt(self._sq_sum / self.samples) if self.samples else None}


class RunClocks:
    """Both fits for one run, and the device's longest main-loop pass (QUEUE_STATUS
    max_pass_us), as the runner uses them.

    :meth:`stamp` gives each sample's stored time: the sensor fit's for continuous
    sampling (a period under ``SINGLE_SHOT_MIN_PERIOD_US`` since the previous sample),
    the device's stamp otherwise. :meth:`event_us` places a host-side event (a prompt, a
    STOP sent) on the device's clock: through the device-clock fit once it predicts
    within ``EVENT_FIT_RMS_US`` (a real serial line), else at the latest device time
    seen (a device in this process, or simavr, whose clock does not follow the host's).
    :meth:`attrs` is what the run file keeps (docs/run-format.md, 1.3).
    """

    EVENT_FIT_RMS_US = 5000.0

    def __init__(self, in_process: bool) -> None:
        self.device = DeviceClockFit()
        self.sensor = SensorClockFit()
        self.in_process = in_process
        self.max_pass_us = 0
        self._prev_us: float | None = None

    def on_status(self, status: Any, round_trips: list[tuple[float, float, int]]) -> None:
        self.max_pass_us = max(self.max_pass_us, int(getattr(status, "max_pass_us", 0)))
        for sent_s, received_s, device_us in round_trips:
            self.device.add(sent_s, received_s, device_us)

    def stamp(self, counter: int, t_us: float) -> float:
        prev, self._prev_us = self._prev_us, t_us
        if prev is None or t_us - prev >= SINGLE_SHOT_MIN_PERIOD_US:
            return t_us
        return self.sensor.stamp(counter, t_us)

    def event_us(self, seen_us: int, host_s: float) -> float:
        if not self.in_process and self.device.round_trips >= 4:
            rms = self.device.summary()["prediction_rms_us"]
            predicted = self.device.device_us(host_s)
            if rms is not None and rms < self.EVENT_FIT_RMS_US and predicted is not None:
                return max(float(seen_us), predicted)
        return float(seen_us)

    def attrs(self) -> dict[str, Any]:
        return {"clock_fit": json.dumps({"device": self.device.summary(), "sensor": self.sensor.summary()}),
                "max_pass_us": self.max_pass_us}
