"""Calibrate the simulated-bench presets to the thesis's records by fitting, and show every record before and after.

Usage:
  PYTHONPATH=host python3 scripts/calibrate_presets.py                 # fit, write the presets, print
  PYTHONPATH=host python3 scripts/calibrate_presets.py --dry-run       # fit and print, write nothing
  PYTHONPATH=host python3 scripts/calibrate_presets.py --only "Scheme 1 (thin SCP + UHMWPE)"
  PYTHONPATH=host python3 scripts/calibrate_presets.py --compare-rev b90b6ca   # no fit: presets at a git
                                                              # revision (before) against the files now (after)

The plan is configs/thesis/calibration.yaml: each fit's parameters (with bounds) and the
records it is fitted to; everything else is held out. A fit with an `extension` is run
without the extension first and the gain on the held-out records is printed. The output
lists the fitted and the held-out records, each fit's parameters (start -> fitted), and
for every record its simulated value and verdict before and after.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tsa_bench.reproduce.calibrate import Settings, calibrate, describe, load_settings, write_calibration
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
    ap.add_argument("--seed", type=int, default=0, help="noise seed of the simulated runs (default 0)")
    ap.add_argument("--passes", type=int, default=2, help="times the sequence of fits is run (default 2)")
    ap.add_argument("--compare-rev", help="no fitting: compare the presets at this git revision with the files now")
    args = ap.parse_args()

    records = load_records()
    plan = load_plan(records)
    fitted = [rid for f in plan.fits for rid in f.records]
    held = [r.id for r in records if r.measure is not None and plan.role(r.id) == "held-out"]
    built = [r.id for r in records if plan.role(r.id) == "built-from"]
    print(f"{len(records)} records: {len(fitted)} fitted, {len(held)} held out, {len(built)} built-from "
          f"(consistency-only), {sum(r.measure is None for r in records)} not simulated")
    print("fitted:   " + ", ".join(fitted))
    print("held out: " + ", ".join(held))
    print("built-from: " + ", ".join(built))

    t0 = time.perf_counter()
    if args.compare_rev:
        before = settings_at(args.compare_rev)
        after = load_settings()
        label = f"presets at {args.compare_rev}"
    else:
        before = load_settings()
        label = "presets before this calibration"
        after, results, extensions = calibrate(plan, records, before, seed=args.seed, maxfev=args.maxfev,
                                               only=args.only, passes=args.passes, log=lambda m: print(m, flush=True))
        print("\nfits (parameter: start -> fitted):")
        for res in results:
            print("\n".join(describe(res)))
        for ext in extensions:
            print(f"- extension {ext.effect} ({ext.fit}): held-out records agreeing {ext.agree_without} -> "
                  f"{ext.agree_with} of {len(ext.held_out)}, summed |residual| {ext.residual_without:.1f} -> "
                  f"{ext.residual_with:.1f}: {'kept' if ext.kept else 'rejected'}")
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
