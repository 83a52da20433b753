"""The twist_heat step: a heater profile over a twist, compiled to queued heater and move segments."""

from __future__ import annotations

import json

import jsonschema
import pytest

from tsa_bench.plan import load_plan_text
from tsa_bench.plan.actions import HeaterLevel, Hold, Move
from tsa_bench.plan.report import describe_segment
from tsa_bench.plan.schema import schema_text
from tsa_bench.userfiles import parse_yaml
from tsa_bench.runner.commands import device_commands
from tsa_bench.protocol import msg
from tests.plan.plan_helpers import BENCH, errors_of, protocol


def test_each_sub_move_is_preceded_by_its_heater_level_and_recorded():
    plan = load_plan_text(protocol(
        "move_to: {turns: 10}",
        "twist_heat: {targets_turns: [20, 40], voltages_V: [1.5, 3], hold_s: 2, end_voltage_V: 0}"), BENCH, "p.yaml")
    segs = plan.segments[1:]
    assert [s.kind for s in segs] == ["heater", "move", "hold", "heater", "move", "hold", "heater"]
    assert all(s.source == "p.yaml:5" for s in segs)
    first, last = segs[0].action, segs[-1].action
    assert isinstance(first, HeaterLevel) and isinstance(segs[1].action, Move) and isinstance(segs[2].action, Hold)
    assert segs[0].params() == {"voltage_V": 1.5, "step": "twist_heat", "sub_move": 1, "sub_moves": 2,
                                "sub_move_target_turns": 20.0}
    assert segs[3].params()["voltage_V"] == 3 and segs[4].action.target_turns == 40
    assert last.params() == {"voltage_V": 0, "step": "twist_heat", "sub_move": 0, "sub_moves": 2,
                             "sub_move_target_turns": None}
    assert "during sub-move 2/2 to 40 turns" in describe_segment(segs[3])
    # queued commands only: SET_HEATER then MOVE_TO, so every backend runs it as it is
    cmds = [c for s in segs for c in device_commands(s, 3200)]
    assert [type(c) for c in cmds[:3]] == [msg.SetHeater, msg.MoveTo, msg.Dwell]
    assert cmds[0].voltage_mV == 1500 and cmds[1].target_steps == 20 * 3200
    assert plan.summary().voltage_range_V == (0, 3)


def test_without_hold_and_end_voltage_the_sub_moves_run_back_to_back():
    plan = load_plan_text(protocol("twist_heat: {targets_turns: [5, 10, 15], voltages_V: [0, 1, 2]}"), BENCH)
    assert [s.kind for s in plan.segments] == ["heater", "move"] * 3
    assert plan.summary().final_voltage_V == 2


@pytest.mark.parametrize("step, where, message", [
    ("twist_heat: {targets_turns: [5, 10], voltages_V: [1]}", "p.yaml:4:", "1 voltages for 2 sub-moves"),
    ("twist_heat: {targets_turns: [5], voltages_V: [13]}", "p.yaml:4:", "max_heater_voltage_V"),
    ("twist_heat: {targets_turns: [5, 101], voltages_V: [1, 2]}", "p.yaml:4:", "exceeds max_twist_turns 100"),
    ("twist_heat: {targets_turns: [5], voltages_V: [1], hold_s: -1}", "p.yaml:4:", "must be >= 0 s"),
    ("twist_heat: {targets_turns: [5], voltages_V: [1], end_voltage_V: 20}", "p.yaml:4:", "<= 12 V"),
    ("twist_heat: {targets_turns: [], voltages_V: []}", "p.yaml:4:", "must not be empty"),
    ("twist_heat: {targets_turns: [5], voltages_V: [1], rate_turns_per_s: 9}", "p.yaml:4:", "max_rate_turns_per_s"),
    ("twist_heat: {targets_turns: [5], volts: [1]}", "p.yaml:4:", "volts"),
])
def test_bad_values_are_refused_with_file_line_and_column(step, where, message):
    text = str(errors_of(protocol(step)))
    assert where in text and message in text, text


def test_the_schema_describes_the_step():
    validator = jsonschema.Draft202012Validator(json.loads(schema_text()))
    good = protocol("twist_heat: {targets_turns: [5, 10], voltages_V: [1, 2], hold_s: 1, end_voltage_V: 0}")
    assert not list(validator.iter_errors(parse_yaml(good, "x").data()))
    assert list(validator.iter_errors(parse_yaml(protocol("twist_heat: {targets_turns: [5]}"), "x").data()))


#: A short twist_heat protocol for the backends (the simulated device here, the firmware in simavr
#: in tests/simavr/test_twist_heat_in_simavr.py).
BACKEND_PROTOCOL = """name: twist-heat-backend
load_g: 250
sampling_period_s: 0.1
defaults: {rate_turns_per_s: 3.33, accel_turns_per_s2: 50}
steps:
  - hold: {duration_s: 1}
  - twist_heat: {targets_turns: [5, 10], voltages_V: [2, 4], hold_s: 2, end_voltage_V: 0}
  - move_to: {turns: 0}
  - heater: {voltage_V: 0}
"""


def check_heater_during_sub_moves(run) -> None:
    """Every sample of each sub-move carries that sub-move's heater level (the applied voltage,
    within the PWM's duty rounding); the end level is 0 V."""
    import numpy as np

    seg = np.asarray(run.samples["segment"])
    volts = np.asarray(run.samples["heater_voltage"], float)
    rows = {int(r["index"]): (r["kind"].decode() if isinstance(r["kind"], bytes) else r["kind"],
                              json.loads(r["params"])) for r in run.segments}
    levels = [p["voltage_V"] for kind, p in rows.values() if kind == "heater" and p.get("step") == "twist_heat"]
    assert levels == [2.0, 4.0, 0.0]
    sub_moves = [i for i, (kind, p) in rows.items() if kind == "move"][:2]
    for i, level in zip(sub_moves, (2.0, 4.0)):
        during = volts[seg == i]
        assert len(during) >= 5 and np.all(np.abs(during - level) < 0.05), (i, during)
    assert np.all(volts[seg == max(rows)] == 0) and run.exit_status == "success"


def test_the_simulated_device_applies_each_level_during_its_sub_move(tmp_path):
    from click.testing import CliRunner

    from tsa_bench.cli import main
    from tsa_bench.store.reader import read_run

    protocol = tmp_path / "p.yaml"
    protocol.write_text(BACKEND_PROTOCOL)
    res = CliRunner().invoke(main, ["run", str(protocol), "--output", str(tmp_path / "run.h5")])
    assert res.exit_code == 0, res.output
    check_heater_during_sub_moves(read_run(tmp_path / "run.h5"))
