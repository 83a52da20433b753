"""Calibrate the simulated-bench presets to the thesis's records by fitting, and show every record before and after.

Usage:
  PYTHONPATH=host python3 scripts/calibrate_presets.py                 # fit, write the presets, print
  PYTHONPATH=host python3 scripts/calibrate_presets.py --dry-run       # fit and print, write nothing
  PYTHONPATH=host python3 scripts/calibrate_presets.py --only "Scheme 1 (thin SCP + UHMWPE)"
  PYTHONPATH=host python3 scripts/calibrate_presets.py --compare-rev b90b6ca   # no fit: presets at a git
                                                              # revision (before) against the files now (after)

The plan is configs/thesis/calibration.yaml: each fit's parameters (with bounds) and the
records it is fitted to. The held-out records are declared in configs/thesis/held-out.yaml
(before the calibration); the fitting reads only the fits' records and refuses held-out
ones. A fit with an `extension` keeps it only if leave-one-out cross-validation within the
fit's own records favours it. Fits of noise levels run on --noise-seeds seeds at once.
The output lists the fitted and the held-out records, each fit's parameters (start ->
fitted), and -- after the fitting, as a report -- every record's simulated value and
verdict before and after (seed --seed).
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tsa_bench.models.long_run_fits import one_blas_thread
from tsa_bench.reproduce.calibrate import (Settings, calibrate, calibration_records, describe, load_settings,
                                           write_calibration)
from tsa_bench.reproduce.experiments import PRESETS
from tsa_bench.reproduce.plan import load_plan
from tsa_bench.reproduce.records import load_records
from tsa_bench.reproduce.table import evaluate

ROOT = Path(__file__).resolve().parents[1]


def settings_at(rev: str) -> Settings:
    """The presets and manipulator file as they were at git revision ``rev``."""
    tmp = Path(tempfile.mkdtemp(prefix="presets-"))
    try:
        for name in PRESETS:
            text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:configs/bench/{name}.yaml"],
                                  check=True, capture_output=True, text=True).stdout
            (tmp / f"{name}.yaml").write_text(text)
        man = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:configs/manipulator/thesis.yaml"],
                             check=True, capture_output=True, text=True).stdout
        (tmp / "manipulator.yaml").write_text(man)
        return load_settings(tmp, tmp / "manipulator.yaml")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def show_value(v: float | None) -> str:
    return "-" if v is None else f"{v:.4g}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dry-run", action="store_true", help="fit and print, but do not write the presets")
    ap.add_argument("--only", action="append", help="run only the fit with this name (repeatable)")
    ap.add_argument("--maxfev", type=int, default=250, help="simulations per fit at most (default 250)")
    ap.add_argument("--seed", type=int, default=100,
                    help="noise seed of the simulated runs (default 100: apart from reproduce's 0-4)")
    ap.add_argument("--noise-seeds", type=int, default=5,
                    help="seeds a fit of noise levels runs on at once, from --seed (default 5)")
    ap.add_argument("--passes", type=int, default=2, help="times the sequence of fits is run (default 2)")
    ap.add_argument("--compare-rev", help="no fitting: compare the presets at this git revision with the files now")
    args = ap.parse_args()

    records = load_records()
    plan = load_plan(records)
    fitted = plan.fitted_ids()
    held = sorted(plan.held_out or ())
    built = [r.id for r in records if plan.role(r.id) == "built-from"]
    print(f"{len(records)} records: {len(fitted)} fitted, {len(held)} held out ({plan.held_out_path or 'no file'}), "
          f"{len(built)} built-from (consistency-only), {sum(r.measure is None for r in records)} not simulated")
    print("fitted:   " + ", ".join(fitted))
    print("held out (never read by the fitting): " + ", ".join(held))
    print("built-from: " + ", ".join(built))

    t0 = time.perf_counter()
    if args.compare_rev:
        before = settings_at(args.compare_rev)
        after = load_settings()
        label = f"presets at {args.compare_rev}"
    else:
        before = load_settings()
        label = "presets before this calibration"
        with one_blas_thread():
            after, results, extensions = calibrate(plan, calibration_records(records, plan), before, seed=args.seed,
                                                   maxfev=args.maxfev, only=args.only, passes=args.passes,
                                                   log=lambda m: print(m, flush=True), noise_seeds=args.noise_seeds)
        print("\nfits (parameter: start -> fitted):")
        for res in results:
            print("\n".join(describe(res)))
        for ext in extensions:
            print(f"- extension {ext.effect} ({ext.fit}), leave-one-out over its {len(ext.records)} records: "
                  f"left-out records agreeing {ext.agree_without} -> {ext.agree_with}, summed |residual| "
                  f"{ext.residual_without:.1f} -> {ext.residual_with:.1f}: {'kept' if ext.kept else 'rejected'}")
        if not args.dry_run:
            for f in write_calibration(after, plan):
                print(f"wrote {f.relative_to(ROOT)}")

    rows_b = {r.id: r for r in evaluate(records, before.lab(seed=args.seed), plan)}
    rows_a = {r.id: r for r in evaluate(records, after.lab(seed=args.seed), plan)}
    print(f"\nevery record, {label} (before) and after (verdicts: agrees / disagrees / consistency-only):")
    print(f"{'record':36s} {'role':10s} {'thesis':>24s} {'before':>11s} {'verdict':>16s} {'after':>11s} {'verdict':>16s}")
    for rec in records:
        b, a = rows_b[rec.id], rows_a[rec.id]
        if a.verdict == "not simulated":
            continue
        print(f"{rec.id:36s} {a.role:10s} {rec.shown_value:>24s} {show_value(b.simulated):>11s} {b.verdict:>16s} "
              f"{show_value(a.simulated):>11s} {a.verdict:>16s}")
    for name, rows in (("before", rows_b), ("after", rows_a)):
        by = {}
        for r in rows.values():
            if r.verdict in ("agrees", "disagrees"):
                key = r.role if r.role != "held-out" else f"held-out {'quantities' if r.kind == 'quantity' else 'coefficients'}"
                by.setdefault(key, {"agrees": 0, "disagrees": 0})[r.verdict] += 1
        print(f"{name}: " + "; ".join(f"{role}: {c['agrees']} agree, {c['disagrees']} disagree"
                                     for role, c in sorted(by.items())))
    print(f"({time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
