#!/usr/bin/env python3
"""Four simulated rigs at once record what each records alone.

Runs ``tsa-bench lab configs/labs/four-sim-rigs.yaml`` (the lifetime protocol, 596 cycles,
on four simulated rigs with four loads and seeds, as fast as the host allows), then each
rig's run again on its own (``tsa-bench run lifetime --seed N --set load_g=L``), and compares
the files dataset by dataset as scripts/bench/run_identity.py does (every sample column,
``/segments``, ``/segment_texts``, ``/events``; attributes such as times are not compared).
Prints one line per rig, the lab's and the single runs' wall times, and the lab's catalogue
rows; exits 1 when any file differs, a rig did not succeed, or a row is missing.

    nice -n 10 python3 scripts/bench/lab_identity.py [--lab configs/labs/four-sim-rigs.yaml] [--keep DIR]
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
CLI = [sys.executable, "-m", "tsa_bench.cli"]


def identity_module():
    spec = importlib.util.spec_from_file_location("run_identity", ROOT / "scripts" / "bench" / "run_identity.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> int:
    from tsa_bench import catalogue
    from tsa_bench.lab.labfile import read_lab

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lab", type=Path, default=ROOT / "configs" / "labs" / "four-sim-rigs.yaml")
    ap.add_argument("--keep", type=Path, help="keep the run files here")
    args = ap.parse_args()
    lab = read_lab(args.lab)
    identity = identity_module()
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        out = folder / "lab"
        print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}, nice {os.nice(0)}")
        t0 = time.perf_counter()
        done = subprocess.run(CLI + ["lab", str(args.lab), "--out", str(out)], env=ENV, capture_output=True, text=True)
        lab_wall = time.perf_counter() - t0
        print(f"lab '{lab.name}': {len(lab.rigs)} rigs at once, exit {done.returncode}, wall {lab_wall:.1f} s")
        bad = done.returncode != 0
        alone_wall = 0.0
        for rig in lab.rigs:
            mine = next(out.glob(f"*_{rig.name}_*.h5"))
            alone = folder / "alone" / f"{rig.name}.h5"
            argv = CLI + ["run", str(rig.protocol), "--bench", str(rig.bench), "--output", str(alone),
                          "--catalogue", "none"]
            argv += ["--seed", str(rig.seed)] if rig.seed is not None else []
            for name, value in rig.variables.items():
                argv += ["--set", f"{name}={value}"]
            t0 = time.perf_counter()
            one = subprocess.run(argv, env=ENV, capture_output=True, text=True)
            alone_wall += time.perf_counter() - t0
            if one.returncode != 0:
                print(f"  {rig.name}: the run alone failed: {one.stderr[-500:]}")
                bad = True
                continue
            diff = identity.differences(mine, alone, ROOT)
            bad |= bool(diff)
            print(f"  rig {rig.name} (seed {rig.seed}, {rig.variables}): "
                  f"{'identical to the run alone' if not diff else 'DIFFERENT: ' + '; '.join(diff)}")
        print(f"the same runs one at a time: wall {alone_wall:.1f} s in all")
        with catalogue.open(out) as cat:
            rows = cat.search(newest_first=False)
        for r in rows:
            print(f"  catalogue row {r.id}: rig {r.rig} {r.status} sample {r.sample} load {r.load_g:g} g "
                  f"{r.samples} samples, {r.samples_lost} lost, file {r.file_state()}")
        bad |= sorted(r.rig for r in rows) != sorted(rig.name for rig in lab.rigs) or any(
            r.status != "success" or r.file_state() != "ok" for r in rows)
        print("every rig's file identical to its run alone; one catalogue row each" if not bad else "FAILED")
        return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
