"""The thesis protocols shipped in configs/protocols/ validate and encode the thesis numbers."""

from __future__ import annotations

import time
from collections import Counter
from pathlib import Path

import pytest

from tsa_bench.plan import Plan, load_plan
from plan_helpers import BENCH, PROTOCOL_DIR

EXPECTED = {
    "stiffness-3ply", "stiffness-4ply", "twist-sweep-3ply", "twist-sweep-4ply", "twist-heat-4ply",
    "quasi-static-self-sensing", "transient-steps", "lifetime",
}
PATHS = sorted(PROTOCOL_DIR.glob("*.yaml"))


def load(name: str) -> Plan:
    return load_plan(PROTOCOL_DIR / f"{name}.yaml", BENCH)


def move_targets(plan: Plan) -> list[float]:
    return [s.action.target_turns for s in plan.segments if s.kind == "move"]


def holds_s(plan: Plan) -> list[float]:
    return [s.action.duration_s for s in plan.segments if s.kind == "hold"]


def test_all_expected_protocols_are_shipped() -> None:
    assert {p.stem for p in PATHS} >= EXPECTED


@pytest.mark.parametrize("path", PATHS, ids=[p.stem for p in PATHS])
def test_protocol_validates_and_ends_safe(path: Path) -> None:
    plan = load_plan(path, BENCH)
    text = path.read_text(encoding="utf-8")
    assert plan.name == path.stem and plan.source_text == text and plan.path == str(path)
    assert text.startswith("#") and "section 2." in text.split("\nname:")[0]
    assert plan.sampling_period_s == 0.1
    summary = plan.summary()
    assert summary.final_twist_turns == 0 and summary.final_voltage_V == 0
    assert plan.segments[-1].kind == "heater" and plan.segments[-1].action.voltage_V == 0
    assert all(s.source.startswith(f"{path.name}:") for s in plan.segments)


def test_stiffness_loads_go_up_then_down_with_60_s_holds() -> None:
    for name, top in (("stiffness-3ply", 200), ("stiffness-4ply", 250)):
        plan = load(name)
        loads = list(plan.summary().loads_g)
        peak = loads.index(top)
        assert loads[: peak + 1] == sorted(loads[: peak + 1]) and loads[peak:] == sorted(loads[peak:], reverse=True)
        assert set(holds_s(plan)) == {60} and move_targets(plan) == []


def test_twist_sweeps_use_thesis_loads_and_full_twist() -> None:
    for name, loads, full in (("twist-sweep-3ply", (100, 150, 200), 72), ("twist-sweep-4ply", (150, 200, 250), 81)):
        s = load(name).summary()
        assert s.loads_g == loads and s.twist_range_turns == (0, full) and s.voltage_range_V == (0, 0)


def test_twist_heat_steps_voltage_up_and_down_at_full_twist() -> None:
    plan = load("twist-heat-4ply")
    s = plan.summary()
    assert s.loads_g == (250,) and s.twist_range_turns == (0, 81) and 0 < s.voltage_range_V[1] <= 10
    volts = [seg.action.voltage_V for seg in plan.segments if seg.kind == "heater"]
    peak = volts.index(max(volts))
    assert volts[: peak + 1] == sorted(volts[: peak + 1]) and volts[peak:] == sorted(volts[peak:], reverse=True)
    # every voltage level is held for at least a minute (cooling takes > 1 min)
    for i, seg in enumerate(plan.segments[:-1]):
        if seg.kind == "heater" and plan.segments[i + 1].kind == "hold":
            assert plan.segments[i + 1].action.duration_s >= 60
    first_heat = next(i for i, seg in enumerate(plan.segments) if seg.kind == "heater" and seg.action.voltage_V > 0)
    moves_before = [seg.action.target_turns for seg in plan.segments[:first_heat] if seg.kind == "move"]
    assert moves_before[-1] == 81


def test_quasi_static_twist_within_20_55_and_3_minute_holds() -> None:
    plan = load("quasi-static-self-sensing")
    s = plan.summary()
    assert s.loads_g == (450, 550) and s.twist_range_turns == (0, 55)
    assert all(t == 0 or 20 <= t <= 55 for t in move_targets(plan))
    segs = plan.segments
    for i, seg in enumerate(segs):
        if seg.kind == "move" and seg.action.target_turns >= 20:
            assert segs[i + 1].action == type(segs[i + 1].action)(180)
    assert plan.metadata["scheme"] == 1


def test_transient_step_durations() -> None:
    plan = load("transient-steps")
    counts = Counter(holds_s(plan))
    assert all(counts[d] == 10 for d in (2.4, 6, 17, 32, 98))
    assert plan.summary().loads_g == (350,)
    assert set(move_targets(plan)) == {0, 15, 17, 19, 21, 23, 25}


def test_lifetime_cycles_duration_and_numbering() -> None:
    plan = load("lifetime")
    s = plan.summary()
    assert s.cycles == 596 and plan.load_g == 550
    assert 11_000 < s.segment_count < 13_000
    assert 2.5 * 3600 <= s.duration_s <= 2.85 * 3600
    assert s.twist_range_turns == (0, 25)
    cycles = [seg.cycle for seg in plan.segments if seg.cycle is not None]
    assert cycles[0] == 0 and cycles[-1] == 595 and cycles == sorted(cycles)
    per_cycle = [seg.action.target_turns for seg in plan.segments if seg.cycle == 7 and seg.kind == "move"]
    assert per_cycle == [17, 19, 21, 23, 25, 23, 21, 19, 17, 15]


def test_lifetime_compiles_fast() -> None:
    best = min(_timed(lambda: load("lifetime")) for _ in range(3))
    assert best < 0.3, f"lifetime compile took {best:.3f} s"


def _timed(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start
