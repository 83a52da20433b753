#!/usr/bin/env python3
"""Link campaign: runs through the fault-injecting relay, counted.

For each condition - the campaign faults (1 % drop, 1 % flip, 2 % duplicate, 2 % swap,
both directions), the same with stalls up to the watchdog period, and a line cut - and
for each device - the simulated bench in-process (sim://), the simulated bench over a
real serial link (pseudo-terminals), the firmware core built natively - it runs a short
plan N times and checks every stored row against what the device sent (tests/faults/
checks.py). Prints per device and condition: runs, successes, clean failures (by
reason), runs with a wrong or duplicated row, runs whose samples_lost differs from the
counter gaps, and the frames dropped/flipped/duplicated/swapped. Exit code 0 when every
run either succeeded or failed cleanly and no run stored a wrong or duplicated row or
a wrong samples_lost.

Two more sections (issue 33):

* ``reorder``: relay runs with frames swapped and delayed towards the host, half of the
  segment boundaries with the event or the sample before it moved (tests/faults/relay.py
  REORDER), over a pty to the simulated bench and on the native firmware (20 ms and
  2.326 ms sampling (every other ADS1115 conversion), alternating): samples stored with a segment index outside the plan
  (target 0) and rows whose segment is not the one the device named;
* ``loaded``: link trials on wall-clock devices (the simulated bench over a pty at real
  time, the firmware at --speed 1) with the campaign's frame faults and no stall, beside
  two processes that burn CPU, and more whose main thread also sleeps 2.5 s once (a slow
  consumer: more than the device's 2 s watchdog): every one should succeed.

    PYTHONPATH=host python3 scripts/link_campaign.py [--runs 20] [--seed 0] [--no-firmware] [--no-pty]
        [--sections faults,reorder,loaded] [--reorder-runs 60] [--loaded-runs 30] [--stalled-runs 10]
"""

from __future__ import annotations

import argparse
import random
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import h5py  # noqa: E402
import numpy as np  # noqa: E402
import serial  # noqa: E402

from tests.faults.checks import check_rows_against_device  # noqa: E402
from tests.faults.ptybench import quick_bench, relayed_sim  # noqa: E402
from tests.faults.relay import CAMPAIGN, REORDER, FaultyPort, LinkFaults  # noqa: E402
from tests.faults.test_keepalive import Stall  # noqa: E402
from tests.faults.test_segments import BOUNDARIES  # noqa: E402
from tests.firmware.native_port import NativeFirmwarePort  # noqa: E402
from tests.runner.helpers import BENCH, open_sim, plan_from_text  # noqa: E402
from tests.runner.test_reliability import SHORT  # noqa: E402
from tsa_bench.bench import load_bench  # noqa: E402
from tsa_bench.device import BenchClient, DeviceError  # noqa: E402
from tsa_bench.runner import AutoOperator, Runner  # noqa: E402
from tsa_bench.store import RunWriter  # noqa: E402

# first match wins: a "no ACK" message also names the watchdog (the budget it retried for)
CLEAN = {"no ACK": "no ACK within the watchdog budget", "lost the connection": "line cut",
         "silent": "device silent", "no answer": "no device (before the run)", "watchdog": "device watchdog"}


def conditions(rng: random.Random, wall: bool) -> dict[str, LinkFaults]:
    """The three conditions; stall and cut times in device seconds for sim:// (a 60 s
    plan), in wall seconds over a pty or on the firmware (where the plan takes ~1 s)."""
    at = (lambda a, b: 0.5 + rng.uniform(a / 10, b / 10)) if wall else rng.uniform  # after the handshake
    return {
        "campaign faults": LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, seed=rng.getrandbits(32)),
        "faults + stalls": LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, seed=rng.getrandbits(32),
                                      stalls=((at(2, 10), rng.uniform(0.3, 1.9)), (at(15, 30), rng.uniform(0.3, 1.9)))),
        "faults + cut": LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, seed=rng.getrandbits(32),
                                   cut_at_s=at(3, 30)),
    }


def run_once(kind: str, faults: LinkFaults, tmp: Path, seed: int, native: Path | None, plan_text: str = SHORT,
             wall_clock: bool = False, consumers: tuple = ()):
    """One run through the relay on ``kind`` (sim, pty, firmware); ``wall_clock``: the
    device keeps real time (pty at speed 1, the firmware at --speed 1); ``consumers``
    besides the writer."""
    plan = plan_from_text(plan_text)
    path = tmp / "run.h5"
    if kind == "pty":
        bench_path = quick_bench(tmp)
        bench = load_bench(bench_path)
        with relayed_sim(bench_path, faults, seed=seed, speed=1.0 if wall_clock else None) as relay, \
                serial.Serial(relay.path, bench.baud, timeout=0.05) as port:
            client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
            client.connect(bench.boot_timeout_s)
            stop = Runner(client, plan, bench, [RunWriter(path), *consumers], AutoOperator(), backend="serial",
                          port_name=relay.path).run()
            return stop, relay.link
    if kind == "sim":
        port = FaultyPort(open_sim(seed), faults)
    else:
        port = FaultyPort(NativeFirmwarePort(native, *(("--speed", "1") if wall_clock else ("--virtual",))), faults)
    try:
        client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s, watchdog_s=BENCH.watchdog_s)
        client.connect(2.0)
        stop = Runner(client, plan, BENCH, [RunWriter(path), *consumers], AutoOperator(), backend=kind,
                      port_name=kind).run()
    finally:
        port.close()
    return stop, port.link


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="runs per device and condition")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-firmware", action="store_true", help="skip the native firmware")
    ap.add_argument("--no-pty", action="store_true", help="skip the run over pseudo-terminals")
    ap.add_argument("--sections", default="faults,reorder,loaded", help="which sections, comma-separated")
    ap.add_argument("--reorder-runs", type=int, default=60, help="relay runs with swaps and delays")
    ap.add_argument("--loaded-runs", type=int, default=30, help="link trials beside two CPU burners")
    ap.add_argument("--stalled-runs", type=int, default=10,
                    help="more link trials beside the burners, the main thread stalled 2.5 s once")
    args = ap.parse_args()
    sections = set(args.sections.split(","))
    rng = random.Random(args.seed)
    native = None
    kinds = ["sim"] + ([] if args.no_pty else ["pty"])
    if not args.no_firmware:
        built = subprocess.run(["make", "-C", str(ROOT / "firmware"), "native"], capture_output=True, text=True)
        if built.returncode == 0:
            native = ROOT / "firmware" / "build" / "tsa_bench_native"
            kinds.append("firmware")
        else:
            print("(native firmware not built: skipped)")
    wall_kinds = [k for k in kinds if k != "sim"]
    bad = 0
    if "faults" in sections:
        bad += faults_section(args, rng, kinds, native)
    if "reorder" in sections and wall_kinds:
        bad += reorder_section(args.reorder_runs, rng, wall_kinds, native)
    if "loaded" in sections and wall_kinds:
        bad += loaded_section(args.loaded_runs, args.stalled_runs, rng, wall_kinds, native)
    print("every run succeeded or failed cleanly; 0 wrong or duplicated rows; samples_lost = counter gaps"
          if not bad else f"{bad} runs broke the link contract")
    return 0 if not bad else 1


def faults_section(args, rng: random.Random, kinds: list[str], native: Path | None) -> int:
    bad = 0
    print(f"{'device':<9}{'condition':<17}{'runs':>5}{'success':>8}{'wrong/dup rows':>15}{'lost != gaps':>13}"
          f"  clean failures; frames dropped/flipped/duplicated/swapped to the host")
    for kind in kinds:
        for name in ("campaign faults", "faults + stalls", "faults + cut"):
            outcome, frames = Counter(), Counter()
            wrong = lost_mismatch = 0
            for i in range(args.runs):
                faults = conditions(rng, wall=kind != "sim")[name]
                with tempfile.TemporaryDirectory() as d:
                    try:
                        stop, link = run_once(kind, faults, Path(d), rng.randrange(10**6), native)
                    except DeviceError as exc:  # the handshake failed: nothing ran, said cleanly
                        outcome[next((v for k, v in CLEAN.items() if k in str(exc)), f"OTHER: {exc}")] += 1
                        continue
                    except Exception as exc:  # a crash of the host is the worst outcome: count it loudly
                        outcome[f"CRASH {type(exc).__name__}: {exc}"] += 1
                        continue
                    frames.update(link.stats["to_host"])
                    try:
                        check_rows_against_device(Path(d) / "run.h5", link.device_frames.samples())
                    except AssertionError as exc:
                        if "samples_lost" in str(exc):
                            lost_mismatch += 1
                        else:
                            wrong += 1
                if stop.exit_status == "success":
                    outcome["success"] += 1
                else:
                    reason = next((v for k, v in CLEAN.items() if k in stop.reason), f"OTHER: {stop.reason}")
                    outcome[reason] += 1
            failures = {k: v for k, v in outcome.items() if k != "success"}
            bad += wrong + lost_mismatch + sum(v for k, v in failures.items() if k.startswith(("CRASH", "OTHER")))
            print(f"{kind:<9}{name:<17}{args.runs:>5}{outcome['success']:>8}{wrong:>15}{lost_mismatch:>13}  "
                  f"{failures or 'none'}; {frames['dropped']}/{frames['flipped']}/{frames['duplicated']}/"
                  f"{frames['swapped']}")
    return bad


def _segments_outside(path: Path) -> tuple[int, int]:
    """(stored samples whose segment index is outside the plan, stored samples)."""
    with h5py.File(path, "r") as f:
        seg = f["samples"]["segment"][()].astype(np.int64)
        n = int(f.attrs["n_segments"])
    return int(((seg < -1) | (seg >= n)).sum()), len(seg)


def reorder_section(runs: int, rng: random.Random, kinds: list[str], native: Path | None) -> int:
    """Swaps and delays towards the host, at segment boundaries above all (module doc)."""
    print(f"\nreorder: {runs} relay runs, frames swapped (3 %) and delayed 2-6 frames (3 %), half of the segment "
          "boundaries reordered")
    totals: Counter[str] = Counter()
    outcome: Counter[str] = Counter()
    for i in range(runs):
        kind = kinds[i % len(kinds)]
        period = 0.002326 if kind == "firmware" and (i // len(kinds)) % 2 else 0.02
        with tempfile.TemporaryDirectory() as d:
            try:
                stop, link = run_once(kind, LinkFaults(to_host=REORDER, seed=rng.getrandbits(32)), Path(d),
                                      rng.randrange(10**6), native, BOUNDARIES.format(period=period))
            except Exception as exc:
                outcome[f"CRASH {type(exc).__name__}: {exc}"] += 1
                continue
            outcome["success" if stop.exit_status == "success" else f"OTHER: {stop.reason}"] += 1
            outside, rows = _segments_outside(Path(d) / "run.h5")
            totals["outside"] += outside
            totals["rows"] += rows
            totals["moved"] += link.stats["to_host"]["boundary_before"] + link.stats["to_host"]["boundary_event"]
            totals["delayed"] += link.stats["to_host"]["delayed"]
            try:
                check_rows_against_device(Path(d) / "run.h5", link.device_frames.samples())
            except AssertionError as exc:
                totals["runs with a wrong row"] += 1
                print(f"  run {i} ({kind}): {str(exc).splitlines()[0]}")
    print(f"  runs {runs}, successes {outcome['success']}, stored samples {totals['rows']:,}, "
          f"samples with a segment index outside the plan: {totals['outside']} (target 0), "
          f"runs with a row not as the device sent it (segment included): {totals['runs with a wrong row']}; "
          f"boundaries reordered {totals['moved']:,}, frames delayed {totals['delayed']:,}")
    others = {k: v for k, v in outcome.items() if k != "success"}
    if others:
        print(f"  not successes: {others}")
    return totals["outside"] + totals["runs with a wrong row"] + sum(others.values())


def loaded_section(runs: int, stalled: int, rng: random.Random, kinds: list[str], native: Path | None) -> int:
    """Runs that should succeed, on wall-clock devices, beside two CPU-burning processes;
    then ``stalled`` more whose main thread also sleeps 2.5 s once (a slow consumer)."""
    print(f"\nloaded: {runs} link trials (campaign frame faults, no line stall) on wall-clock devices beside two "
          f"CPU-burning processes, then {stalled} more whose main thread also stalls 2.5 s once")
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    bad = 0
    try:
        for label, n, stall_s in (("loaded", runs, 0.0), ("loaded + 2.5 s main-thread stall", stalled, 2.5)):
            outcome: Counter[str] = Counter()
            wrong = 0
            for i in range(n):
                kind = kinds[i % len(kinds)]
                faults = LinkFaults(to_host=CAMPAIGN, to_device=CAMPAIGN, seed=rng.getrandbits(32))
                with tempfile.TemporaryDirectory() as d:
                    try:
                        stop, link = run_once(kind, faults, Path(d), rng.randrange(10**6), native,
                                              BOUNDARIES.format(period=0.02), wall_clock=True,
                                              consumers=(Stall(stall_s, after_s=1.0),) if stall_s else ())
                    except Exception as exc:
                        outcome[f"{kind}: CRASH {type(exc).__name__}: {exc}"] += 1
                        continue
                    outcome["success" if stop.exit_status == "success" else f"{kind}: {stop.reason}"] += 1
                    try:
                        check_rows_against_device(Path(d) / "run.h5", link.device_frames.samples())
                    except AssertionError:
                        wrong += 1
            failed = {k: v for k, v in outcome.items() if k != "success"}
            print(f"  {label}: trials {n}, successes {outcome['success']} (target {n}), runs with a wrong row {wrong}")
            if failed:
                print(f"    not successes: {failed}")
            bad += sum(failed.values()) + wrong
    finally:
        for p in burners:
            p.kill()
            p.wait()
    return bad


if __name__ == "__main__":
    sys.exit(main())
