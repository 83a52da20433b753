#!/usr/bin/env python3
"""The flagship loop of `tsa-bench diagnose` and its two hard cases, with the figures the issue asks for.

1. The README's main job (`tsa-bench run configs/protocols/quasi-static-self-sensing.yaml`,
   seed 0), then default `tsa-bench diagnose RUN --write-model EXT.yaml --validate RUN2`
   (RUN2: the same protocol, seed 1): what is named, and per output the held-out RMSE of the
   extended model with its 95 % interval, as a multiple of the noise RMS and of the noise
   with the named hold-to-hold offsets; then `tsa-bench predict EXT.yaml RUN2` (its
   held-out part, as diagnose splits it) and whether it falls in that interval; and
   whether `predict EXT.yaml RUN` gives the report's figure back bit for bit.
2. The sensor-gain-drift case: a clean run of the thesis-level baseline bench on the same
   protocol with ``resistance *= 1 + 0.002 (t - t0) / T`` written into its file: what is
   named, with which confidence (creep must never be above 0.5).
3. The dominant-decay case: the same bench as the main job with resistance settling and
   load dependence off: is the resistance transient decay named?

    nice -n 10 python3 scripts/bench/diagnose_flagship.py [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import h5py
import yaml

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = "configs/protocols/quasi-static-self-sensing.yaml"
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT / "host"), os.environ.get("PYTHONPATH", "")])}


def cli(*args: str) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "tsa_bench.cli", *args], cwd=ROOT, env=ENV, capture_output=True,
                          text=True)
    if proc.returncode:
        raise SystemExit(f"tsa-bench {' '.join(args)} exited {proc.returncode}:\n{proc.stderr[-3000:]}")
    return proc


def diagnose(run: Path, out: Path, *extra: str) -> dict:
    shutil.rmtree(out, ignore_errors=True)      # a report folder holding files is refused (no --force here)
    cli("diagnose", str(run), "-q", "--out", str(out), *extra)
    return json.loads((out / "diagnose.json").read_text())


def named(data: dict) -> str:
    return ", ".join(f"{c['effect']} ({c['form']}, {c['confidence']:.2f})" for c in data["named"]) or "nothing"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--keep", type=Path, default=None, help="keep the runs and reports here")
    args = ap.parse_args()
    work = args.keep or Path(tempfile.mkdtemp(prefix="diagnose-flagship-"))
    work.mkdir(parents=True, exist_ok=True)

    run, run2, ext = work / "flagship.h5", work / "flagship-seed1.h5", work / "extended.yaml"
    for path, seed in ((run, 0), (run2, 1)):
        if not path.exists():
            cli("run", PROTOCOL, "--output", str(path), "--seed", str(seed))
    ext.unlink(missing_ok=True)
    data = diagnose(run, work / "flagship_diagnose", "--write-model", str(ext), "--validate", str(run2))
    print(f"1. flagship run: {data['verdict']}: {named(data)}")
    predicted = {}
    for path, key in ((run, "same"), (run2, "other")):
        pj = work / f"predict-{key}.json"
        pj.unlink(missing_ok=True)
        cli("predict", str(ext), str(path), "--json", str(pj))
        predicted[key] = json.loads(pj.read_text())["outputs"]
    for g in data["gain"]:
        o, lo, hi = g["output"], *g["after_ci95"]
        p2 = predicted["other"][o]["rmse_heldout"]
        extra = ""
        if g["settling_sd"]:
            extra = f", {g['after_over_noise_and_settling']:.2f}x noise and hold-to-hold offsets ({g['settling_sd']:.3g})"
        print(f"   {o:<10} held-out RMSE {g['heldout_rmse_after']:.4g} (95 % {lo:.4g} to {hi:.4g}) = "
              f"{g['after_over_noise']:.2f}x the noise RMS {g['noise_rms']:.3g}{extra}; judged model "
              f"{g['heldout_rmse_before']:.4g}")
        print(f"   {'':<10} predict EXT.yaml on seed 1, held-out part: {p2:.4g} -> "
              f"{'within' if lo <= p2 <= hi else 'OUTSIDE'} the interval; whole run {predicted['other'][o]['rmse_all']:.4g}")
        same = predicted["same"][o]["rmse_heldout"] == g["heldout_rmse_after"]
        print(f"   {'':<10} predict EXT.yaml on the same run gives the report's figure bit for bit: {same}")
    for v in data["validation"]:
        print(f"   validation {Path(v['run']).name} {v['output']}: whole run {v['rmse']:.4g} = "
              f"{v['rmse'] / v['noise_rms']:.2f}x its noise; offset {v['offset']:.3g}")

    clean, drift = work / "clean-baseline.h5", work / "gain-drift.h5"
    if not clean.exists():
        cli("run", PROTOCOL, "--bench", "configs/bench/sim-baseline.yaml", "--output", str(clean))
    shutil.copy(clean, drift)
    with h5py.File(drift, "r+") as f:
        t, r = f["samples/t"][:], f["samples/resistance"][:]
        f["samples/resistance"][...] = r * (1 + 0.002 * (t - t[0]) / (t[-1] - t[0]))
    data = diagnose(drift, work / "gain-drift_diagnose")
    creep = [c["confidence"] for c in data["named"] if c["effect"] == "resistance_creep"]
    alts = [a["effect"] for c in data["named"] for a in c.get("alternatives", [])]
    print(f"2. gain drift: {data['verdict']}: {named(data)}; alternatives {alts or 'none'}; creep confidence "
          f"{max(creep) if creep else 'not named'}")

    bench = yaml.safe_load((ROOT / "configs" / "bench" / "sim.yaml").read_text())
    for fx in ("resistance_settling", "load_dependence"):
        bench["plant"]["effects"][fx]["enabled"] = False
    decay_bench, decay = work / "sim-no-settling-no-load-dependence.yaml", work / "decay.h5"
    decay_bench.write_text(yaml.safe_dump(bench, sort_keys=False))
    if not decay.exists():
        cli("run", PROTOCOL, "--bench", str(decay_bench), "--output", str(decay))
    data = diagnose(decay, work / "decay_diagnose")
    print(f"3. dominant decay: {data['verdict']}: {named(data)}; decay named: "
          f"{'resistance_transient_decay' in data['causes']}")
    print(f"(runs and reports in {work})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
