"""The simulated device's identity and limits, in the units the firmware works in.

Units: twist in microsteps, rate in step/s, acceleration in step/s^2, heater in mV,
watchdog and fault release in ms, sampling period in us.

Contract: :func:`device_limits` converts a :class:`BenchConfig` (turns, V, s) to the
integers a firmware build would carry, rounding to the nearest unit and saturating to
the wire type; an unlimited (``None``) bench limit becomes the wire type's extreme.
The simulated device enforces exactly these integers, and reports them in IDENTITY,
so host and device agree to the step. The shortest sampling period and the fault
release time are the firmware's (firmware/config.h; a test checks they agree): they are
properties of the device, not of the bench file.
"""

from __future__ import annotations

from dataclasses import dataclass

from tsa_bench.benchdata import BenchConfig
from tsa_bench.protocol import catalogue as msg

#: Firmware version the simulation reports (major, minor, patch).
SIM_FIRMWARE_VERSION = (0, 2, 0)
#: Shortest nonzero sampling period the device accepts (us), firmware MIN_SAMPLE_PERIOD_US:
#: one ADS1115 conversion at 860 samples/s (shorter periods are refused too_fast_for_sensor).
MIN_SAMPLING_PERIOD_US = 1163
#: A latched fault releases the motor after this long (ms), firmware FAULT_RELEASE_MS.
FAULT_RELEASE_MS = 10000

I32_MIN, I32_MAX = -(2 ** 31), 2 ** 31 - 1
U32_MAX, U16_MAX, U8_MAX = 2 ** 32 - 1, 2 ** 16 - 1, 2 ** 8 - 1


def _saturate(value: float | None, lo: int, hi: int, none_value: int) -> int:
    if value is None:
        return none_value
    return max(lo, min(hi, int(round(value))))


@dataclass(frozen=True)
class DeviceLimits:
    """Integer limits the device enforces (see module docstring)."""

    steps_per_turn: int
    min_twist_steps: int
    max_twist_steps: int
    max_rate_steps_per_s: int
    max_accel_steps_per_s2: int
    max_heater_mV: int
    queue_slots: int
    watchdog_ms: int
    min_sample_period_us: int = MIN_SAMPLING_PERIOD_US
    fault_release_ms: int = FAULT_RELEASE_MS

    @property
    def watchdog_s(self) -> float:
        return self.watchdog_ms / 1000.0

    @property
    def fault_release_s(self) -> float:
        """0.0 means never."""
        return self.fault_release_ms / 1000.0


def device_limits(bench: BenchConfig) -> DeviceLimits:
    """The bench's limits in device units (see module docstring)."""
    lim, spt = bench.limits, bench.steps_per_turn

    def per_turn(value: float | None) -> float | None:
        return None if value is None else value * spt

    return DeviceLimits(
        steps_per_turn=spt,
        min_twist_steps=_saturate(per_turn(lim.min_twist_turns), I32_MIN, I32_MAX, I32_MIN),
        max_twist_steps=_saturate(per_turn(lim.max_twist_turns), I32_MIN, I32_MAX, I32_MAX),
        max_rate_steps_per_s=_saturate(per_turn(lim.max_rate_turns_per_s), 1, U32_MAX, U32_MAX),
        max_accel_steps_per_s2=_saturate(per_turn(lim.max_accel_turns_per_s2), 1, U32_MAX, U32_MAX),
        max_heater_mV=_saturate(None if lim.max_heater_voltage_V is None else lim.max_heater_voltage_V * 1000.0,
                                0, U16_MAX, U16_MAX),
        queue_slots=_saturate(bench.queue_slots, 1, U8_MAX, 16),
        watchdog_ms=_saturate(bench.watchdog_s * 1000.0, 1, U16_MAX, 2000),
    )


def identity_message(limits: DeviceLimits, simulated: bool = True) -> msg.Identity:
    """The IDENTITY the simulated device answers HELLO with (flags: SIMULATED, unless it
    passes for hardware: a rehearsal device, ``simulated=False``)."""
    major, minor, patch = SIM_FIRMWARE_VERSION
    return msg.Identity(
        protocol_version=msg.PROTOCOL_VERSION, fw_major=major, fw_minor=minor, fw_patch=patch,
        catalogue_hash=msg.CATALOGUE_HASH, steps_per_turn=limits.steps_per_turn,
        min_twist_steps=limits.min_twist_steps, max_twist_steps=limits.max_twist_steps,
        max_rate_steps_per_s=limits.max_rate_steps_per_s, max_accel_steps_per_s2=limits.max_accel_steps_per_s2,
        max_heater_mV=limits.max_heater_mV, queue_slots=limits.queue_slots, watchdog_ms=limits.watchdog_ms,
        flags=int(msg.DeviceFlags.SIMULATED) if simulated else 0, min_sample_period_us=limits.min_sample_period_us,
        fault_release_ms=limits.fault_release_ms,
    )
