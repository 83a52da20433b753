"""`tsa-bench run --resume`: an aborted run continued from its first incomplete segment
gives the same segments, in two linked files, as an uninterrupted run; a killed run's
last samples are recovered from its live sidecar first."""

from __future__ import annotations

import json
import multiprocessing
import os
import random
import signal

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from tests.runner.helpers import BENCH, KillWhen, open_sim, plan_from_text, run_plan
from tsa_bench.cli import main
from tsa_bench.device import BenchClient
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.runner.interrupts import Interrupts
from tsa_bench.store import RunWriter, read_run
from tsa_bench.store.live import LiveSidecar, LiveTail, sidecar_path

PROTOCOL = """name: resumable
load_g: 300
sampling_period_s: 0.05
defaults: {rate_turns_per_s: 4, accel_turns_per_s2: 40}
steps:
  - move_to: {turns: 5}
  - hold: {duration_s: 2}
  - repeat:
      count: 3
      steps:
        - move_by: {turns: 3}
        - heater: {voltage_V: 2}
        - hold: {duration_s: 1}
        - heater: {voltage_V: 0}
        - sampling: {period_s: 0.1}
        - hold_until_settled: {max_duration_s: 4, window_s: 2, max_dL_dt_mm_per_s: 1.0}
        - sampling: {period_s: 0.05}
  - prompt: {text: "hang 500 g", load_g: 500}
  - move_to: {turns: 2}
  - hold: {duration_s: 1}
"""


class AbortAt:
    """A consumer that asks the run to stop (as Ctrl-C does) once segment ``k`` has ended."""

    def __init__(self, interrupts: Interrupts, k: int) -> None:
        self.interrupts, self.k = interrupts, k

    def on_segment(self, s) -> None:
        if s.index >= self.k and not self.interrupts.count:
            self.interrupts.count, self.interrupts.last_signal = 1, signal.SIGINT

    def on_start(self, _): ...
    def on_samples(self, _): ...
    def on_event(self, _): ...
    def on_stop(self, _): ...


def _rows(path) -> list[tuple]:
    """(index, kind, params without the settling outcome, source, cycle) of completed segments."""
    out = []
    for row in read_run(path).segments:
        if row["completed"]:
            params = {k: v for k, v in json.loads(row["params"]).items()
                      if k not in ("settled", "dR_dt_ohm_per_s", "dL_dt_mm_per_s")}
            out.append((int(row["index"]), row["kind"].decode(), params, row["source"].decode(), int(row["cycle"])))
    return out


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    d = tmp_path_factory.mktemp("whole")
    stop, _, path = run_plan(plan_from_text(PROTOCOL), d, seed=5)
    assert stop.exit_status == "success", stop.reason
    return _rows(path)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_resume_after_an_abort_at_a_random_segment(tmp_path, uninterrupted, seed):
    plan = plan_from_text(PROTOCOL)
    k = random.Random(seed).randrange(1, len(plan.segments) - 1)
    first = tmp_path / "first.h5"
    interrupts = Interrupts()
    port = open_sim(seed)
    client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s)
    client.connect(BENCH.boot_timeout_s)
    # block_samples=1: documents handed over at every read, so the abort lands right after segment k
    stop = Runner(client, plan, BENCH, [RunWriter(first), AbortAt(interrupts, k)], AutoOperator(), backend="sim",
                  port_name="sim://", interrupts=interrupts, block_samples=1).run()
    port.close()
    assert stop.exit_status == "aborted"

    second = tmp_path / "second.h5"
    res = CliRunner().invoke(main, ["run", "--resume", str(first), "--output", str(second), "--seed", "9"])
    assert res.exit_code == 0, res.output
    a, b = _rows(first), _rows(second)
    resumed_at = b[0][0]
    assert [r[0] for r in a] == list(range(resumed_at))             # the first file: 0 .. k'-1 completed
    assert sorted(r[0] for r in a + b) == list(range(len(plan.segments)))  # each segment once in all
    assert a + b == uninterrupted                                   # the same segments, parameters, sources
    with h5py.File(first) as f1, h5py.File(second) as f2:             # linked both ways
        assert f2.attrs["resumed_from"] == "first.h5" and f2.attrs["first_segment"] == resumed_at
        assert f2.attrs["resumed_from_created"] == f1.attrs["created"]
        assert f1.attrs["continued_in"] == "second.h5" and f1.attrs["exit_status"] == "aborted"
    # the rig was brought to the plan's state at the resumed segment before it ran
    run2 = read_run(second)
    start = float(run2.segments["t_start"][0])
    at = np.searchsorted(run2.samples["t"], start)
    before = [s for s in plan.segments[:resumed_at] if s.kind == "move"]
    assert run2.samples["turns"][at] == pytest.approx(before[-1].action.target_turns if before else 0.0, abs=1e-3)
    loads = [s.action.load_g for s in plan.segments[:resumed_at] if s.kind == "prompt"]
    assert run2.samples["load"][at] == pytest.approx((loads[-1] if loads else 300) * 9.80665e-3)


def _killed_child(path: str, k: int) -> None:
    """Run the protocol and die like `kill -9` once segment k is under way."""
    plan = plan_from_text(PROTOCOL)
    side = LiveSidecar(path)

    kill = KillWhen(side, lambda block: (block.columns["segment"] >= k).sum(), 3)
    port = open_sim(7)
    client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s)
    client.connect(BENCH.boot_timeout_s)
    Runner(client, plan, BENCH, [RunWriter(path, flush_interval_s=60), side, kill], AutoOperator(),
           backend="sim", port_name="sim://", block_samples=1).run()  # blocks per read: killed mid-run
    os._exit(0)


def test_a_killed_run_is_recovered_from_its_sidecar_then_resumed(tmp_path, uninterrupted):
    first = tmp_path / "killed.h5"
    child = multiprocessing.get_context("fork").Process(target=_killed_child, args=(str(first), 9))
    child.start()
    child.join(60)
    assert child.exitcode == 9
    with h5py.File(first) as f:
        stored = f["samples/t"].shape[0]
        stored_segments = f["segments"].shape[0]
        assert f.attrs["exit_status"] == "running"
    tail = LiveTail(sidecar_path(first), documents=True)
    live = tail.poll()
    journaled = [(s[0], s[1], s[2], s[3]) for s in tail.segments]
    tail.close()
    assert len(live) > stored                                        # samples only the sidecar has
    assert len(journaled) > stored_segments                          # and segment rows
    res = CliRunner().invoke(main, ["run", "--resume", str(first), "--output", str(tmp_path / "rest.h5")])
    assert res.exit_code == 0, res.output
    assert f"{len(live) - stored} samples after its last flush were recovered" in res.output
    run = read_run(first)
    assert run.exit_status == "failed" and "recovered" in run.attrs["reason"]
    assert int(run.attrs["recovered_samples"]) == len(live) - stored and len(run) == len(live)
    assert np.array_equal(run.samples["counter"], live["counter"])  # every sample once, in order
    for name in ("t", "turns", "length", "resistance", "step_position", "position_raw", "resistance_raw"):
        assert np.array_equal(run.samples[name], live[name], equal_nan=True), name
    assert not sidecar_path(first).exists()
    assert [(int(r["index"]), r["kind"].decode(), float(r["t_start"]), float(r["t_end"])) for r in run.segments] \
        == journaled                                                 # every segment row kept across the kill
    # killed within milliseconds of the start, before a segment record was flushed: the samples
    # show the device was executing segment 9, so the rest starts there
    rest = _rows(tmp_path / "rest.h5")
    with h5py.File(tmp_path / "rest.h5") as f:
        assert f.attrs["first_segment"] == 9 and f.attrs["resumed_from"] == "killed.h5"
    assert [r[:3] + r[4:] for r in rest] == [r[:3] + r[4:] for r in uninterrupted[9:]]


def test_nothing_to_resume(tmp_path, uninterrupted):
    stop, _, path = run_plan(plan_from_text(PROTOCOL), tmp_path, seed=5)
    res = CliRunner().invoke(main, ["run", "--resume", str(path)])
    assert res.exit_code == 2 and "ended in success; there is nothing to resume" in res.output
    res = CliRunner().invoke(main, ["run", "x.yaml", "--resume", str(path)])
    assert res.exit_code == 2 and "either PROTOCOL or --resume" in res.output


def test_a_killed_run_whose_file_cannot_be_read_is_rebuilt_from_its_journal_then_resumed(tmp_path, uninterrupted):
    """Killed inside a write, the file may not read: `info` and `run --resume` rebuild the run
    from its journal into RUN-rebuilt.h5 (leaving the damaged file as it is) and say so."""
    first = tmp_path / "killed.h5"
    child = multiprocessing.get_context("fork").Process(target=_killed_child, args=(str(first), 9))
    child.start()
    child.join(60)
    assert child.exitcode == 9
    tail = LiveTail(sidecar_path(first), documents=True)
    live = tail.poll()
    journaled = len(tail.segments)
    tail.close()
    with open(first, "r+b") as f:   # a superblock's worth is left: HDF5 cannot read it
        f.truncate(1024)
    damaged = first.read_bytes()
    res = CliRunner().invoke(main, ["info", str(first)])
    assert res.exit_code == 0, res.output
    rebuilt = tmp_path / "killed-rebuilt.h5"
    assert f"{first} cannot be read" in res.output and f"into {rebuilt}" in res.output
    assert first.read_bytes() == damaged and not sidecar_path(first).exists()
    run = read_run(rebuilt)
    assert np.array_equal(run.samples["counter"], live["counter"]) and len(run.segments) == journaled
    assert run.exit_status == "failed" and run.attrs["rebuilt_from"] == "killed.h5"
    res = CliRunner().invoke(main, ["run", "--resume", str(rebuilt), "--output", str(tmp_path / "rest.h5")])
    assert res.exit_code == 0, res.output
    with h5py.File(tmp_path / "rest.h5") as f:
        assert f.attrs["resumed_from"] == "killed-rebuilt.h5" and f.attrs["first_segment"] == 9


def test_run_resume_of_a_damaged_file_rebuilds_it_first(tmp_path, uninterrupted):
    first = tmp_path / "killed.h5"
    child = multiprocessing.get_context("fork").Process(target=_killed_child, args=(str(first), 9))
    child.start()
    child.join(60)
    with open(first, "r+b") as f:
        f.truncate(1024)
    res = CliRunner().invoke(main, ["run", "--resume", str(first), "--output", str(tmp_path / "rest.h5")])
    assert res.exit_code == 0, res.output
    assert "cannot be read" in res.output and f"resuming {tmp_path / 'killed-rebuilt.h5'}" in res.output
    with h5py.File(tmp_path / "rest.h5") as f:
        assert f.attrs["resumed_from"] == "killed-rebuilt.h5" and f.attrs["first_segment"] == 9
    with h5py.File(tmp_path / "killed-rebuilt.h5") as f:
        assert f.attrs["continued_in"] == "rest.h5"
