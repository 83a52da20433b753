#!/usr/bin/env python3
"""CPU seconds of `tsa-bench diagnose` on the flagship run, this checkout beside another one.

The README's main job (`tsa-bench run configs/protocols/quasi-static-self-sensing.yaml`,
seed 0) is simulated once; then `tsa-bench diagnose RUN -q` runs in a child process for
this checkout and for ``--baseline CHECKOUT`` (e.g. ``git worktree add /tmp/base57 57a1be5``),
alternating, ``--repeats`` times each; the children's user + system CPU seconds
(``getrusage(RUSAGE_CHILDREN)``, so the load of the machine does not count as it does in
wall time) are printed per run, with the median and the ratio this / baseline. The
children run with ``nice`` when ``--nice`` is given.

    python3 scripts/bench/diagnose_cost.py --baseline /tmp/base57 [--repeats 2] [--nice 10] [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = "configs/protocols/quasi-static-self-sensing.yaml"


def child_cpu(cmd: list[str], env: dict, cwd: Path) -> tuple[float, float, int]:
    """(CPU seconds, wall seconds, exit code) of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode:
        print(proc.stderr[-2000:], file=sys.stderr)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), wall, proc.returncode


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", type=Path, required=True, help="another checkout (its host/ is used)")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--nice", type=int, default=0)
    ap.add_argument("--keep", type=Path, default=None, help="keep the run and reports here")
    args = ap.parse_args()
    work = args.keep or Path(tempfile.mkdtemp(prefix="diagnose-cost-"))
    work.mkdir(parents=True, exist_ok=True)
    run = work / "flagship.h5"
    prefix = ["nice", "-n", str(args.nice)] if args.nice else []
    env_of = {name: {**os.environ, "PYTHONPATH": str(path / "host"), "OPENBLAS_NUM_THREADS": os.environ.get(
        "OPENBLAS_NUM_THREADS", "")} for name, path in (("this", ROOT), ("baseline", args.baseline))}
    for env in env_of.values():
        if not env["OPENBLAS_NUM_THREADS"]:
            del env["OPENBLAS_NUM_THREADS"]
    if not run.exists():
        subprocess.run([sys.executable, "-m", "tsa_bench.cli", "run", PROTOCOL, "--output", str(run)], cwd=ROOT,
                       env=env_of["this"], check=True, stdout=subprocess.DEVNULL)
    cpu: dict[str, list[float]] = {"this": [], "baseline": []}
    for k in range(args.repeats):
        for name, path in (("baseline", args.baseline), ("this", ROOT)):
            out = work / f"{name}-{k}"
            shutil.rmtree(out, ignore_errors=True)     # a report folder holding files is refused
            cmd = [*prefix, sys.executable, "-m", "tsa_bench.cli", "diagnose", str(run), "-q", "--out", str(out)]
            c, wall, code = child_cpu(cmd, env_of[name], path)
            if code:
                print(f"{name}: diagnose exited {code}", file=sys.stderr)
                return 1
            cpu[name].append(c)
            print(f"  {name:<9} run {k + 1}: CPU {c:6.1f} s   (wall {wall:6.1f} s)", flush=True)
    b, t = statistics.median(cpu["baseline"]), statistics.median(cpu["this"])
    print(f"diagnose of the flagship run ({run}): CPU median this {t:.1f} s, baseline {b:.1f} s "
          f"({args.baseline}); ratio {t / b:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
