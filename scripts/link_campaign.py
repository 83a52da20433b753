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

    PYTHONPATH=host python3 scripts/link_campaign.py [--runs 20] [--seed 0] [--no-firmware] [--no-pty]
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

import serial  # noqa: E402

from tests.faults.checks import check_rows_against_device  # noqa: E402
from tests.faults.ptybench import quick_bench, relayed_sim  # noqa: E402
from tests.faults.relay import CAMPAIGN, FaultyPort, LinkFaults  # noqa: E402
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


def run_once(kind: str, faults: LinkFaults, tmp: Path, seed: int, native: Path | None):
    plan = plan_from_text(SHORT)
    path = tmp / "run.h5"
    if kind == "pty":
        bench_path = quick_bench(tmp)
        bench = load_bench(bench_path)
        with relayed_sim(bench_path, faults, seed=seed) as relay, \
                serial.Serial(relay.path, bench.baud, timeout=0.05) as port:
            client = BenchClient(port, ack_timeout_s=bench.ack_timeout_s, watchdog_s=bench.watchdog_s)
            client.connect(bench.boot_timeout_s)
            stop = Runner(client, plan, bench, [RunWriter(path)], AutoOperator(), backend="serial",
                          port_name=relay.path).run()
            return stop, relay.link
    if kind == "sim":
        port = FaultyPort(open_sim(seed), faults)
    else:
        port = FaultyPort(NativeFirmwarePort(native, "--virtual"), faults)
    try:
        client = BenchClient(port, ack_timeout_s=BENCH.ack_timeout_s, watchdog_s=BENCH.watchdog_s)
        client.connect(2.0)
        stop = Runner(client, plan, BENCH, [RunWriter(path)], AutoOperator(), backend=kind, port_name=kind).run()
    finally:
        port.close()
    return stop, port.link


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20, help="runs per device and condition")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-firmware", action="store_true", help="skip the native firmware")
    ap.add_argument("--no-pty", action="store_true", help="skip the run over pseudo-terminals")
    args = ap.parse_args()
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
    print("every run succeeded or failed cleanly; 0 wrong or duplicated rows; samples_lost = counter gaps"
          if not bad else f"{bad} runs broke the link contract")
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
