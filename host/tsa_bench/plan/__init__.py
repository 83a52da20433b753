"""Experiment protocols: load YAML protocols, validate them against bench limits, and
compile them into a sequence of segments (moves, holds, heater and sampling changes,
operator prompts) with position-pinned error reports. Every segment is checked when the
protocol loads; ``plan.segments`` expands repeat blocks again on demand (memory flat in
the number of cycles).

Typical use::

    plan = load_plan("configs/protocols/lifetime.yaml", bench_limits)   # raises PlanErrors
    print(format_summary(plan))
    for segment in plan.segments: ...
"""

from tsa_bench.plan.actions import KINDS, Action, Hold, Move, Prompt, Segment, SetHeater, SetSampling, Settle, TrackLength
from tsa_bench.plan.errors import PlanError, PlanErrors
from tsa_bench.plan.loader import DEFAULT_SAMPLING_PERIOD_S, load_plan, load_plan_text
from tsa_bench.plan.model import Plan, PlanSummary, Segments
from tsa_bench.plan.report import format_duration, format_summary

__all__ = [
    "KINDS",
    "DEFAULT_SAMPLING_PERIOD_S",
    "Action",
    "Hold",
    "Move",
    "Plan",
    "PlanError",
    "PlanErrors",
    "PlanSummary",
    "Prompt",
    "Segment",
    "Segments",
    "SetHeater",
    "SetSampling",
    "Settle",
    "TrackLength",
    "format_duration",
    "format_summary",
    "load_plan",
    "load_plan_text",
]
