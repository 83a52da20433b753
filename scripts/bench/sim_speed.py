#!/usr/bin/env python3
"""Speed of the simulated bench, end to end, and of the host codec.

Prints, for the lifetime protocol (596 cycles, ~2.8 h of device time) run through
plant + simulated device + codec + runner + HDF5 writer, the wall time and the
real-time factor (target >= 500 on a 2-core machine) with the shipped bench's plant
effects (all on), the plant's own cost per sample, and the host codec's decode
throughput in frames/s on a recorded-like stream of SAMPLE frames.

    python scripts/bench/sim_speed.py [--protocol configs/protocols/lifetime.yaml] [--repeat 1]
    python scripts/bench/sim_speed.py --plant-only [--baseline CHECKOUT] [--repeat 3]

``--plant-only`` measures just the plant on a lifetime-like input (2-turn moves at 3.33
turns/s between 15 and 25 turns, 1 s holds, 0.1 s sampling, 550 g, the shipped bench's
effects): CPU us per sample of ``sample`` in a fresh process, of ``sample_block`` over
the same inputs where the checkout has it, and of ``tsa_bench.sim.history.simulate``
(what fits and diagnose replays call); with ``--baseline`` the other checkout's plant is
measured alternately with this one (side by side, same inputs), and the outputs' digests
show whether both compute the same numbers.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import serial

import tsa_bench.transport  # noqa: F401  (registers sim://)
from tsa_bench.bench import load_bench
from tsa_bench.device import BenchClient
from tsa_bench.plan import load_plan
from tsa_bench.protocol import MessageDecoder, encode, msg
from tsa_bench.runner import AutoOperator, Runner
from tsa_bench.sim.effects import EFFECTS
from tsa_bench.sim.plant import plant_from_config
from tsa_bench.store import RunWriter

ROOT = Path(__file__).resolve().parents[2]


def run_once(protocol: Path, min_flush_interval_s: float = 0.05) -> tuple[float, float, int, int]:
    bench = load_bench(None)
    plan = load_plan(protocol, bench.limits)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        port = serial.serial_for_url("sim://?seed=1", timeout=0.05)
        client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s)
        client.connect(bench.boot_timeout_s)
        writer = RunWriter(Path(tmp) / "run.h5", min_flush_interval_s=min_flush_interval_s)
        stop = Runner(client, plan, bench, [writer], AutoOperator(), backend="sim", port_name="sim://").run()
        port.close()
        wall = time.perf_counter() - t0
    assert stop.exit_status == "success", stop.reason
    return wall, stop.t_end, stop.samples, writer.flushes


def plant_cost_us(n: int = 20_000) -> float:
    """Microseconds per plant sample with the shipped bench's effects (all on)."""
    plant = plant_from_config(load_bench(None).plant, seed=0)
    t0 = time.perf_counter()
    for i in range(n):
        plant.sample(i * 0.1, 15 + (i // 20) % 10, 0.0, i % 20 < 6)
    return (time.perf_counter() - t0) / n * 1e6


PLANT_CHILD = """
import sys, time
from tsa_bench.bench import load_bench
from tsa_bench.sim.plant import plant_from_config
n = int(sys.argv[1])
ts, cmds, moving = [], [], []
t, turns, target, up = 0.0, 15.0, 17.0, True
while len(ts) < n:
    if turns != target:                     # 2-turn move at 3.33 turns/s
        turns = min(turns + 0.333, target) if target > turns else max(turns - 0.333, target)
        ts.append(t); cmds.append(turns); moving.append(True)
    else:                                   # 1 s hold, then the next target
        for _ in range(10):
            ts.append(t); cmds.append(turns); moving.append(False)
            t += 0.1
        up = (up and target < 25.0) or target <= 15.0
        target += 2.0 if up else -2.0
    t += 0.1
ts, cmds, moving = ts[:n], cmds[:n], moving[:n]
import hashlib
import numpy as np
from tsa_bench.sim.history import simulate
bench = load_bench(None)
plant = plant_from_config(bench.plant, seed=1)
plant.set_load(550.0)
sample = plant.sample
readings = []
c0 = time.process_time()
for a, b, m in zip(ts, cmds, moving):
    readings.append(sample(a, b, 0.0, m))
single = time.process_time() - c0
digest = hashlib.sha256(np.array(readings, dtype=float).tobytes()).hexdigest()[:12]
block = float("nan")
plant = plant_from_config(bench.plant, seed=1)
plant.set_load(550.0)
if hasattr(plant, "sample_block"):
    c0 = time.process_time()
    plant.sample_block(ts, cmds, 0.0, moving)
    block = time.process_time() - c0
c0 = time.process_time()
out = simulate(bench.plant, np.array(ts), np.array(cmds), 0.0, 550.0, np.array(moving), seed=1)
hist = time.process_time() - c0
cols = np.column_stack([out[k] for k in ("length_mm", "resistance_ohm", "temperature_C", "turns_actual")])
print(single, block, hist, digest, hashlib.sha256(cols.tobytes()).hexdigest()[:12])
"""


def plant_side_by_side(checkouts: list[Path], repeat: int, n: int = 100_000) -> None:
    """CPU us per plant sample (``sample`` and ``sample_block``) of each checkout, alternately."""
    got: dict[Path, list[list[str]]] = {c: [] for c in checkouts}
    for _ in range(repeat):
        for c in checkouts:
            env = {**os.environ, "PYTHONPATH": str(c / "host")}
            got[c].append(subprocess.run([sys.executable, "-c", PLANT_CHILD, str(n)], env=env, cwd=c, check=True,
                                         capture_output=True, text=True).stdout.split())

    def us(rows: list[list[str]], k: int) -> str:
        v = sorted(float(r[k]) for r in rows)
        return f"{v[0] / n * 1e6:5.2f} / {v[len(v) // 2] / n * 1e6:5.2f}"

    for c, rows in got.items():
        print(f"plant  {str(c):40s} sample {us(rows, 0)} us   sample_block {us(rows, 1)} us   "
              f"history.simulate {us(rows, 2)} us   (CPU per sample, min / median of {repeat}, {n:,} samples; "
              f"outputs sha256 {rows[0][3]} / {rows[0][4]})")
    digests = {(r[3], r[4]) for rows in got.values() for r in rows}
    print(f"plant  outputs {'identical in every checkout and run' if len(digests) == 1 else 'DIFFER'} "
          "(the readings of sample; simulate's length, resistance, temperature and actual twist)")


def codec_throughput(n: int = 200_000) -> float:
    frames = b"".join(encode(msg.Sample(i, 1000 * i, i, i % 30000, -i, 0, 0, i & 1, i % 65535), i & 0xFFFF)
                      for i in range(n))
    decoder = MessageDecoder()
    t0 = time.perf_counter()
    got = 0
    for k in range(0, len(frames), 4096):
        got += len(decoder.feed(frames[k:k + 4096]))
    dt = time.perf_counter() - t0
    assert got == n
    return n / dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--protocol", type=Path, default=ROOT / "configs" / "protocols" / "lifetime.yaml")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--every-segment", action="store_true",
                    help="also run with one file flush per segment end (no coalescing), for comparison")
    ap.add_argument("--plant-only", action="store_true", help="only the plant, in fresh processes (CPU s)")
    ap.add_argument("--baseline", type=Path, help="with --plant-only: another checkout, measured alternately")
    args = ap.parse_args()
    if args.plant_only:
        plant_side_by_side([ROOT] + ([args.baseline.resolve()] if args.baseline else []), max(args.repeat, 1))
        return
    variants = [("default", 0.05)] + ([("flush every segment", 0.0)] if args.every_segment else [])
    for i in range(args.repeat):
        for label, interval in variants:
            wall, device_s, samples, flushes = run_once(args.protocol, interval)
            print(f"end to end  {args.protocol.name} [{label}]: {device_s / 3600:.2f} h of device time, "
                  f"{samples} samples, {flushes} file flushes in {wall:.2f} s wall -> real-time factor "
                  f"{device_s / wall:.0f} (target >= 500)")
    enabled = [e.name for e in plant_from_config(load_bench(None).plant, seed=0).effects]
    print(f"plant       {plant_cost_us():.1f} us/sample with {len(enabled)} of {len(EFFECTS)} effects on "
          f"({', '.join(enabled)})")
    print(f"codec       decode throughput {codec_throughput():,.0f} frames/s (SAMPLE frames, 4 KiB chunks)")


if __name__ == "__main__":
    main()
