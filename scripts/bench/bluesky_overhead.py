#!/usr/bin/env python3
"""What the Bluesky RunEngine costs over the project's own runner, on the simulated bench.

The same acquisitions both ways, on ``sim://`` at full speed (virtual time costs no wall
time, so what is measured is the host's work): ``count([rig.length, rig.resistance], N)``
with the RunEngine over :class:`tsa_bench.bluesky.TsaRig` (each point a DWELL of the
integration time, its samples reduced to one event), and a YAML protocol of N holds of
the same length at the same sampling period run by :class:`tsa_bench.runner.Runner`
(each hold a segment, its samples kept as blocks). Prints wall time, per point, and the
ratio, side by side from one run.

    python3 scripts/bench/bluesky_overhead.py [--points 1000] [--integration 0.5] [--period 0.1] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

import serial  # noqa: E402

from tsa_bench import transport  # noqa: E402,F401  (registers sim://)
from tsa_bench.bench import load_bench  # noqa: E402
from tsa_bench.device import BenchClient  # noqa: E402
from tsa_bench.plan import load_plan  # noqa: E402
from tsa_bench.runner import AutoOperator, Runner  # noqa: E402


class _Count:
    """A run consumer counting what arrives (the runner's cheapest consumer)."""

    def __init__(self) -> None:
        self.samples, self.segments, self.stop = 0, 0, None

    def on_start(self, start): ...
    def on_event(self, event): ...
    def on_samples(self, block): self.samples += len(block)
    def on_segment(self, segment): self.segments += 1
    def on_stop(self, stop): self.stop = stop


def with_runengine(points: int, window_s: float, period_s: float, seed: int) -> tuple[float, int]:
    from bluesky import RunEngine
    import bluesky.plans as bp
    from ophyd_async.core import init_devices

    from tsa_bench.bluesky import TsaRig

    re = RunEngine({})
    events = []
    re.subscribe(lambda name, doc: events.append(1) if name == "event" else None)
    with init_devices():
        rig = TsaRig(f"sim://?seed={seed}", integration_time_s=window_s, sampling_period_s=period_s)
    try:
        t0 = time.perf_counter()
        re(bp.count([rig.length, rig.resistance], points))
        return time.perf_counter() - t0, len(events)
    finally:
        rig.close()


def with_runner(points: int, window_s: float, period_s: float, seed: int) -> tuple[float, int]:
    bench = load_bench()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "count.yaml"
        holds = "".join(f"  - hold: {{duration_s: {window_s}}}\n" for _ in range(points))
        path.write_text(f"name: count\nsampling_period_s: {period_s}\nsteps:\n{holds}")
        plan = load_plan(path, bench.limits)
    port = serial.serial_for_url(f"sim://?seed={seed}", baudrate=bench.baud, timeout=0.05)
    try:
        client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
        client.connect(bench.boot_timeout_s)
        keep = _Count()
        t0 = time.perf_counter()
        Runner(client, plan, bench, [keep], AutoOperator(), backend="sim", port_name="sim://").run()
        elapsed = time.perf_counter() - t0
    finally:
        port.close()
    if keep.stop is None or keep.stop.exit_status != "success":
        raise SystemExit(f"the runner's protocol did not succeed: {keep.stop}")
    return elapsed, keep.segments


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1000)
    ap.add_argument("--integration", type=float, default=0.5, help="acquisition window per point (s)")
    ap.add_argument("--period", type=float, default=0.1, help="sampling period (s)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    re_s, re_n = with_runengine(args.points, args.integration, args.period, args.seed)
    run_s, run_n = with_runner(args.points, args.integration, args.period, args.seed)
    print(f"{args.points} points of {args.integration:g} s at {args.period:g} s sampling, sim:// full speed")
    print(f"{'':24}{'wall s':>10}{'ms/point':>10}{'points':>8}")
    print(f"{'RunEngine count':24}{re_s:10.2f}{re_s / args.points * 1e3:10.2f}{re_n:8d}")
    print(f"{'runner (YAML holds)':24}{run_s:10.2f}{run_s / args.points * 1e3:10.2f}{run_n:8d}")
    print(f"RunEngine / runner: {re_s / run_s:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
