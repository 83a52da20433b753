"""Run engine: executes a plan on a bench and emits documents to consumers."""

from tsa_bench.runner.documents import (
    SAMPLE_COLUMNS, EventRecord, RunConsumer, RunStart, RunStop, SampleBlock, SegmentRecord,
)
from tsa_bench.runner.engine import PlanRejected, Runner, check_plan_against_device
from tsa_bench.runner.operator import AutoOperator, ConsoleOperator, Operator

__all__ = ["SAMPLE_COLUMNS", "EventRecord", "RunConsumer", "RunStart", "RunStop", "SampleBlock", "SegmentRecord",
           "PlanRejected", "Runner", "check_plan_against_device", "AutoOperator", "ConsoleOperator", "Operator"]
