#!/usr/bin/env python3
"""`tsa-bench reproduce` full-table time: this tree (default seeds) against a baseline checkout (its default), side by side.

Runs `python3 -m tsa_bench.cli reproduce --json` under `nice -n 10`, alternately with this tree's
host/ and the baseline's host/ on PYTHONPATH (each with its own presets), --rounds times each,
and prints per run the CPU seconds (user + sys of the child, the figure that matters on a
shared machine), the wall seconds and the table's summary, then the ratio of the median CPU
times. The baseline is a git worktree of the revision before issue 28:

    git worktree add /tmp/base57-28 57a1be5
    python3 scripts/bench/reproduce_time.py [--baseline /tmp/base57-28] [--rounds 2] [-- --seeds 5]

Arguments after ``--`` go to this tree's `reproduce` only. Done when: the ratio is <= 2.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def timed(tree: Path, extra: list[str]) -> tuple[float, float, dict]:
    """(CPU s, wall s, summary) of one `reproduce --json` run with ``tree``'s code and presets."""
    env = {**os.environ, "PYTHONPATH": str(tree / "host")}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = subprocess.run(["nice", "-n", "10", sys.executable, "-m", "tsa_bench.cli", "reproduce", "--json", *extra],
                         cwd=tree, env=env, capture_output=True, text=True, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    doc = json.loads(res.stdout[res.stdout.index("{"):])
    return cpu, wall, doc["summary"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", type=Path, default=Path("/tmp/base57-28"), help="baseline worktree (57a1be5)")
    ap.add_argument("--rounds", type=int, default=2, help="runs of each tree, alternating (default 2)")
    ap.add_argument("extra", nargs="*", help="after --: arguments for this tree's reproduce")
    args = ap.parse_args()
    if not (args.baseline / "host" / "tsa_bench").is_dir():
        print(f"{args.baseline}: no baseline checkout (git worktree add {args.baseline} 57a1be5)", file=sys.stderr)
        return 2
    cpu: dict[str, list[float]] = {"baseline": [], "this tree": []}
    for k in range(args.rounds):
        for name, tree, extra in (("baseline", args.baseline, []), ("this tree", ROOT, args.extra)):
            c, w, s = timed(tree, extra)
            cpu[name].append(c)
            seeds = s.get("seeds", ["(one)"])
            roles = "; ".join(f"{r}: {v['agrees']}/{v['agrees'] + v['disagrees']}" for r, v in s["by_role"].items())
            print(f"round {k + 1} {name:9s}: CPU {c:6.1f} s, wall {w:6.1f} s, seeds {seeds}, agree by role {roles}",
                  flush=True)
    b, t = statistics.median(cpu["baseline"]), statistics.median(cpu["this tree"])
    print(f"median CPU: baseline {b:.1f} s, this tree {t:.1f} s, ratio {t / b:.2f} (done when <= 2)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
