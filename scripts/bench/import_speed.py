"""Import speed and memory of `tsa-bench import` on a large CSV.

Usage: PYTHONPATH=host python3 scripts/bench/import_speed.py [--rows 1000000] [--keep DIR]

Writes a CSV of ROWS rows as a logger would (time in ms, length, resistance in kohm with
empty cells where it was not measured, heater voltage, a load cell, a temperature in K,
a text column), then runs `tsa-bench import` on it in a fresh process (inferring
segments, as the command does by default) and prints the wall time of the import and the
process's peak resident memory (targets for 1,000,000 rows: <= 5 s, <= 500 MiB), with the
CPU time it used and the machine's load average (on a shared machine wall time follows the load).
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

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def write_csv(path: Path, rows: int) -> None:
    rng = np.random.default_rng(0)
    t_ms = np.arange(rows) * 10.0
    turns = np.floor(np.arange(rows) / 500.0) % 40
    length = 250 - 0.9 * turns + rng.normal(0, 0.01, rows)
    r_kohm = 0.005 + 0.0001 * turns
    volts = np.where((np.arange(rows) // 5000) % 4 == 3, 2.0, 0.0)
    force = 2 + 0.05 * turns + rng.normal(0, 0.003, rows)
    temp_k = 296 + volts * 10
    with open(path, "w") as f:
        f.write("# logger export, 100 Hz\ntime_ms,twist [turn],length [mm],R [kohm],heater_voltage [V],"
                "load cell [N],T [K],status\n")
        block = 100_000
        for a in range(0, rows, block):
            b = min(rows, a + block)
            r = [f"{x:.6g}" for x in r_kohm[a:b]]
            for k in range(0, b - a, 7):  # not measured while heating: empty cells
                if volts[a + k] > 0:
                    r[k] = ""
            f.write("".join(f"{t_ms[a + k]:.0f},{turns[a + k]:.0f},{length[a + k]:.4f},{r[k]},{volts[a + k]:g},"
                            f"{force[a + k]:.4f},{temp_k[a + k]:.2f},ok\n" for k in range(b - a)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--keep", type=Path, default=None, help="keep the CSV and run file here")
    args = ap.parse_args()
    d = args.keep or Path(tempfile.mkdtemp(prefix="import-speed-"))
    d.mkdir(parents=True, exist_ok=True)
    src, out = d / "big.csv", d / "big.h5"
    if out.exists():
        out.unlink()
    t0 = time.perf_counter()
    write_csv(src, args.rows)
    print(f"wrote {src}: {args.rows:,} rows, {src.stat().st_size / 2**20:.1f} MiB in {time.perf_counter() - t0:.1f} s")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
    t0 = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "tsa_bench.cli", "import", str(src), "--map", "turns=twist",
                          "--out", str(out)], env=env, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    peak_mib = usage.ru_maxrss / 1024  # kB on Linux
    cpu = usage.ru_utime + usage.ru_stime
    if res.returncode:
        print(res.stdout + res.stderr, file=sys.stderr)
        return 1
    print(res.stdout.strip().splitlines()[-1])
    print(f"import of {args.rows:,} rows: {wall:.2f} s wall (target <= 5 s; {cpu:.2f} s CPU, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores), peak RSS {peak_mib:.0f} MiB (target <= 500 MiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
