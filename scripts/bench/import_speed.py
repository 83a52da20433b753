"""Import speed and memory of `tsa-bench import` on a large CSV, beside pyarrow's bare parse of the same file.

Usage: PYTHONPATH=host python3 scripts/bench/import_speed.py [--rows 1000000] [--wide] [--keep DIR]

Writes a CSV of ROWS rows as a logger would (4 columns: time in s, twist, length and
resistance; with --wide the 8-column logger export of earlier rounds: time in ms, an
empty resistance cell now and then, a text column, ...), then, each in a fresh process:

* the whole `tsa-bench import` (reading, checking, converting, segment inference, the HDF5
  run file written), targets for 1,000,000 rows x 4 columns: <= 1.0 s CPU, <= 300 MiB peak;
* pyarrow's CSV reader alone on the same file (`pyarrow.csv.read_csv`, all columns as
  float64): the floor a well-kept parser sets;
* the interpreter with the modules the import loads and nothing read (the start-up share).

It prints, side by side, CPU time (user + system, from wait4), wall time, peak resident
memory of each process, and the parse time pyarrow reports inside its process: the
lowest of --repeat runs of each (default 3, interleaved), since on a shared machine other
processes only ever add time. Wall time follows the load (printed); CPU time is the
figure to compare.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def write_csv(path: Path, rows: int) -> None:
    """t [s], turns, length [mm], resistance [ohm]: a twist staircase at 100 Hz."""
    rng = np.random.default_rng(0)
    with open(path, "w") as f:
        f.write("t [s],turns [turn],length [mm],resistance [ohm]\n")
        block = 200_000
        for a in range(0, rows, block):
            k = np.arange(a, min(rows, a + block))
            turns = np.floor(k / 500.0) % 40
            length = 250 - 0.9 * turns + rng.normal(0, 0.01, len(k))
            r = 5.0 + 0.02 * turns + rng.normal(0, 0.001, len(k))
            np.savetxt(f, np.column_stack([k * 0.01, turns, length, r]), fmt=["%.4f", "%.4f", "%.6f", "%.6f"],
                       delimiter=",")


def write_wide_csv(path: Path, rows: int) -> None:
    """The 8-column logger export: time in ms, empty resistance cells while heating, a text column."""
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


PYARROW = """
import sys, time
import pyarrow as pa, pyarrow.csv as pc
t0 = time.process_time()
with open(sys.argv[1]) as f:
    lines = iter(f)
    skip = 0
    for line in lines:
        if not line.startswith("#"):
            break
        skip += 1
names = line.strip().split(",")
types = {n: pa.float64() for n in names if n != "status"}  # the wide file's text column stays text
table = pc.read_csv(sys.argv[1], read_options=pc.ReadOptions(skip_rows=skip),
                    convert_options=pc.ConvertOptions(column_types=types))
print(f"{time.process_time() - t0:.3f} {table.num_rows}")
"""
STARTUP = "import tsa_bench.cli, tsa_bench.importers.pipeline, tsa_bench.importers.text, h5py, pyarrow.csv"


def run(cmd: list[str], env: dict[str, str]) -> tuple[float, float, float, str]:
    """(CPU s, wall s, peak RSS MiB, stdout) of one fresh process, its own figures (wait4), not its siblings'."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        p = subprocess.Popen(cmd, env=env, stdout=out, stderr=err, text=True)
        _, status, usage = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        wall = time.perf_counter() - t0
        out.seek(0)
        err.seek(0)
        text = out.read()
        if p.returncode:
            raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}):\n{text}{err.read()}")
    return usage.ru_utime + usage.ru_stime, wall, usage.ru_maxrss / 1024, text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=1_000_000)
    ap.add_argument("--wide", action="store_true", help="the 8-column logger export instead of 4 columns")
    ap.add_argument("--keep", type=Path, default=None, help="keep the CSV and run file here")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each process; the lowest figures are printed")
    args = ap.parse_args()
    d = args.keep or Path(tempfile.mkdtemp(prefix="import-speed-"))
    d.mkdir(parents=True, exist_ok=True)
    src, out = d / ("wide.csv" if args.wide else "big.csv"), d / "big.h5"
    if out.exists():
        out.unlink()
    (write_wide_csv if args.wide else write_csv)(src, args.rows)
    n_cols = 8 if args.wide else 4
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
    cmd = [sys.executable, "-m", "tsa_bench.cli", "import", str(src), "--out", str(out)]
    if args.wide:
        cmd += ["--map", "turns=twist"]
    runs: dict[str, list] = {"ours": [], "arrow": [], "start": []}
    for _ in range(max(1, args.repeat)):
        if out.exists():
            out.unlink()
        runs["ours"].append(run(cmd, env))
        runs["arrow"].append(run([sys.executable, "-c", PYARROW, str(src)], env))
        runs["start"].append(run([sys.executable, "-c", STARTUP], env))

    def lowest(key: str) -> tuple[float, float, float, str]:
        r = runs[key]
        return min(x[0] for x in r), min(x[1] for x in r), min(x[2] for x in r), r[-1][3]

    ours, arrow, start = lowest("ours"), lowest("arrow"), lowest("start")
    parse_s = min(float(x[3].split()[0]) for x in runs["arrow"])
    print(f"{args.rows:,} rows x {n_cols} columns, {src.stat().st_size / 2**20:.1f} MiB; lowest of {args.repeat} "
          f"runs each (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
    print(f"{'':44s}{'CPU s':>8s}{'wall s':>8s}{'peak MiB':>10s}")
    for label, (cpu, wall, peak, _) in (("tsa-bench import, whole (HDF5 written)", ours),
                                        ("pyarrow.csv.read_csv, whole process", arrow),
                                        ("start-up alone (interpreter + modules)", start)):
        print(f"{label:44s}{cpu:8.2f}{wall:8.2f}{peak:10.0f}")
    print(f"{'pyarrow parse inside its process':44s}{parse_s:8.2f}")
    print(f"ours / pyarrow process CPU: {ours[0] / arrow[0]:.2f}")
    if not args.wide and args.rows == 1_000_000:
        print(f"targets for 1,000,000 x 4: whole import <= 1.0 s CPU ({'met' if ours[0] <= 1.0 else 'NOT met'}), "
              f"<= 300 MiB peak ({'met' if ours[2] <= 300 else 'NOT met'})")
    print(ours[3].strip().splitlines()[-1])
    return 0


if __name__ == "__main__":
    sys.exit(main())
