"""The heater's duty rounding, as the firmware applies it (firmware/drivers/heater_scale.h).

Units: voltages in mV (the equivalent DC voltage of the PWM), supply in mV.

Contract: the firmware sets the MOSFET's duty to n/4096 with n = round(4096 V^2 / V_s^2)
(its 8-bit Timer2 PWM dithered over 16 periods) and reports the voltage that duty
applies, round(V_s sqrt(n / 4096)). :func:`applied_mV` returns exactly that integer for a
request, so the simulated device reports in SAMPLE, and heats its plant with, the same
voltage as the firmware; ``tests`` check the two agree. The smallest non-zero voltage is
V_s / 64 (375 mV at 24 V); a request below V_s / sqrt(8192) (265 mV) rounds to off.
"""

from __future__ import annotations

from math import isqrt

#: The bench's heater supply (firmware/config.h HEATER_SUPPLY_MV).
HEATER_SUPPLY_MV = 24000
#: Duty steps of the dithered PWM.
DUTY_STEPS = 4096
#: Highest request the firmware accepts (firmware/config.h MAX_HEATER_MV); requests are clamped to it.
MAX_HEATER_MV = 12000


def duty_steps(requested_mV: int, supply_mV: int = HEATER_SUPPLY_MV, max_mV: int = MAX_HEATER_MV) -> int:
    """Duty steps (of 4096) the firmware sets for a request."""
    v = max(0, min(int(requested_mV), max_mV, supply_mV))
    step = supply_mV * supply_mV // DUTY_STEPS
    return min(DUTY_STEPS, (v * v + step // 2) // step)


def applied_mV(requested_mV: int, supply_mV: int = HEATER_SUPPLY_MV, max_mV: int = MAX_HEATER_MV) -> int:
    """The equivalent voltage (mV) the firmware applies, and reports, for a request."""
    x = duty_steps(requested_mV, supply_mV, max_mV) * (supply_mV * supply_mV // DUTY_STEPS)
    r = isqrt(x)
    return r + 1 if x - r * r > r else r
