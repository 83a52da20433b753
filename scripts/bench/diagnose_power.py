#!/usr/bin/env python3
"""Power of `tsa-bench diagnose` on two generators: detection, wrong names, false alarms, time.

Generators (both in tests/, imported by path):

* ``library``: tests/analysis/hidden.py, the project's own plant (tsa_bench.sim) on the
  thesis-like diagnostic protocol, one or two library effects hidden (parameters drawn);
* ``foreign``: tests/analysis/foreign/, an independent numpy plant on random rotation
  walks, rigs unlike the library default, effects in other forms and effects the library
  does not have (tests/analysis/foreign/cases.py says what each case must give).

For each case x seed a run is written and diagnosed against the default judged model
(configs/bench/sim-baseline.yaml). Reported, each with a 95 % Wilson interval:

* detection: in-library cases whose expected effects are all named, dominant first (with
  two hidden effects, the one that changes the noise-free outputs more, in noise units);
* wrong name: runs where an effect not hidden was named (any case);
* out-of-library: cases answered ``unexplained`` with nothing named;
* false alarm: clean runs not answered ``explained``;

and the diagnose time per run (median, max).

    python scripts/bench/diagnose_power.py [--seeds 3] [--clean 20] [--generators library,foreign]
                                           [--cases a,b] [--minutes 20] [--jobs 2] [-v]
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
sys.path.insert(0, str(ROOT))          # the generators live in tests/ (a package)
LIBRARY_CASES = {
    **{e: ((e,), "named", (e,)) for e in ("resistance_transient_decay", "resistance_creep", "length_creep",
                                           "load_dependence", "twist_hysteresis", "thermal_dynamics",
                                           "missed_steps", "resistance_hysteresis")},
    "thermal_dynamics+resistance_temperature": (("thermal_dynamics", "resistance_temperature"), "named",
                                                ("thermal_dynamics", "resistance_temperature")),
    "length_creep+resistance_transient_decay": (("length_creep", "resistance_transient_decay"), "named",
                                                ("length_creep", "resistance_transient_decay")),
}


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    if n == 0:
        return 0.0, 1.0
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def _library_run(case: str, seed: int, path: Path) -> dict:
    from tests.analysis import hidden
    if case == "clean":
        info = hidden.generate(path, (), seed=seed, short=True)
        return {"verdict": "explained", "causes": (), "n": info["n"]}
    effects, verdict, causes = LIBRARY_CASES[case]
    info = hidden.generate(path, effects, seed=seed)
    if len(causes) > 1:
        causes = tuple(sorted(causes, key=lambda c: -_library_power(effects, c, seed)))
    return {"verdict": verdict, "causes": causes, "n": info["n"]}


def _library_power(effects: tuple[str, ...], effect: str, seed: int) -> float:
    """Mean squared change of the noise-free outputs, in noise variances, that ``effect`` makes
    among ``effects`` (which of two hidden effects dominates)."""
    import numpy as np

    from tests.analysis import hidden
    from tsa_bench.analysis.modelspec import switch
    from tsa_bench.analysis.replay import deterministic
    from tsa_bench.sim.history import simulate
    h = hidden.history(hidden.protocol_steps())
    cfg, _ = hidden.truth_config(effects, seed, h)
    args = (h["t"], h["turns"], h["heater_voltage"], h["load_g"], h["motor_moving"].astype(bool))
    full = simulate(deterministic(cfg), *args)
    rest = simulate(deterministic(switch(cfg, effect, False)), *args)
    scale = {"length_mm": np.hypot(0.05, 0.14 / np.sqrt(12)), "resistance_ohm": 0.001}
    return float(sum(np.mean(((full[k] - rest[k]) / s) ** 2) for k, s in scale.items()))


def _foreign_run(case: str, seed: int, path: Path, minutes: float) -> dict:
    from tests.analysis.foreign.cases import make
    c = make(case, path, seed=seed, minutes=minutes)
    return {"verdict": c.verdict, "causes": tuple(c.causes), "n": c.n}


def one(job: tuple[str, str, int, float]) -> dict:
    """Generate one run and diagnose it."""
    generator, case, seed, minutes = job
    from tsa_bench.analysis import diagnose, load_model
    from tsa_bench.store import read_run
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.h5"
        truth = _library_run(case, seed, path) if generator == "library" else _foreign_run(case, seed, path, minutes)
        t0, c0 = time.perf_counter(), time.process_time()
        result = diagnose([read_run(path)], load_model(None), None, seed=seed)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"generator": generator, "case": case, "seed": seed, "expected": truth["verdict"],
            "expected_causes": truth["causes"], "verdict": result.verdict, "causes": tuple(result.causes),
            "seconds": dt, "cpu_seconds": cpu, "n": truth["n"], "summary": result.summary}


def jobs_for(generators: list[str], seeds: int, clean: int, cases: list[str] | None, minutes: float) -> list:
    jobs = []
    if "library" in generators:
        for case in cases or list(LIBRARY_CASES):
            if case in LIBRARY_CASES:
                jobs += [("library", case, 100 + s, minutes) for s in range(seeds)]
        jobs += [("library", "clean", 500 + s, minutes) for s in range(clean)]
    if "foreign" in generators:
        from tests.analysis.foreign.cases import CASES
        for case in cases or list(CASES):
            if case in CASES and not case.startswith("clean"):
                jobs += [("foreign", case, 100 + s, minutes) for s in range(seeds)]
        rigs = [c for c in CASES if c.startswith("clean")]
        jobs += [("foreign", rigs[s % len(rigs)], 500 + s, minutes) for s in range(clean)]
    return jobs


def rate_line(label: str, k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    return f"  {label:<44} {k:>4}/{n:<4} = {100 * k / max(n, 1):5.1f} %   95 % CI [{100 * lo:.1f}, {100 * hi:.1f}] %"


def report(results: list[dict], generator: str) -> None:
    rs = [r for r in results if r["generator"] == generator]
    if not rs:
        return
    print(f"\n{generator} generator: {len(rs)} runs")
    named = [r for r in rs if r["expected"] == "named"]
    outside = [r for r in rs if r["expected"] == "unexplained"]
    clean = [r for r in rs if r["expected"] == "explained"]
    print(f"  {'case':<44} {'runs':>4}  right  verdicts")
    for case in sorted({r["case"] for r in rs}):
        cs = [r for r in rs if r["case"] == case]
        right = sum(_right(r) for r in cs)
        verdicts = ", ".join(sorted({r["verdict"] + (":" + "+".join(r["causes"]) if r["causes"] else "")
                                     for r in cs}))
        print(f"  {case:<44} {len(cs):>4}  {right:>5}  {verdicts}")
    print(rate_line("detection (expected effects named, dominant first)", sum(_right(r) for r in named),
                    len(named)))
    print(rate_line("wrong name (an effect not hidden was named)",
                    sum(any(c not in r["expected_causes"] for c in r["causes"]) for r in rs), len(rs)))
    if outside:
        print(rate_line("out-of-library answered unexplained, nothing named", sum(_right(r) for r in outside),
                        len(outside)))
    if clean:
        print(rate_line("false alarm (clean run not explained)", sum(r["verdict"] != "explained" for r in clean),
                        len(clean)))
    secs = sorted(r["seconds"] for r in rs)
    cpu = sorted(r.get("cpu_seconds", r["seconds"]) for r in rs)
    print(f"  diagnose time per run: median {secs[len(secs) // 2]:.1f} s, max {secs[-1]:.1f} s wall; "
          f"median {cpu[len(cpu) // 2]:.1f} s, max {cpu[-1]:.1f} s CPU "
          f"(samples per run {min(r['n'] for r in rs)}-{max(r['n'] for r in rs)})")


def _right(r: dict) -> bool:
    if r["expected"] == "named":
        return r["verdict"] == "named" and tuple(r["causes"]) == tuple(r["expected_causes"])
    return r["verdict"] == r["expected"] and not r["causes"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3, help="seeds per case with an effect")
    ap.add_argument("--clean", type=int, default=20, help="clean runs per generator")
    ap.add_argument("--generators", default="library,foreign")
    ap.add_argument("--cases", default=None, help="comma-separated subset of cases")
    ap.add_argument("--minutes", type=float, default=20.0, help="length of the foreign generator's walks")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes")
    ap.add_argument("--verbose", "-v", action="store_true", help="print every run")
    args = ap.parse_args()
    gens = [g.strip() for g in args.generators.split(",") if g.strip()]
    jobs = jobs_for(gens, args.seeds, args.clean, args.cases.split(",") if args.cases else None, args.minutes)
    t0 = time.perf_counter()
    results = []

    def show(r: dict) -> None:
        results.append(r)
        if args.verbose:
            mark = "ok " if _right(r) else "BAD"
            print(f"{mark} {r['generator']:<8} {r['case']:<40} seed {r['seed']:<4} {r['seconds']:5.1f} s  "
                  f"{r['summary'][:160]}", flush=True)

    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            for r in pool.map(one, jobs):
                show(r)
    else:
        for j in jobs:
            show(one(j))
    wall = time.perf_counter() - t0
    print(f"diagnose power: {len(results)} runs, {wall:.0f} s wall with {args.jobs} job(s)")
    for g in gens:
        report(results, g)


if __name__ == "__main__":
    main()
