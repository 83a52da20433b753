#!/usr/bin/env python3
"""Power of `tsa-bench diagnose`: detection rate per hidden effect and false-alarm rate.

Uses the hidden-effect generator of the engine's tests, tests/analysis/hidden.py
(imported by path: ``generate(path, effects, seed, short)`` and ``HIDEABLE``): for each
effect x seed it writes a "measured" run = baseline + that effect (parameters drawn in
physical ranges, sensor noise on), runs ``diagnose`` against the baseline and counts

* detected - the drawn effect is among the named causes;
* detected + gain - and the best held-out relative RMSE gain over the outputs >= 30 %;
* wrong    - some other effect was named.

Clean runs (baseline only) give the false-alarm rate: any cause named. Rates come with
95 % Wilson intervals.

    python scripts/bench/diagnose_power.py [--seeds 5] [--clean 20] [--effects a,b] [--short] [--jobs 2]
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HIDDEN = ROOT / "tests" / "analysis" / "hidden.py"


def _hidden():
    if not HIDDEN.exists():
        sys.exit(f"diagnose_power: the hidden-effect generator {HIDDEN.relative_to(ROOT)} is missing; "
                 "it belongs to the diagnose engine's tests (issue 5)")
    spec = importlib.util.spec_from_file_location("tsa_hidden", HIDDEN)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    if n == 0:
        return 0.0, 1.0
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def one(job: tuple[tuple[str, ...], int, bool]) -> dict:
    """Generate one run with ``effects`` hidden and diagnose it."""
    effects, seed, short = job
    hidden = _hidden()
    from tsa_bench.analysis import diagnose, load_model
    from tsa_bench.store import read_run
    with tempfile.TemporaryDirectory() as tmp:
        info = hidden.generate(Path(tmp) / "run.h5", tuple(effects), seed=seed, short=short)
        runs = [read_run(info["path"])]
        t0 = time.perf_counter()
        result = diagnose(runs, load_model(None), None, seed=seed)
        dt = time.perf_counter() - t0
    gains = {g.output: g.relative for g in result.gain}
    return {"effects": tuple(effects), "seed": seed, "causes": list(result.causes), "gains": gains,
            "seconds": dt, "n": info["n"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5, help="seeds per hidden effect")
    ap.add_argument("--clean", type=int, default=20, help="clean (no hidden effect) seeds")
    ap.add_argument("--effects", default=None, help="comma-separated subset (default: the generator's HIDEABLE)")
    ap.add_argument("--short", action="store_true", help="the generator's short protocol (faster, less power)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--verbose", "-v", action="store_true", help="print every run")
    args = ap.parse_args()
    hidden = _hidden()
    try:
        from tsa_bench.analysis import diagnose, load_model  # noqa: F401
    except ImportError as exc:
        sys.exit(f"diagnose_power: the engine tsa_bench.analysis is missing ({exc})")
    effects = args.effects.split(",") if args.effects else list(hidden.HIDEABLE)
    jobs = [((e,), 100 + s, args.short) for e in effects for s in range(args.seeds)]
    jobs += [((), 500 + s, args.short) for s in range(args.clean)]
    t0 = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(one, jobs))
    else:
        results = [one(j) for j in jobs]
    wall = time.perf_counter() - t0
    if args.verbose:
        for r in results:
            g = ", ".join(f"{o} {100 * v:+.0f} %" for o, v in r["gains"].items())
            print(f"  {','.join(r['effects']) or 'clean':<28} seed {r['seed']:<4} named {r['causes'] or '-'}  "
                  f"gain {g}  ({r['seconds']:.1f} s)")

    print(f"diagnose power: {len(results)} runs ({'short' if args.short else 'full'} protocol, "
          f"{results[0]['n'] if results else 0} samples each), {wall:.0f} s wall with {args.jobs} job(s)")
    print(f"{'hidden effect':<28} {'runs':>4} {'detected':>9} {'+gain>=30%':>11} {'wrong':>6}  detection 95 % CI")
    tot_k = tot_n = 0
    for e in effects:
        rs = [r for r in results if r["effects"] == (e,)]
        k = sum(e in r["causes"] for r in rs)
        kg = sum(e in r["causes"] and max(r["gains"].values(), default=0) >= 0.3 for r in rs)
        wrong = sum(any(c != e for c in r["causes"]) for r in rs)
        lo, hi = wilson(k, len(rs))
        tot_k, tot_n = tot_k + k, tot_n + len(rs)
        print(f"{e:<28} {len(rs):>4} {k / max(len(rs), 1):>9.0%} {kg / max(len(rs), 1):>11.0%} {wrong:>6}  "
              f"[{lo:.0%}, {hi:.0%}]")
    lo, hi = wilson(tot_k, tot_n)
    print(f"{'all effects':<28} {tot_n:>4} {tot_k / max(tot_n, 1):>9.0%} {'':>11} {'':>6}  [{lo:.0%}, {hi:.0%}]")
    clean = [r for r in results if not r["effects"]]
    fa = sum(bool(r["causes"]) for r in clean)
    lo, hi = wilson(fa, len(clean))
    named = sorted({c for r in clean for c in r["causes"]})
    print(f"false alarms (clean runs): {fa}/{len(clean)} = {fa / max(len(clean), 1):.0%} "
          f"(95 % CI [{lo:.0%}, {hi:.0%}]; target <= 5 %){'; named: ' + ', '.join(named) if named else ''}")
    secs = sorted(r["seconds"] for r in results)
    if secs:
        print(f"diagnose time per run: median {secs[len(secs) // 2]:.1f} s, max {secs[-1]:.1f} s")


if __name__ == "__main__":
    main()
