#!/usr/bin/env python3
"""Throughput of `tsa-bench sweep` on Dask with 1 and 2 workers, and the engine's overhead per point.

The points are simulate-and-diagnose points (the diagnose runner: a ~10-minute
diagnostic run simulated with an effect hidden, then diagnosed), ``--points`` of them
(effects x seeds). For each cluster size a LocalCluster (processes, one thread each) is
started and warmed up (every worker imports the runners and runs one point) before the
timed sweep, which runs on a fresh results folder. Printed:

* points/s with 1 and 2 workers, and the ratio (target >= 1.7 on two free cores);
* the per-point overhead of the engine: ``(wall x workers - sum of the points' own work)
  / points``, as a share of the mean point's work (target <= 5 %), which also counts the
  idle tail of uneven points, and the same on the busiest worker alone (wall minus its
  points' work, per point it ran). The points' own work is timed inside the worker
  (``work_s`` of the results table), so the overhead holds scheduling,
  (de)serialisation, result transfer and the table's writes;
* the machine's load average before and after (the figures are only as good as the
  cores were free), and the expected throughput of a larger cluster from the per-point
  cost.

    python scripts/bench/sweep_scaling.py [--points 8] [--workers 1,2]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))

STUDY = """\
study: scaling
runner: diagnose
base:
  protocol: {{shape: diagnostic, hold_s: 30.0, repeats: 1}}
  diagnose: {{max_causes: 1}}
vary:
  effect.name: [resistance_creep, twist_hysteresis, length_creep, resistance_transient_decay]
  effect.magnitude: [1.0]
  bench.seed: {{grid: {{start: {first}, stop: {last}, step: 1}}}}
"""


def study_file(folder: Path, points: int, first_seed: int) -> Path:
    seeds = max(1, -(-points // 4))
    p = folder / f"scaling-{first_seed}.yaml"
    p.write_text(STUDY.format(first=first_seed, last=first_seed + seeds - 1), encoding="utf-8")
    return p


def measure(workers: int, points: int, folder: Path) -> dict:
    from distributed import Client, LocalCluster

    from tsa_bench.sweep import load_study
    from tsa_bench.sweep.engine import run_study
    from tsa_bench.sweep.table import ResultsTable

    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0")
    client = Client(cluster)
    try:
        warm = load_study(study_file(folder, 4 * workers, 900 + 10 * workers))
        warm.points = warm.points[:workers]
        run_study(warm, ResultsTable(folder / f"warm-{workers}"), client=client)   # imports on every worker
        study = load_study(study_file(folder, points, 100))
        study.points = study.points[:points]
        table = ResultsTable(folder / f"run-{workers}")
        t0 = time.perf_counter()
        summary = run_study(study, table, client=client)
        wall = time.perf_counter() - t0
        per_worker: dict[str, list[float]] = {}
        for row in table.read().to_pylist():
            per_worker.setdefault(row["worker"], []).append(row["work_s"])
    finally:
        client.close()
        cluster.close()
    n = summary.done + summary.failed
    work = summary.work_s / n
    overhead = (wall * workers - summary.work_s) / n
    # the busiest worker's idle time per point it ran: the engine's cost without the tail's imbalance
    busiest = max(per_worker.values(), key=sum)
    engine = (wall - sum(busiest)) / len(busiest)
    return {"workers": workers, "points": n, "failed": summary.failed, "wall_s": wall, "rate": n / wall,
            "work_s": work, "overhead_s": overhead, "overhead_share": overhead / work, "engine_s": engine,
            "engine_share": engine / (sum(busiest) / len(busiest)), "spread": sorted(len(v) for v in per_worker.values())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=8, help="simulate-and-diagnose points per cluster size")
    ap.add_argument("--workers", default="1,2", help="cluster sizes, comma-separated")
    args = ap.parse_args()
    sizes = [int(w) for w in args.workers.split(",")]
    load0 = os.getloadavg()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for w in sizes:
            r = measure(w, args.points, Path(tmp))
            results.append(r)
            print(f"{w} worker(s): {r['points']} points ({r['failed']} failed, per worker {r['spread']}) in "
                  f"{r['wall_s']:.1f} s = {r['rate']:.3f} points/s; work {r['work_s']:.2f} s per point; idle+engine "
                  f"{r['overhead_s'] * 1000:.0f} ms per point = {100 * r['overhead_share']:.1f} % of a point's work "
                  f"(wall x workers - work); engine on the busiest worker {r['engine_s'] * 1000:.0f} ms per point "
                  f"= {100 * r['engine_share']:.1f} %", flush=True)
    load1 = os.getloadavg()
    base = results[0]
    for r in results[1:]:
        print(f"speed-up {r['workers']} vs {base['workers']} worker(s): {r['rate'] / base['rate']:.2f}x "
              f"(ideal {r['workers'] / base['workers']:.0f}x)")
    print(f"load average (1 min) before {load0[0]:.2f}, after {load1[0]:.2f} on {os.cpu_count()} cores "
          "(other processes share the cores: speed-ups below the ideal)")
    per = min(r["work_s"] for r in results)
    print(f"expected scale-out: one point costs ~{per:.1f} s of one free core and the engine "
          f"~{1000 * min(r['engine_s'] for r in results):.0f} ms, so N free cores give ~N/{per:.1f} points/s "
          f"(a Dask scheduler handles thousands of tasks/s: it stays far from the limit up to hundreds of workers)")


if __name__ == "__main__":
    main()
