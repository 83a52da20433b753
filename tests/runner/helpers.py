"""Run a plan on the simulated bench in-process and return the run file path."""

from __future__ import annotations

import os
from pathlib import Path

import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan, load_plan_text
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.store import RunWriter

BENCH = load_bench(None)


def open_sim(seed: int = 1, speed: float | None = None, bench_path: str | None = None):
    url = f"sim://?seed={seed}" + (f"&speed={speed}" if speed else "") + (f"&bench={bench_path}" if bench_path else "")
    return serial.serial_for_url(url, timeout=0.05)


def run_plan(plan, out: Path, *, port=None, seed: int = 1, writer: RunWriter | None = None, block_samples: int = 2048,
             bench=None):
    """Run ``plan`` on the simulated bench (``bench``: a BenchConfig, default sim.yaml; or
    ``port``); return (RunStop, client, path).
    ``block_samples=1`` hands documents to the writer at every read (not coalesced)."""
    bench = bench if bench is not None else BENCH
    port = port if port is not None else open_sim(seed, bench_path=bench.path if bench is not BENCH else None)
    client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
    client.connect(bench.boot_timeout_s)
    writer = writer if writer is not None else RunWriter(out / "run.h5")
    path = writer.path
    runner = Runner(client, plan, bench, [writer], AutoOperator(), backend="sim", port_name="sim://",
                    block_samples=block_samples)
    stop = runner.run()
    port.close()
    return stop, client, path


def plan_from_text(text: str):
    return load_plan_text(text, BENCH.limits, "test.yaml")


def shipped_plan(name: str):
    return load_plan(Path(__file__).resolve().parents[2] / "configs" / "protocols" / name, BENCH.limits)


class KillWhen:
    """Run consumer that dies like `kill -9` (``os._exit(9)``) once ``count(block)`` summed over
    the blocks seen reaches ``at_least`` (the sidecar has written every block handed to it;
    the run file has not flushed). Place it after the writer and the sidecar."""

    def __init__(self, sidecar, count, at_least: int) -> None:
        self.sidecar, self.count, self.at_least, self.seen = sidecar, count, at_least, 0

    def on_samples(self, block) -> None:
        self.seen += int(self.count(block))
        if self.seen >= self.at_least:
            os._exit(9)

    def on_start(self, _) -> None: ...
    def on_segment(self, _) -> None: ...
    def on_event(self, _) -> None: ...
    def on_stop(self, _) -> None: ...
