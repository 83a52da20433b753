"""Plan segments -> the device commands that execute them, and whether they fit the wire.

Contract: :func:`device_commands` gives the commands of one segment, in order: a move
is one MOVE_TO, a heater or sampling change one SET_HEATER / SET_SAMPLING, a hold one
DWELL or, when it is longer than a DWELL can say (:data:`MAX_DWELL_US`, 4294.967 s),
several DWELLs of near-equal length that add up to it exactly (to the microsecond); a
settling hold is given as the DWELLs of its maximum duration (for the wire checks: the
runner sends it in short DWELLs, :mod:`tsa_bench.runner.settle`).
Prompts have no device command (the host handles them), nor has a ``track_length`` (its
moves and DWELLs are decided while running, :mod:`tsa_bench.runner.tracking`). :func:`plan_problems` lists,
for a plan on a bench, every segment whose commands would not fit their wire fields
(a target beyond the 32-bit step range on a bench without a twist limit, a heater
voltage beyond 65.535 V, a load beyond the simulated bench's 32-bit milligrams), so
`validate` refuses exactly what `run` would fail on, before anything moves.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

from tsa_bench.plan import Hold, Move, Plan, Prompt, Segment, SetHeater, SetSampling, Settle, TrackLength
from tsa_bench.protocol import encode, msg

NO_SEGMENT = 0xFFFF           # wire value for commands outside the plan (setup, teardown)
WIRE_SEGMENTS = 0xFFFF        # plan indices travel modulo this; the host unwraps them
MAX_DWELL_US = 2**32 - 1      # DWELL.duration_us is a u32
MAX_LOAD_MG = 2**32 - 1       # SIM_SET_LOAD.load_mg is a u32


def plan_segment(wire: int, near: int, n_segments: int) -> int:
    """The plan segment a device reports as ``wire`` (its index modulo :data:`WIRE_SEGMENTS`),
    or -1 for :data:`NO_SEGMENT` and for an index that is no segment of the plan.

    Of the plan indices congruent to ``wire``, the one nearest ``near`` (the oldest segment
    the host has not seen done): the device is always within a queue's length of it, ahead
    (queued) or just behind (a sample or event of a segment already done reaching the host
    late, samples while the device idles after its last segment), so the answer never
    jumps by a wrap of the wire field: a wire index below ``near`` is a segment before it.
    """
    if wire == NO_SEGMENT:
        return -1
    idx = near + (wire - near + WIRE_SEGMENTS // 2) % WIRE_SEGMENTS - WIRE_SEGMENTS // 2
    return idx if 0 <= idx < n_segments else -1


def dwell_chunks_us(duration_s: float) -> list[int]:
    """A hold split into DWELL durations (us), each <= MAX_DWELL_US, summing to the hold."""
    total = round(duration_s * 1e6)
    k = max(1, math.ceil(total / MAX_DWELL_US))
    base, extra = divmod(total, k)
    return [base + (1 if i < extra else 0) for i in range(k)]


def device_commands(seg: Segment, steps_per_turn: int) -> list[NamedTuple]:
    """The device commands of one plan segment (none for a prompt)."""
    a, wire, spt = seg.action, seg.index % WIRE_SEGMENTS, steps_per_turn
    if isinstance(a, Move):
        return [msg.MoveTo(wire, round(a.target_turns * spt), max(1, round(a.rate_turns_per_s * spt)),
                           max(1, round(a.accel_turns_per_s2 * spt)))]
    if isinstance(a, Hold):
        return [msg.Dwell(wire, us) for us in dwell_chunks_us(a.duration_s)]
    if isinstance(a, Settle):  # at most this; the runner sends it in short DWELLs (runner/settle.py)
        return [msg.Dwell(wire, us) for us in dwell_chunks_us(a.max_duration_s)]
    if isinstance(a, SetHeater):
        return [msg.SetHeater(wire, round(a.voltage_V * 1000))]
    if isinstance(a, SetSampling):
        return [msg.SetSampling(wire, round(a.period_s * 1e6))]
    if isinstance(a, (Prompt, TrackLength)):  # the host answers prompts; tracking decides while running
        return []
    raise TypeError(f"segment {seg.index} ({seg.kind}) has no device command")


def load_mg(load_g: float) -> int:
    """A declared hanging mass as SIM_SET_LOAD's milligrams."""
    return round(load_g * 1000)


def plan_problems(plan: Plan, steps_per_turn: int) -> list[str]:
    """``"source: what"`` for every segment whose commands cannot be sent (empty: all fit)."""
    problems: list[str] = []
    folder = Path(plan.path).parent if plan.path else None

    def where(source: str) -> str:  # "file.yaml:LINE" -> the path the user gave
        return str(folder / source) if folder is not None else source

    segments = plan.segments
    # a segment whose step and target came earlier has that segment's commands up to the
    # wire segment index, which always fits: checking the first of each is checking all
    distinct = getattr(segments, "distinct", None)
    prompts = getattr(segments, "prompts", None)
    if distinct is None or prompts is None:
        distinct = segments
        prompts = [s for s in segments if isinstance(s.action, Prompt)]
    loads = [(plan.load_g, where(f"{Path(plan.path).name}:1") if plan.path else "load_g")] + [
        (s.action.load_g, where(s.source)) for s in prompts]
    for load_g, at in loads:
        if load_g is not None and load_mg(load_g) > MAX_LOAD_MG:
            problems.append(f"{at}: load_g {load_g:g} g is more than the {MAX_LOAD_MG / 1000:g} g "
                            "a bench command can carry")
    seen: set[tuple[str, str]] = set()
    for seg in distinct:
        for command in device_commands(seg, steps_per_turn):
            try:
                encode(command, 0)
            except ValueError:
                key = (seg.source, seg.kind)
                if key not in seen:
                    seen.add(key)
                    problems.append(f"{where(seg.source)}: {seg.kind} {seg.params()} does not fit the device "
                                    f"command {type(command).__name__} {tuple(command)} at {steps_per_turn} "
                                    "steps/turn")
    return problems
