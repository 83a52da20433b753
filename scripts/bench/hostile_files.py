#!/usr/bin/env python3
"""Hostile files against the commands that read them: wall time, CPU time and peak RSS.

Builds the files of tests/store/hostile.py (a run file declaring 73 columns of 20,000,000
rows, chunks never written; a 2 KB MATLAB v7.3 file declaring a 1 x 3e9 matrix; run files
on which the HDF5 library loops), a protocol holding a list of a million numbers and one
healthy run file of 2,000,000 rows, then runs each
command in its own process and prints its exit code, wall time, CPU time (user + system;
the wall time of a busy machine is longer) and peak resident memory (GNU time's %M),
beside the load average. The hostile files must be refused (exit 2) within the memory
budget, in under 2 s each; the probe of the healthy file must read metadata only.

    PYTHONPATH=host python3 scripts/bench/hostile_files.py
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "host"))

import numpy as np  # noqa: E402

from tests.store.hostile import huge_matlab_file, huge_run_file, looping_file  # noqa: E402
from tsa_bench.rundocs import SAMPLE_COLUMNS, RunStart, RunStop, SampleBlock  # noqa: E402
from tsa_bench.store import RunWriter  # noqa: E402

ENV = {**os.environ, "PYTHONPATH": f"{ROOT / 'host'}{os.pathsep}{ROOT}"}


def measure(args: list[str], cwd: Path) -> tuple[int, float, float, float, str]:
    """(exit code, wall s, cpu s, peak RSS MiB, last line of output) of one command, measured
    by GNU time (a small parent: a forked Python child would count this script's memory)."""
    proc = subprocess.run(["/usr/bin/time", "-f", "@@ %e %U %S %M", sys.executable, "-m", "tsa_bench.cli", *args],
                          cwd=cwd, env=ENV, capture_output=True, text=True)
    stats = [line for line in proc.stderr.splitlines() if line.startswith("@@ ")][-1].split()
    lines = [line for line in (proc.stdout + proc.stderr).splitlines()
             if line.strip() and not line.startswith(("@@", "Command exited"))]
    return (proc.returncode, float(stats[1]), float(stats[2]) + float(stats[3]), int(stats[4]) / 1024,
            (lines or [""])[-1])


def healthy(path: Path, rows: int = 2_000_000) -> Path:
    start = RunStart("healthy", "name: healthy\n", None, "b: 1\n", None, "sim", "sim://", "1.0.0", {}, 1, rows * 1e-3)
    w = RunWriter(path)
    w.on_start(start)
    cols = {name: np.arange(rows).astype(dtype) for name, (dtype, _) in SAMPLE_COLUMNS.items()}
    cols["t"] = np.arange(rows) * 1e-3
    w.on_samples(SampleBlock(cols))
    w.on_stop(RunStop("success", "done", rows * 1e-3, rows, 0, 0, 1.0))
    return path


def main() -> None:
    if not Path("/usr/bin/time").exists():
        raise SystemExit("needs GNU time (/usr/bin/time; apt-get install time) to measure each command")
    with tempfile.TemporaryDirectory(prefix="hostile-") as tmp:
        d = Path(tmp)
        huge_run_file(d / "huge-run.h5")
        huge_matlab_file(d / "huge.mat")
        loops = d / "loops"
        loops.mkdir()
        for i in range(5):
            looping_file(loops / f"loop{i}.h5")
        healthy(d / "healthy.h5")
        (d / "big-list.yaml").write_text("name: big\nsteps:\n  - hold: {duration_s: 1}\nmetadata:\n  notes: ["
                                         + ",".join(["0.5"] * 1_000_000) + "]\n")
        sizes = {p.name: p.stat().st_size for p in (d / "huge-run.h5", d / "huge.mat", loops / "loop0.h5",
                                                     d / "healthy.h5")}
        print("files: " + ", ".join(f"{k} {v:,} bytes" for k, v in sizes.items()))
        print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
        cases = [
            ("info: run file declaring 73 x 20,000,000 rows", ["info", "huge-run.h5"]),
            ("report: the same", ["report", "huge-run.h5", "--out", "rep"]),
            ("export --csv: the same", ["export", "huge-run.h5", "--csv", "--out", "csv"]),
            ("import: MATLAB v7.3 declaring 1 x 3e9", ["import", "huge.mat", "--out", "imported.h5"]),
            ("info: HDF5 library loops on it", ["info", "loops/loop0.h5"]),
            ("watch: the same", ["watch", "loops/loop0.h5", "--wait", "0"]),
            ("ls: a folder of 5 such files", ["ls", "loops"]),
            ("validate: 4 MB protocol, a 1,000,000-value list", ["validate", "big-list.yaml"]),
            ("info: healthy 2,000,000-row run (reference)", ["info", "healthy.h5"]),
        ]
        print(f"\n{'case':<46} {'exit':>4} {'wall s':>7} {'cpu s':>6} {'RSS MiB':>8}  output")
        for label, args in cases:
            code, wall, cpu, rss, last = measure(args, d)
            print(f"{label:<46} {code:>4} {wall:>7.2f} {cpu:>6.2f} {rss:>8.1f}  {last[:90]}")
        from tsa_bench.store import probe
        t0 = time.monotonic()
        verdict = probe.check_hdf5_terminates(d / "healthy.h5")
        print(f"\nprobe of the healthy 2,000,000-row file: {time.monotonic() - t0:.3f} s wall ({verdict or 'passes'})")


if __name__ == "__main__":
    main()
