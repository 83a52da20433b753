"""Human-readable printout of a compiled plan (used by ``tsa-bench validate``)."""

from __future__ import annotations

from tsa_bench.plan.actions import KINDS, Segment
from tsa_bench.plan.model import Plan


def format_duration(seconds: float) -> str:
    """``h:mm:ss`` (rounded to the nearest second)."""
    total = int(round(seconds))
    hours, rest = divmod(total, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}"


def _num(x: float | None, unit: str) -> str:
    return "unlimited" if x is None else f"{x:g} {unit}"


def _bound(x: float | None, unbounded: str) -> str:
    return unbounded if x is None else f"{x:g}"


def _part_of(a: dict) -> str:
    """Where a heater level of a combined step (twist_heat) belongs, or ''."""
    if "step" not in a:
        return ""
    if a["sub_move"]:
        return f" ({a['step']}: during sub-move {a['sub_move']}/{a['sub_moves']} to {a['sub_move_target_turns']:g} turns)"
    return f" ({a['step']}: after its {a['sub_moves']} sub-moves)"


def describe_segment(seg: Segment) -> str:
    """One line such as ``#12  move   target 17 turns @ 3.33 turns/s, 50 turns/s^2  (cycle 0, lifetime.yaml:31)``."""
    a = seg.params()
    text = {
        "move": lambda: f"target {a['target_turns']:g} turns @ {a['rate_turns_per_s']:g} turns/s, "
                        f"{a['accel_turns_per_s2']:g} turns/s^2",
        "hold": lambda: f"{a['duration_s']:g} s",
        "settle": lambda: f"until settled over {a['window_s']:g} s"
                          + "".join(f", {lab} <= {a[k]:g} {unit}" for k, lab, unit in
                                    (("max_dR_dt_ohm_per_s", "|dR/dt|", "ohm/s"),
                                     ("max_dL_dt_mm_per_s", "|dL/dt|", "mm/s")) if a[k] is not None)
                          + f"; {a['min_duration_s']:g} .. {a['max_duration_s']:g} s",
        "heater": lambda: f"{a['voltage_V']:g} V" + _part_of(a),
        "sampling": lambda: f"period {a['period_s']:g} s",
        "prompt": lambda: repr(a["text"]) + ("" if a["load_g"] is None else f", load {a['load_g']:g} g"),
        "track_length": lambda: "to " + ", ".join(f"{t:g} mm (hold {h:g} s)" for t, h in zip(a["targets_mm"], a["hold_s"]))
                                + f" from resistance, model {a['model_path']}",
    }[seg.kind]()
    where = seg.source if seg.cycle is None else f"cycle {seg.cycle}, {seg.source}"
    return f"#{seg.index:<6d} {seg.kind:<8s} {text}  ({where})"


def format_summary(plan: Plan, max_listed: int = 12) -> str:
    """Multi-line summary: counts, estimated duration, ranges, loads, prompts, cycles, limits,
    then the first and last segments (``max_listed`` in all; 0 lists none)."""
    s = plan.summary()
    lim = plan.limits
    per_kind = ", ".join(f"{k} {s.counts_by_kind[k]:,}" for k in KINDS)
    loads = ", ".join(f"{g:g} g" for g in s.loads_g) or "none given"
    lines = [
        f"Protocol:   {plan.name}" + (f"  ({plan.path})" if plan.path else ""),
    ]
    if plan.description:
        lines.append(f"            {plan.description.strip()}")
    if plan.metadata:
        lines.append("Metadata:   " + ", ".join(f"{k}={v}" for k, v in plan.metadata.items()))
    lines += [
        f"Segments:   {s.segment_count:,} ({per_kind})",
        f"Duration:   {format_duration(s.duration_s)} estimated "
        f"(moves {format_duration(s.move_duration_s)}, holds {format_duration(s.hold_duration_s)}; "
        "operator prompts not included"
        + (", settle holds at their maximum)" if s.counts_by_kind.get("settle") else ")"),
        f"Twist:      {s.twist_range_turns[0]:g} .. {s.twist_range_turns[1]:g} turns "
        f"(ends at {s.final_twist_turns:g})",
        f"Heater:     {s.voltage_range_V[0]:g} .. {s.voltage_range_V[1]:g} V (ends at {s.final_voltage_V:g})",
        f"Sampling:   {plan.sampling_period_s:g} s initial"
        + ("" if s.sampling_period_range_s[0] == s.sampling_period_range_s[1]
           else f" (range {s.sampling_period_range_s[0]:g} .. {s.sampling_period_range_s[1]:g} s)"),
        f"Loads:      {loads}",
        f"Prompts:    {s.prompt_count}",
        f"Cycles:     {s.cycles} (outermost repeat)" if s.cycles else "Cycles:     none (no repeat)",
        f"Limits:     twist {_bound(lim.min_twist_turns, '-inf')} .. {_bound(lim.max_twist_turns, 'inf')} turns, "
        f"heater <= {_num(lim.max_heater_voltage_V, 'V')}, rate <= {_num(lim.max_rate_turns_per_s, 'turns/s')}, "
        f"accel <= {_num(lim.max_accel_turns_per_s2, 'turns/s^2')}",
    ]
    if max_listed > 0 and plan.segments:
        segs = plan.segments
        head = max_listed - max_listed // 3 if len(segs) > max_listed else len(segs)
        tail = max_listed - head if len(segs) > max_listed else 0
        lines.append("Segments:")
        lines += [f"  {describe_segment(seg)}" for seg in segs[:head]]
        if tail:
            lines.append(f"  ... {len(segs) - head - tail:,} more ...")
            lines += [f"  {describe_segment(seg)}" for seg in segs[-tail:]]
    return "\n".join(lines)
