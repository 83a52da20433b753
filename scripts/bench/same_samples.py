#!/usr/bin/env python3
"""Whether this checkout records the same samples as another one for the same protocol and seed.

Runs ``tsa-bench run PROTOCOL --seed N`` on the simulated bench once with this checkout
and once with ``--baseline CHECKOUT`` (each in a fresh process with its own
``PYTHONPATH``), reads both run files with this checkout's reader and compares every
sample column exactly (bit for bit; a speed-up of the plant or the run loop must not
change a single recorded value). Prints one line per column and exits 1 on any
difference.

    python3 scripts/bench/same_samples.py --baseline /path/to/other/checkout
                                          [--protocol configs/protocols/lifetime.yaml] [--seed 1]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def record(checkout: Path, protocol: Path, seed: int, out: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(checkout / "host")}
    subprocess.run([sys.executable, "-m", "tsa_bench.cli", "run", str(protocol), "--seed", str(seed),
                    "--output", str(out)], cwd=checkout, env=env, check=True, stdout=subprocess.DEVNULL)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", type=Path, required=True, help="the other checkout (its host/ is imported)")
    ap.add_argument("--protocol", type=Path, default=ROOT / "configs" / "protocols" / "lifetime.yaml")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "host"))
    from tsa_bench.store import read_run

    with tempfile.TemporaryDirectory() as tmp:
        here, there = Path(tmp) / "here.h5", Path(tmp) / "baseline.h5"
        record(ROOT, args.protocol.resolve(), args.seed, here)
        record(args.baseline.resolve(), args.protocol.resolve(), args.seed, there)
        a, b = read_run(here).samples, read_run(there).samples
    differ = 0
    for name in sorted(set(a) | set(b)):
        if name not in a or name not in b:
            print(f"{name:16s} only in {'this checkout' if name in a else 'the baseline'}")
            differ += 1
            continue
        x, y = np.asarray(a[name]), np.asarray(b[name])
        same = x.shape == y.shape and x.tobytes() == y.astype(x.dtype).tobytes() and x.dtype == y.dtype
        print(f"{name:16s} {len(x):8d} rows  {'identical' if same else 'DIFFERENT'}")
        differ += not same
    print(f"{args.protocol.name} --seed {args.seed}: "
          f"{'every sample column identical' if not differ else f'{differ} column(s) differ'} "
          f"(this checkout vs {args.baseline})")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
