"""Held-out RMSE of the additive (thesis eq. 3.3) and the coupled twist-and-heat length models, side by side.

Runs the training protocol (configs/protocols/twist-heat-grid.yaml: heating after twisting,
at four twists) and the held-out protocols (twist-heat-simultaneous.yaml: twisting and
heating at the same time; the grid again with another noise seed) on a simulated bench,
fits `twist-heat-additive` and `twist-heat-coupled` on the training run and prints each
held-out run's RMSE (mm, quasi-static samples) for both. Units: mm, %.

Run: PYTHONPATH=host python3 scripts/twist_heat_gain.py [--bench configs/bench/sim-4ply.yaml]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROTOCOLS = ROOT / "configs" / "protocols"


def run(protocol: str, bench: str, seed: int, out: Path) -> Path:
    path = out / f"{protocol}-seed{seed}.h5"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
    subprocess.run([sys.executable, "-m", "tsa_bench.cli", "run", str(PROTOCOLS / f"{protocol}.yaml"), "--bench",
                    bench, "--seed", str(seed), "--output", str(path)], check=True, env=env,
                   stdout=subprocess.DEVNULL)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", default=str(ROOT / "configs" / "bench" / "sim-4ply.yaml"))
    args = ap.parse_args()
    from tsa_bench.models.twist_heat import compare_forms
    from tsa_bench.store.reader import read_run

    wall = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        train = [read_run(run("twist-heat-grid", args.bench, 1, out))]
        held = [read_run(run("twist-heat-simultaneous", args.bench, 2, out)),
                read_run(run("twist-heat-grid", args.bench, 3, out))]
        rows = compare_forms(train, held)
    print(f"bench {Path(args.bench).name}; trained on {Path(train[0].path).name}")
    print(f"{'held-out run':<36s} {'n':>6s} {'additive RMSE':>14s} {'coupled RMSE':>13s} {'gain':>7s}")
    for r in rows:
        print(f"{Path(r['run']).name:<36s} {r['n']:>6d} {r['rmse_additive_mm']:>11.3f} mm "
              f"{r['rmse_coupled_mm']:>10.3f} mm {r['gain_percent']:>6.1f} %")
    own, runs = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = own.ru_utime + own.ru_stime + runs.ru_utime + runs.ru_stime
    print(f"wall {time.perf_counter() - wall:.1f} s, CPU (user+sys, with the runs) {cpu:.1f} s")


if __name__ == "__main__":
    main()
