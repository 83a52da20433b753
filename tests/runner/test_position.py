"""The twist zero at the start of a run: the device says whether it knows its position;
when it does not, the operator is asked whether the TSA is untwisted and the answer is
recorded; a "no" ends the run before anything moves."""

from __future__ import annotations

from tests.runner.helpers import BENCH, open_sim, plan_from_text
from tsa_bench.device import BenchClient
from tsa_bench.runner import AutoOperator, ConsoleOperator, Runner
from tsa_bench.store import RunWriter
from tsa_bench.store.reader import read_run

PLAN = """name: zero
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 30}
steps:
  - move_to: {turns: 2}
  - hold: {duration_s: 0.5}
  - move_to: {turns: 0}
"""


def _run(tmp_path, operator, prepare=None):
    port = open_sim()
    if prepare:
        prepare(port.device)
    client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s)
    client.connect(BENCH.boot_timeout_s)
    path = tmp_path / "run.h5"
    stop = Runner(client, plan_from_text(PLAN), BENCH, [RunWriter(path)], operator, backend="sim",
                  port_name="sim://").run()
    device = port.device
    port.close()
    return stop, read_run(path), device


def _events(run, kind):
    return [e for e in run.events if (e["kind"].decode() if isinstance(e["kind"], bytes) else e["kind"]) == kind]


def test_unknown_position_is_confirmed_by_the_operator_and_recorded(tmp_path):
    operator = AutoOperator()
    stop, run, device = _run(tmp_path, operator)
    assert stop.exit_status == "success", stop.reason
    assert any("untwisted" in q for q in operator.prompts)
    assert len(_events(run, "position_set")) == 1
    assert device.position_known and device.executor.position_steps == 0


def test_operator_saying_no_ends_the_run_before_anything_moves(tmp_path):
    asked = []
    stop, run, device = _run(tmp_path, ConsoleOperator(ask=lambda q: asked.append(q) or "n"))
    assert stop.exit_status == "failed" and "untwisted" in stop.reason
    assert len(asked) == 1 and "untwisted" in asked[0]
    assert not device.position_known and device.executor.position_steps == 0
    assert len(run.segments) == 0


def test_a_kept_position_is_used_and_recorded_without_asking(tmp_path):
    def kept(dev):
        dev.position_known = True
        dev.executor.set_position(3200)

    operator = AutoOperator()
    stop, run, device = _run(tmp_path, operator, prepare=kept)
    assert stop.exit_status == "success", stop.reason
    assert not operator.prompts
    detail = _events(run, "position_kept")[0]["detail"]
    assert "3200 steps" in (detail.decode() if isinstance(detail, bytes) else detail)
    assert device.executor.position_steps == 0      # the plan's move_to 0 is absolute


def test_a_fault_latched_before_the_run_is_told_and_cleared_at_its_start(tmp_path):
    """Issue 35, defect 3: a fault left by an earlier program (the watchdog after Ctrl-C)
    no longer fails the run: the operator is told what it is and what clears it, then
    CLEAR_QUEUE, and the run goes on (recorded as an event)."""
    from tsa_bench.protocol import msg

    said: list[str] = []
    operator = AutoOperator(say=said.append)
    stop, run, device = _run(tmp_path, operator, prepare=lambda dev: dev.inject_fault(msg.Fault.WATCHDOG))
    assert stop.exit_status == "success", stop.reason
    assert len(said) == 1 and "device fault watchdog latched" in said[0] and "Clearing it now" in said[0]
    assert len(_events(run, "fault_at_start")) == 1 and len(_events(run, "fault_cleared")) == 1 and device.fault == 0


def test_a_fault_that_stays_ends_the_run_before_anything_moves(tmp_path):
    from tsa_bench.protocol import msg

    def stuck(dev):
        dev.inject_fault(msg.Fault.POSITION_SENSOR)
        clear = dev._apply

        def keep_fault(message):   # the cause is still there: CLEAR_QUEUE cannot clear it
            clear(message)
            if type(message) is msg.ClearQueue:
                dev.fault = int(msg.Fault.POSITION_SENSOR)
        dev._apply = keep_fault

    stop, run, device = _run(tmp_path, AutoOperator(), prepare=stuck)
    assert stop.exit_status == "failed" and "keeps fault position_sensor latched" in stop.reason
    assert "I2C" in stop.reason and stop.segments_done == 0 and device.executor.position_steps == 0
