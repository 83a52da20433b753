"""track_length on the simulated Scheme 2 bench: it reaches its targets from resistance alone."""

from __future__ import annotations

import dataclasses
import json
import signal

import numpy as np

from tsa_bench.control.controller import MOVING, NO_RESISTANCE, ON_TARGET
from tsa_bench.control.evaluation import target_figures
from tsa_bench.runner.interrupts import Interrupts
from tests.control.helpers import SCHEME2, protocol, run_text

STEPS = protocol("targets: [{length_mm: 201, hold_s: 20}, {length_mm: 211, hold_s: 20}]")


def test_two_length_steps_reach_their_targets_on_the_true_length(tmp_path):
    stop, run = run_text(STEPS, tmp_path)
    assert stop.exit_status == "success", stop.reason
    s = run.samples
    assert run.units["length_estimate"] == "mm" and run.units["length_target"] == "mm"
    assert run.units["controller_state"] == "1"
    figs = target_figures(run)
    assert [f.target_mm for f in figs] == [201, 211]
    for f in figs:
        assert f.rise_s is not None and abs(f.steady_error_mm) <= 0.5, f
    seg = [r for r in run.segments if r["kind"] == b"track_length"][0]
    params = json.loads(seg["params"])
    assert params["controller"] == "self-sensing step controller" and params["targets_reached"] == 2
    assert all(t["corrections"] >= 1 for t in params["targets"])
    # the estimate exists before tracking too (the estimator runs on the whole run)
    before = s["segment"] < int(seg["index"])
    assert np.isfinite(s["length_estimate"][before]).sum() > 100
    assert np.all(s["controller_state"][before] == 0) and np.all(np.isnan(s["length_target"][before]))


def test_the_controller_never_reads_the_position_sensor(tmp_path):
    """A position sensor calibrated 40 mm off changes the recorded length, not one command."""
    shifted = dataclasses.replace(SCHEME2, position=dataclasses.replace(SCHEME2.position,
                                                                      offset_mm=SCHEME2.position.offset_mm + 40.0))
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    stop_a, a = run_text(STEPS, tmp_path / "a", seed=3)
    stop_b, b = run_text(STEPS, tmp_path / "b", seed=3, bench=shifted)
    assert stop_a.exit_status == stop_b.exit_status == "success"
    assert np.allclose(b.samples["length"], a.samples["length"] + 40.0, atol=1e-6)
    np.testing.assert_array_equal(a.samples["step_position"], b.samples["step_position"])
    np.testing.assert_array_equal(a.samples["length_estimate"], b.samples["length_estimate"])


def test_heater_on_means_no_resistance_and_the_controller_holds(tmp_path):
    text = protocol("length_mm: 205, hold_s: 5, timeout_s: 8", heater_V=3,
                    before="  - heater: {voltage_V: 2}\n", after="  - heater: {voltage_V: 0}\n")
    stop, run = run_text(text, tmp_path)
    assert stop.exit_status == "success", stop.reason
    s = run.samples
    seg = [r for r in run.segments if r["kind"] == b"track_length"][0]
    mine = s["segment"] == int(seg["index"])
    tracking = mine & np.isfinite(s["length_target"])   # (after the controller ends, its last DWELL runs out)
    assert np.all(np.isnan(s["resistance"][mine])) and tracking.sum() >= 70
    assert np.all(s["controller_state"][tracking] == NO_RESISTANCE)
    assert np.ptp(s["step_position"][mine]) == 0                    # not one step moved
    assert json.loads(seg["params"])["targets"][0]["reached"] is False


def test_an_estimate_outside_the_validity_range_stops_the_run(tmp_path):
    """Untwisted under 450 g the string is longer than any length the model was identified on."""
    text = protocol("length_mm: 205, hold_s: 5",
                    before="  - move_to: {turns: 0}\n  - prompt: {text: heavier, load_g: 600}\n  - hold: {duration_s: 15}\n")
    stop, run = run_text(text, tmp_path)
    assert stop.exit_status == "failed"
    assert "left the model's validity range" in stop.reason
    kinds = [e["kind"] for e in run.events]
    assert b"stop_sent" in kinds


class StopWhenMoving:
    """Asks the run to stop (as Ctrl-C does) at the first sample of a controller correction."""

    def __init__(self, interrupts: Interrupts) -> None:
        self.interrupts = interrupts

    def on_samples(self, block) -> None:
        if (block.columns["controller_state"] == MOVING).any() and not self.interrupts.count:
            self.interrupts.count, self.interrupts.last_signal = 1, signal.SIGINT

    def on_start(self, _): ...
    def on_segment(self, _): ...
    def on_event(self, _): ...
    def on_stop(self, _): ...


def test_ctrl_c_while_tracking_stops_the_motor_and_closes_the_file(tmp_path):
    interrupts = Interrupts()
    # at 40 x real time sample blocks reach the consumers while the controller works
    stop, run = run_text(STEPS, tmp_path, consumers=[StopWhenMoving(interrupts)], interrupts=interrupts, speed=40)
    assert stop.exit_status == "aborted"
    assert run.attrs["exit_status"] == "aborted"
    assert b"stop_sent" in [e["kind"] for e in run.events]
    seg = [r for r in run.segments if r["kind"] == b"track_length"]
    assert len(seg) == 1 and not seg[0]["completed"]
    assert not (run.samples["controller_state"] == ON_TARGET).all()


def test_with_resistance_and_twist_a_100_g_load_change_is_recovered_within_60_s(tmp_path):
    """configs/protocols/track-length-loads.yaml: 207 mm held through +-100 g, not told to the controller."""
    from tsa_bench.control.evaluation import load_recoveries
    from tsa_bench.plan import load_plan
    from tests.control.helpers import ROOT
    from tests.runner.helpers import run_plan
    from tsa_bench.store.reader import read_run

    plan = load_plan(ROOT / "configs/protocols/track-length-loads.yaml", SCHEME2.limits)
    stop, _, path = run_plan(plan, tmp_path, bench=SCHEME2, seed=4)
    assert stop.exit_status == "success", stop.reason
    run = read_run(path)
    recoveries = load_recoveries(run)
    assert [(round(r.load_from_g), round(r.load_to_g)) for r in recoveries] == [
        (250, 350), (350, 250), (250, 150), (150, 250)]
    for r in recoveries:
        assert r.max_deviation_mm > 3          # the new mass did move the string ...
        assert r.recovery_s is not None and r.recovery_s <= 60, r   # ... and the loop brought it back
    assert json.loads(run.segments[3]["params"])["model_path"].endswith("scheme2-load-strain.json")


def test_a_run_aborted_after_tracking_resumes_at_the_twist_it_reached(tmp_path):
    from tsa_bench.runner.resume import resume_point
    from tsa_bench.plan import load_plan_text

    text = protocol("length_mm: 207, hold_s: 5", after="  - hold: {duration_s: 30}\n  - move_to: {turns: 0}\n")
    interrupts = Interrupts()

    class AbortInLastHold(StopWhenMoving):
        def on_samples(self, block) -> None:   # samples of the hold after the track_length (segment 4)
            if (block.columns["segment"] == 4).any() and not self.interrupts.count:
                self.interrupts.count, self.interrupts.last_signal = 1, signal.SIGINT

    # at 40 x real time sample blocks reach the consumers during the 30 s hold
    stop, run = run_text(text, tmp_path, consumers=[AbortInLastHold(interrupts)], interrupts=interrupts, speed=40)
    assert stop.exit_status == "aborted"
    plan = load_plan_text(text, SCHEME2.limits, "track-test.yaml")
    point = resume_point(run, plan, tmp_path / "run.h5")
    assert plan.segments[point.first_segment].kind in ("hold", "move")
    track = [r for r in run.segments if r["kind"] == b"track_length"][0]
    last = run.samples["turns"][run.samples["segment"] == track["index"]][-1]
    assert point.turns == last and point.turns != 30.0   # not the last move's 30 turns


def test_report_draws_the_tracking_figure_with_its_figures(tmp_path):
    from tsa_bench.report.run_report import write_run_report

    stop, run = run_text(STEPS, tmp_path)
    report = write_run_report(tmp_path / "run.h5", tmp_path / "report")
    (fig,) = [f for f in report.figures if f.name == "tracking"]
    assert fig.path.stat().st_size > 10_000
    assert "2 of 2 targets reached" in fig.caption and "steady-state error of the true length max" in fig.caption
    assert "tracking" in (tmp_path / "report" / "index.html").read_text()
