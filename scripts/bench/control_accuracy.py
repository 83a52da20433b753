#!/usr/bin/env python3
"""Length tracking from resistance alone on the simulated Scheme 2 bench: accuracy and load recovery.

Steps (each through the `tsa-bench` command line, simulated bench
configs/bench/sim-scheme2-4ply.yaml with its default noise):

1. run configs/protocols/track-length-training.yaml and fit a self-sensing model on it
   (`tsa-bench fit self-sensing`), unless --model is given (a self-sensing model: resistance
   only; or a load-strain model from `tsa-bench estimate --train`: resistance and twist);
2. run a generated protocol of --targets random length steps of 5-20 mm inside the
   model's validity range (each held 30 s once reached), then load changes of +100 g,
   -100 g, -100 g and +100 g (250 -> 350 -> 250 -> 150 -> 250 g) while tracking one length;
3. print, from the run file (tsa_bench.control.evaluation): the steady-state error of the
   TRUE length (position sensor; the controller never reads it) per target, its
   maximum and mean, how many targets were reached, rise time, overshoot, and the
   recovery time after each load change.

    python scripts/bench/control_accuracy.py [--targets 20] [--seed 3] [--model M.json] [-v]

Done when: every target reached, max |steady-state error| <= 0.5 mm, every load change
recovered within 60 s.
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
BENCH = ROOT / "configs/bench/sim-scheme2-4ply.yaml"
TRAINING = ROOT / "configs/protocols/track-length-training.yaml"


def cli(*args: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "host")}
    p = subprocess.run([sys.executable, "-m", "tsa_bench.cli", *args], capture_output=True, text=True, env=env,
                       timeout=1800)
    if p.returncode != 0:
        raise SystemExit(f"tsa-bench {' '.join(args)} failed ({p.returncode}):\n{p.stdout}\n{p.stderr}")
    return p.stdout


def run_file(out_dir: Path) -> Path:
    return max(out_dir.glob("*.h5"), key=lambda p: p.stat().st_mtime)


def random_targets(n: int, lo: float, hi: float, rng: np.random.Generator) -> list[float]:
    """n lengths (mm) inside [lo, hi], each 5-20 mm from the one before."""
    out, x = [], 0.5 * (lo + hi)
    for _ in range(n):
        while True:
            step = rng.uniform(5.0, 20.0) * rng.choice((-1.0, 1.0))
            if lo <= x + step <= hi:
                break
        x = round(x + step, 2)
        out.append(x)
    return out


def protocol(model: Path, targets: list[float], hold_mm: float, extra: str) -> str:
    items = ", ".join(f"{{length_mm: {t:g}, hold_s: 30}}" for t in targets)
    track = f"{{model: {model}, length_mm: {hold_mm:g}, hold_s: 90{extra}}}"
    loads = "".join(f"""  - prompt: {{text: "Change the mass to {g} g", load_g: {g}}}
  - track_length: {track}
""" for g in (350, 250, 150, 250))
    return f"""name: control-accuracy
load_g: 250
sampling_period_s: 0.1
limits: {{max_twist_turns: 55, max_heater_voltage_V: 0}}
defaults: {{rate_turns_per_s: 3.33, accel_turns_per_s2: 50}}
steps:
  - hold: {{duration_s: 10}}
  - move_to: {{turns: 30}}
  - hold: {{duration_s: 20}}
  - track_length: {{model: {model}, targets: [{items}]{extra}}}
  - track_length: {track}
{loads}  - move_to: {{turns: 0}}
  - heater: {{voltage_V: 0}}
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=20)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--model", type=Path, default=None, help="a self-sensing model JSON (default: fit one)")
    ap.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="a track_length setting for every step, e.g. --set tolerance_mm=0.1")
    ap.add_argument("--keep", type=Path, default=None, help="copy the run files here")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "host"))
    from tsa_bench.control.evaluation import load_recoveries, target_figures
    from tsa_bench.plan.tracking_step import model_info
    from tsa_bench.store.reader import read_run

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        model = args.model
        if model is None:
            (work / "train").mkdir()
            cli("run", str(TRAINING), "--bench", str(BENCH), "--out", str(work / "train"), "--seed", str(args.seed))
            model = work / "model.json"
            cli("fit", "self-sensing", str(run_file(work / "train")), "--out", str(model))
        lo, hi = model_info(model)[0]
        if "load-strain" in model.read_text(encoding="utf-8")[:200]:   # its range spans every training load:
            from tsa_bench.models import load_strain                      # targets reachable at 250 g

            ls = load_strain.load(model)
            span = [ls.length(t, 250 * load_strain.G_N_PER_G) for t in np.linspace(*ls.twist_range_turns, 41)]
            lo, hi = max(lo, min(span)), min(hi, max(span))
        rng = np.random.default_rng(args.seed)
        targets = random_targets(args.targets, lo + 2.0, hi - 2.0, rng)
        proto = work / "control-accuracy.yaml"
        extra = "".join(f", {kv.replace('=', ': ', 1)}" for kv in args.settings)
        proto.write_text(protocol(model.resolve(), targets, round(0.5 * (lo + hi), 1), extra), encoding="utf-8")
        (work / "run").mkdir()
        cli("run", str(proto), "--bench", str(BENCH), "--out", str(work / "run"), "--seed", str(args.seed + 1))
        run = read_run(run_file(work / "run"))
        if args.keep:
            import shutil

            args.keep.mkdir(parents=True, exist_ok=True)
            for f in (run_file(work / "run"), model):
                shutil.copy(f, args.keep / f.name)
        figs = target_figures(run)
        steps = figs[:args.targets]
        if args.verbose:
            for f in figs:
                print(f"  target {f.target_mm:7.2f} mm from {f.start_mm:7.2f}: rise "
                      f"{'never' if f.rise_s is None else f'{f.rise_s:5.1f} s'}, steady-state error "
                      f"{f.steady_error_mm:+.3f} mm (estimate {f.estimate_error_mm:+.3f}), overshoot {f.overshoot_mm:.2f} mm")
        err = np.array([f.steady_error_mm for f in steps])
        reached = sum(f.rise_s is not None for f in steps)
        rise = [f.rise_s for f in steps if f.rise_s is not None]
        print(f"random length steps: {len(steps)} (5-20 mm, inside {lo:g}..{hi:g} mm), reached {reached}")
        print(f"steady-state error of the true length: max |e| {np.nanmax(np.abs(err)):.3f} mm, "
              f"mean |e| {np.nanmean(np.abs(err)):.3f} mm, mean e {np.nanmean(err):+.3f} mm")
        print(f"rise time (to within tolerance): median {np.median(rise):.1f} s, max {np.max(rise):.1f} s; "
              f"overshoot max {np.nanmax([f.overshoot_mm for f in steps]):.2f} mm")
        ok = reached == len(steps) and np.nanmax(np.abs(err)) <= 0.5
        for r in load_recoveries(run):
            rec = "not recovered" if r.recovery_s is None else f"recovered in {r.recovery_s:.1f} s"
            print(f"load {r.load_from_g:g} -> {r.load_to_g:g} g at {r.target_mm:g} mm: largest deviation "
                  f"{r.max_deviation_mm:.2f} mm, {rec} (back within 0.5 mm for good)")
            ok = ok and r.recovery_s is not None and r.recovery_s <= 60
        print("PASS" if ok else "FAIL")
        return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
