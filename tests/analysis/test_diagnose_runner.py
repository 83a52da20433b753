"""Diagnose on data recorded through the full simulated-bench stack (sim:// + Runner)
with a custom bench file whose plant hides one effect from the judged baseline."""

from __future__ import annotations

from pathlib import Path

import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tsa_bench.analysis import BASELINE, diagnose, load_model
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan_text
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter, read_run

PROTOCOL = """
name: diagnose-runner-test
description: staircases up and down with holds, fast cycles, a load change
load_g: 500
sampling_period_s: 0.1
limits: {max_twist_turns: 40, max_heater_voltage_V: 0}
defaults: {rate_turns_per_s: 3, accel_turns_per_s2: 50}
steps:
  - heater: {voltage_V: 0}
  - hold: {duration_s: 10}
  - rotation_sequence: {targets_turns: [10, 20, 30, 40, 30, 20, 10], hold_s: 30}
  - repeat:
      count: 4
      steps:
        - rotation_sequence: {targets_turns: [35, 10], hold_s: 1}
  - prompt: {text: "Hang 300 g", load_g: 300}
  - rotation_sequence: {targets_turns: [25, 40, 25, 10], hold_s: 30}
  - rotation_sequence: {targets_turns: [20, 30, 40, 30, 20, 10], hold_s: 30}
"""


def test_runner_recorded_twist_hysteresis_is_named(tmp_path: Path):
    text = BASELINE.read_text().replace("twist_hysteresis: {enabled: false}",
                                        "twist_hysteresis: {enabled: true, play_turns: 0.4}")
    assert "play_turns: 0.4" in text
    bench_path = tmp_path / "hidden-bench.yaml"
    bench_path.write_text(text)
    bench = load_bench(bench_path)
    plan = load_plan_text(PROTOCOL, bench.limits, "diagnose-test.yaml")
    port = serial.serial_for_url(f"sim://?bench={bench_path}&seed=7", timeout=0.05)
    client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
    client.connect(bench.boot_timeout_s)
    path = tmp_path / "run.h5"
    Runner(client, plan, bench, [RunWriter(path)], AutoOperator(), backend="sim", port_name="sim://").run()
    port.close()
    run = read_run(path)
    result = diagnose([run], load_model(None))
    assert result.cause == "twist_hysteresis", result.notes
    gain = {g.output: g.relative for g in result.gain}
    assert gain["length"] >= 0.30, result.gain
