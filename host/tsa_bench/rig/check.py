"""`tsa-bench check`: is the rig alive and do its sensors read sensibly?

Units: length in mm, resistance in ohm, twist in turns, heater in V, time in s.

Contract: :func:`check_rig` reads the device's identity (firmware version, protocol
version; the handshake already refused a catalogue mismatch), its status (latched
fault, queue), then samples for ``duration_s`` at ``period_s`` and summarises each
sensor raw and converted with the bench calibration: mean, min, max, standard
deviation, how many readings were flagged (resistance not measured, over-range,
position read failed). :func:`findings` turns the report into warnings a person should
act on (a fault, a sensor that never read, a reading outside its range, a stuck
sensor). Nothing moves and the heater stays off.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tsa_bench.device.faults import latched_text
from tsa_bench.protocol import msg
from tsa_bench.rig.link import RigLink


@dataclass(frozen=True)
class SensorStats:
    """One sensor over the check: raw counts and the converted value, finite readings only."""

    name: str
    unit: str
    raw_mean: float
    mean: float
    lo: float
    hi: float
    std: float
    valid: int
    total: int


@dataclass(frozen=True)
class CheckReport:
    identity: msg.Identity
    status: msg.QueueStatus
    samples: int
    duration_s: float
    twist_turns: float
    heater_V: float
    length: SensorStats
    resistance: SensorStats
    flags: dict[str, int]

    @property
    def position_unknown(self) -> bool:
        """The device does not know the motor's step position (no twist zero declared)."""
        return bool(self.status.state & msg.DeviceState.POSITION_UNKNOWN)


def _stats(name: str, unit: str, raw: np.ndarray, value: np.ndarray) -> SensorStats:
    ok = np.isfinite(value)
    v, r = value[ok], raw[ok]
    if not len(v):
        nan = float("nan")
        return SensorStats(name, unit, nan, nan, nan, nan, nan, 0, len(value))
    return SensorStats(name, unit, float(r.mean()), float(v.mean()), float(v.min()), float(v.max()),
                       float(v.std()), int(ok.sum()), len(value))


def check_rig(link: RigLink, duration_s: float = 2.0, period_s: float = 0.1,
              on_sample: Callable[[msg.Sample], None] | None = None) -> CheckReport:
    """Identity, status and ``duration_s`` of samples (module contract)."""
    status = link.status()
    link.set_sampling(period_s)
    got = link.samples(duration_s, on_sample)
    link.set_sampling(0)
    bench = link.bench
    flags = np.array([s.adc_flags for s in got], dtype=np.uint8)
    pos_raw = np.array([s.position_raw for s in got], dtype=float)
    res_raw = np.array([s.resistance_raw for s in got], dtype=float)
    length = bench.position.length_mm(pos_raw)
    length[(flags & msg.AdcFlags.POSITION_INVALID) != 0] = np.nan
    resistance = bench.resistance.resistance_ohm(res_raw)
    resistance[(flags & msg.AdcFlags.RESISTANCE_NOT_MEASURED) != 0] = np.nan
    counts = {f.name.lower(): int(((flags & f) != 0).sum()) for f in msg.AdcFlags}
    last = got[-1]
    return CheckReport(link.identity, status, len(got), (got[-1].t_us - got[0].t_us) / 1e6, 
                       last.step_position / link.steps_per_turn, last.heater_mV / 1000.0,
                       _stats("length", "mm", pos_raw, length), _stats("resistance", "ohm", res_raw, resistance),
                       counts)


def findings(report: CheckReport, position_range_mm: tuple[float, float] | None = None,
             cleared: msg.QueueStatus | None = None) -> list[str]:
    """What a person should look at (empty: the rig looks sound); ``cleared`` is the status
    that showed a fault latched before the check and cleared since."""
    out = []
    if cleared is not None:
        out.append(f"{latched_text(cleared, report.identity)} (cleared before the check read the sensors)")
    if report.status.fault:
        out.append(latched_text(report.status, report.identity))
    if report.position_unknown:
        out.append("the device does not know the motor's position (it powered up, reset while moving, or released "
                   "the motor): moves are refused until the twist zero is declared; hang the TSA untwisted and "
                   "run `tsa-bench zero` (or `tsa-bench zero --turns N`)")
    for s, what in ((report.length, "the position sensor (ADS1115 on I2C)"),
                    (report.resistance, "the resistance converter (CS5513, sense current)")):
        if s.valid == 0:
            out.append(f"{s.name}: no valid reading in {s.total} samples: check {what}")
        elif s.valid < s.total:
            out.append(f"{s.name}: {s.total - s.valid} of {s.total} readings invalid or not measured")
    if report.flags.get("resistance_overrange"):
        out.append(f"resistance: {report.flags['resistance_overrange']} readings over range (open circuit, or "
                   "more than the converter's span: check the string's connections)")
    if report.length.valid and report.length.std == 0 and report.length.total >= 5:
        out.append("length: the reading did not change at all (a stuck or unconnected sensor reads constant; "
                   "a real one shows a count or two of noise)")
    if position_range_mm and report.length.valid:
        lo, hi = position_range_mm
        if not lo <= report.length.mean <= hi:
            out.append(f"length: {report.length.mean:.1f} mm is outside the sensor's {lo:g}..{hi:g} mm: "
                       "check position_sensor in the bench file (tsa-bench calibrate position)")
    return out
