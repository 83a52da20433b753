"""Shared pieces of the length-tracking tests: the shipped Scheme 2 model and a small runner."""

from __future__ import annotations

from pathlib import Path

from tsa_bench.bench import load_bench
from tsa_bench.plan import load_plan_text
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter
from tsa_bench.store.reader import read_run
from tests.runner.helpers import open_sim

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "configs/models/scheme2-self-sensing.json"
BENCH_PATH = ROOT / "configs/bench/sim-scheme2-4ply.yaml"
SCHEME2 = load_bench(BENCH_PATH)


def protocol(track: str, *, before: str = "", after: str = "", heater_V: float = 0) -> str:
    """A Scheme 2 protocol: rest, twist to 30 turns, rest, then ``track`` (the body of a track_length)."""
    return f"""name: track-test
load_g: 250
sampling_period_s: 0.1
limits: {{max_twist_turns: 55, max_heater_voltage_V: {heater_V}}}
defaults: {{rate_turns_per_s: 3.33, accel_turns_per_s2: 50}}
steps:
  - hold: {{duration_s: 5}}
  - move_to: {{turns: 30}}
  - hold: {{duration_s: 20}}
{before}  - track_length: {{model: {MODEL}, {track}}}
{after}"""


#: Two length steps after the rest and twist of :func:`protocol`.
STEPS_TEXT = protocol("targets: [{length_mm: 201, hold_s: 20}, {length_mm: 211, hold_s: 20}]")


def run_text(text: str, out: Path, *, seed: int = 2, bench=SCHEME2, consumers=(), interrupts=None,
             speed: float | None = None, writer: RunWriter | None = None, block_samples: int | None = None):
    """Run a protocol text on the simulated ``bench`` (as fast as possible, or ``speed`` x real
    time); return (RunStop, RunData)."""
    from tsa_bench.device import BenchClient

    plan = load_plan_text(text, bench.limits, "track-test.yaml")
    port = open_sim(seed, speed=speed, bench_path=str(bench.path))
    client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
    client.connect(bench.boot_timeout_s)
    path = out / "run.h5"
    runner = Runner(client, plan, bench, [writer or RunWriter(path), *consumers], AutoOperator(), backend="sim",
                    port_name="sim://", interrupts=interrupts,
                    **({} if block_samples is None else {"block_samples": block_samples}))
    stop = runner.run()
    port.close()
    return stop, read_run(path)
