"""Checks of a plan against the connected device, before anything moves."""

from __future__ import annotations

from tsa_bench.plan import Move, Plan
from tsa_bench.plan.actions import SetSampling
from tsa_bench.protocol import msg
from tsa_bench.protocol.blocks import SINGLE_SHOT_MIN_PERIOD_US, refusal_reason


class PlanRejected(ValueError):
    """The plan does not fit the connected device's limits (nothing was sent)."""


def check_plan_against_device(plan: Plan, ident: msg.Identity) -> None:
    """Refuse a plan the device would refuse, before anything moves."""
    spt = ident.steps_per_turn
    problems = []
    summary = plan.summary()      # one pass over the segments, not one per check
    lo, hi = summary.twist_range_turns
    if round(hi * spt) > ident.max_twist_steps or round(lo * spt) < ident.min_twist_steps:
        problems.append(f"twist range {lo:g}..{hi:g} turns exceeds the device's "
                        f"{ident.min_twist_steps / spt:g}..{ident.max_twist_steps / spt:g} turns")
    vmax = summary.voltage_range_V[1]
    if round(vmax * 1000) > ident.max_heater_mV:
        problems.append(f"heater {vmax:g} V exceeds the device's {ident.max_heater_mV / 1000:g} V")
    moves_ok = between_ok = True
    for seg in plan.segments:
        a = seg.action
        if moves_ok and isinstance(a, Move) and (round(a.rate_turns_per_s * spt) > ident.max_rate_steps_per_s
                                                 or round(a.accel_turns_per_s2 * spt) > ident.max_accel_steps_per_s2):
            problems.append(f"{seg.source}: rate/acceleration beyond the device's maximum")
            moves_ok = False
        if between_ok and isinstance(a, SetSampling):
            period_us = round(a.period_s * 1e6)
            if ident.min_sample_period_us <= period_us < SINGLE_SHOT_MIN_PERIOD_US \
                    and period_us % ident.min_sample_period_us:
                command = msg.SetSampling(0, period_us)
                problems.append(f"{seg.source}: sampling period refused by the device"
                                f"{refusal_reason(command, msg.Status.BETWEEN_CONVERSIONS)}")
                between_ok = False
    pmin = summary.sampling_period_range_s[0]
    if 0 < round(pmin * 1e6) < ident.min_sample_period_us:
        problems.append(f"sampling period {pmin * 1000:g} ms is shorter than the device's "
                        f"{ident.min_sample_period_us / 1000:g} ms")
    if problems:
        raise PlanRejected("; ".join(problems))
