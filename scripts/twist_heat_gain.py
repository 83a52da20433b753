"""The coupled twist-and-heat model's gain over the additive one (thesis eq. 3.3), with 95 % intervals, per preset.

Runs the training protocol (configs/protocols/twist-heat-grid.yaml, seed 1: heating after
twisting, at four twists) and the held-out runs (twist-heat-simultaneous.yaml, seed 2:
twisting and heating at the same time; the grid again, seed 3) on every simulated preset
that supports the experiment (heating moves the length by at least 1 mm at some twist of the
training run), fits `twist-heat-additive` and `twist-heat-coupled` on the training run and
prints the gain ``100 (1 - RMSE_coupled / RMSE_additive)`` over the quasi-static samples:
on the training run itself, on every held-out hold, and split into holds whose twist/voltage
pair the training grid held (on grid) and the others (off grid), each with its
block-bootstrap 95 % interval over holds (tsa_bench.reproduce.gain) and the share of the
gain the three largest holds carry. Units: mm, %.

Run: PYTHONPATH=host python3 scripts/twist_heat_gain.py [--bench configs/bench/sim-4ply.yaml ...]
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

import yaml

ROOT = Path(__file__).resolve().parents[1]
PROTOCOLS = ROOT / "configs" / "protocols"
BENCHES = ROOT / "configs" / "bench"
MIN_HEATING_MM = 1.0


def run(protocol: str, bench: Path, seed: int, out: Path) -> Path:
    path = out / f"{bench.stem}-{protocol}-seed{seed}.h5"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
    subprocess.run([sys.executable, "-m", "tsa_bench.cli", "run", str(PROTOCOLS / f"{protocol}.yaml"), "--bench",
                    str(bench), "--seed", str(seed), "--output", str(path)], check=True, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return path


def simulated_presets() -> list[Path]:
    return [p for p in sorted(BENCHES.glob("*.yaml"))
            if (yaml.safe_load(p.read_text(encoding="utf-8")) or {}).get("backend") == "sim"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", action="append", type=Path,
                    help="a bench file (repeatable; default: every simulated preset in configs/bench/)")
    args = ap.parse_args()
    from tsa_bench.reproduce.gain import gain_with_interval, heating_effect_mm, hold_errors
    from tsa_bench.store.reader import read_run

    wall = time.perf_counter()
    head = (f"{'preset':18s} {'holds scored':24s} {'holds':>5s} {'samples':>7s} {'additive':>9s} {'coupled':>8s} "
            f"{'gain':>6s}  {'95 % interval':>14s}  top-3 holds")
    print(head)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for bench in args.bench or simulated_presets():
            train = [read_run(run("twist-heat-grid", bench, 1, out))]
            held = [read_run(run("twist-heat-simultaneous", bench, 2, out)), read_run(run("twist-heat-grid", bench, 3,
                                                                                          out))]
            tr, scored = hold_errors(train, held)
            effect = heating_effect_mm(tr)
            if effect < MIN_HEATING_MM:
                print(f"{bench.stem:18s} does not support the experiment: heating moves the length by "
                      f"{effect:.2f} mm at most (< {MIN_HEATING_MM} mm)")
                continue
            simult = [h for h in scored if "simultaneous" in h.run]
            sets = [("training (in-sample)", tr), ("held-out, all", scored),
                    ("held-out, on grid", [h for h in scored if h.on_grid]),
                    ("held-out, off grid", [h for h in scored if not h.on_grid]),
                    ("simultaneous, on grid", [h for h in simult if h.on_grid]),
                    ("simultaneous, off grid", [h for h in simult if not h.on_grid])]
            for label, holds in sets:
                if not holds:
                    print(f"{bench.stem:18s} {label:24s} no holds")
                    continue
                g = gain_with_interval(holds)
                print(f"{bench.stem:18s} {label:24s} {g.holds:>5d} {g.samples:>7d} {g.rmse_additive_mm:>6.3f} mm "
                      f"{g.rmse_coupled_mm:>5.3f} mm {g.gain_percent:>5.1f} %  [{g.low_percent:5.1f}, "
                      f"{g.high_percent:5.1f}] %  {100 * g.top3_share:.0f} %")
            n_on = sum(h.n for h in simult if h.on_grid)
            print(f"{bench.stem:18s} simultaneous run: {100 * n_on / sum(h.n for h in simult):.0f} % of its scored "
                  f"samples at twist/voltage pairs of the training grid; heating moves the length by up to "
                  f"{effect:.1f} mm")
    own, runs = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = own.ru_utime + own.ru_stime + runs.ru_utime + runs.ru_stime
    print(f"wall {time.perf_counter() - wall:.1f} s, CPU (user+sys, with the runs) {cpu:.1f} s")


if __name__ == "__main__":
    main()
