#!/usr/bin/env python3
"""Rates of `tsa-bench diagnose` on the second independent generator (tests/analysis/second).

Every case of tests/analysis/second/cases.py (clean rigs; library families in the
generator's own forms; sensor artefacts a physical effect can mimic; effects outside the
library) is written for each seed and diagnosed against the default judged model. Printed:
one line per run (what was named, confidence, CPU seconds), then, each with a 95 % Wilson
interval, detection (library and artefact cases: the family named, or named as a
confusable alternative), wrong names (a name with confidence above 0.5 that is not the
truth, every run), false alarms (anything named on a clean run) and names with confidence
above 0.5 on cases outside the library; and the CPU seconds per diagnosis.

    nice -n 10 python3 scripts/bench/diagnose_second.py [--seeds 6] [--cases a,b] [--minutes 12] [--workers 1]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT))          # the generator lives in tests/ (a package)


def one(args: tuple[str, int, float]) -> dict:
    name, seed, minutes = args
    from tests.analysis.second.cases import judge, make
    from tsa_bench.analysis import diagnose, load_model
    from tsa_bench.store import read_run

    with tempfile.TemporaryDirectory() as tmp:
        case = make(name, Path(tmp) / "run.h5", seed, minutes)
        t0 = time.process_time()
        result = diagnose([read_run(case.path)], load_model(None), seed=seed)
        cpu = time.process_time() - t0
    row = judge(case, result)
    row.update(seed=seed, cpu_s=cpu, n=case.n,
               confidences={c.effect: round(c.confidence, 2) for c in result.named})
    return row


def main() -> int:
    from tests.analysis.second.cases import CASES, rates
    from tsa_bench.sweep.stats import mean_interval

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=6, help="seeds per case (default 6: 72 runs)")
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated case names")
    ap.add_argument("--minutes", type=float, default=12.0, help="run length")
    ap.add_argument("--workers", type=int, default=1, help="processes (the CPU figures are per process)")
    args = ap.parse_args()
    jobs = [(c, s, args.minutes) for c in args.cases.split(",") for s in range(1, args.seeds + 1)]
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    rows = []
    with ProcessPoolExecutor(max_workers=max(1, args.workers)) as pool:
        for row in pool.map(one, jobs):
            rows.append(row)
            flag = "WRONG " if row["wrong"] else ("ALARM " if row["alarm"] else "")
            print(f"{row['case']:<16} seed {row['seed']:<2} {row['n']:>6} samples  cpu {row['cpu_s']:5.1f} s  {flag}"
                  f"named {row['confidences'] or '-'}  alternatives {row['alternatives'] or '-'}", flush=True)
    print(f"\n{len(rows)} runs of the second generator ({args.minutes:g} min each)")
    for label, (k, n, (lo, hi)) in rates(rows).items():
        print(f"  {label:<38} {k:>3}/{n:<3} = {100 * k / max(n, 1):5.1f} %   95 % CI [{100 * lo:.1f}, {100 * hi:.1f}] %")
    mean, lo, hi = mean_interval([r["cpu_s"] for r in rows])
    print(f"  CPU per diagnosis: mean {mean:.2f} s (95 % CI {lo:.2f} to {hi:.2f}), max {max(r['cpu_s'] for r in rows):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
