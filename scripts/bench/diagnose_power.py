#!/usr/bin/env python3
"""Power of `tsa-bench diagnose`, run as sweep studies on Dask: detection, wrong names, false alarms, time.

A thin wrapper over the sweep engine (docs/sweep.md):

* ``library``: the study configs/studies/diagnose-power.yaml (the project's own plant
  on the diagnostic protocol, each candidate effect hidden at a magnitude; magnitude 0
  is a clean run), with ``--seeds``, ``--magnitudes``, ``--repeats`` and ``--effects``
  replacing its lists;
* ``foreign``: tests/analysis/foreign/, an independent numpy plant on random rotation
  walks (other rigs, other forms of the effects, effects the library does not have;
  tests/analysis/foreign/cases.py says what each case must give), a study built here
  with one point per case x seed.

Both run on a LocalCluster sized to the machine (``--workers``) or an existing
scheduler (``--scheduler tcp://HOST:PORT``); results are kept in ``--out`` (resumable:
re-running skips finished points). Printed, each with a 95 % Wilson interval:
detection per effect and magnitude, wrong names, out-of-library answered
``unexplained``, false alarms, and the diagnose time per run.

    python scripts/bench/diagnose_power.py [--generators library,foreign] [--seeds 2] [--magnitudes 0,0.3,1]
        [--repeats 1,2] [--effects a,b] [--clean 10] [--minutes 20] [--workers N | --scheduler tcp://H:P]
        [--out sweeps/diagnose-power-script]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host"))
sys.path.insert(0, str(ROOT))          # the foreign generator lives in tests/ (a package)
os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT / "host"), str(ROOT), os.environ.get("PYTHONPATH", "")])

import yaml  # noqa: E402

from tsa_bench.sweep.stats import wilson  # noqa: E402


def rate_line(label: str, k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    return f"  {label:<52} {k:>4}/{n:<4} = {100 * k / max(n, 1):5.1f} %   95 % CI [{100 * lo:.1f}, {100 * hi:.1f}] %"


def foreign_point(config: dict, _plant: None) -> dict:
    """One foreign-generator case: write the run, diagnose it against the default model."""
    import time

    from tests.analysis.foreign.cases import make
    from tsa_bench.analysis import diagnose, load_model
    from tsa_bench.store import read_run

    with tempfile.TemporaryDirectory() as tmp:
        c = make(config["case"], Path(tmp) / "run.h5", seed=config["seed"], minutes=config["minutes"])
        t0 = time.perf_counter()
        r = diagnose([read_run(Path(tmp) / "run.h5")], load_model(None), None, seed=config["seed"])
    return {"expected": c.verdict, "expected_causes": "+".join(c.causes), "verdict": r.verdict,
            "causes": "+".join(r.causes), "diagnose_s": time.perf_counter() - t0}


def library_study(args, folder: Path):
    from tsa_bench.sweep import load_study

    spec = yaml.safe_load((ROOT / "configs" / "studies" / "diagnose-power.yaml").read_text(encoding="utf-8"))
    vary = spec["vary"]
    if args.effects:
        vary["effect.name"] = args.effects.split(",")
    if args.magnitudes:
        vary["effect.magnitude"] = [float(m) for m in args.magnitudes.split(",")]
    if args.repeats:
        vary["protocol.repeats"] = [int(r) for r in args.repeats.split(",")]
    vary["bench.seed"] = list(range(1, args.seeds + 1))
    path = folder / "diagnose-power.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    return load_study(path)


def foreign_study(args):
    from tests.analysis.foreign.cases import CASES
    from tsa_bench.sweep.study import Axis, Point, Study, point_key

    cases = [c for c in CASES if not c.startswith("clean") and (not args.cases or c in args.cases.split(","))]
    rigs = [c for c in CASES if c.startswith("clean")]
    configs = [{"case": c, "seed": 100 + s, "minutes": args.minutes} for c in cases for s in range(args.seeds)]
    configs += [{"case": rigs[s % len(rigs)], "seed": 500 + s, "minutes": args.minutes} for s in range(args.clean)]
    points = [Point(i, point_key("foreign-generator", c, None), c, dict(c)) for i, c in enumerate(configs)]
    return Study("diagnose-power-foreign", "foreign generator", foreign_point, 0, {},
                 [Axis("case", tuple(c["case"] for c in configs))], None, points=points)


def report_library(rows: list[dict]) -> None:
    print(f"\nlibrary generator: {len(rows)} runs")
    for r in rows:
        r["name"] = r["effect.name"] if "effect.name" in r else "none"
    effects = sorted({r["name"] for r in rows} - {"none"})
    mags = sorted({r.get("effect.magnitude") for r in rows if r["name"] != "none"})
    for e in effects:
        for m in mags:
            cell = [r for r in rows if r["name"] == e and r.get("effect.magnitude") == m]
            if cell:
                print(rate_line(f"detection {e} x {m:g}", sum(bool(r["detected"]) for r in cell), len(cell)))
    named = [r for r in rows if r["name"] != "none"]
    print(rate_line("wrong name (an effect not hidden was named)",
                    sum(bool(r["causes"]) and r["causes"].split("+")[0] != r["name"] for r in named), len(named)))
    clean = [r for r in rows if r["name"] == "none"]
    print(rate_line("false alarm (clean run not explained)", sum(bool(r["alarm"]) for r in clean), len(clean)))
    _times(rows)


def report_foreign(rows: list[dict]) -> None:
    print(f"\nforeign generator: {len(rows)} runs")
    named = [r for r in rows if r["expected"] == "named"]
    print(rate_line("detection (expected effects named, dominant first)",
                    sum(r["verdict"] == "named" and r["causes"] == r["expected_causes"] for r in named), len(named)))
    print(rate_line("wrong name (an effect not hidden was named)",
                    sum(any(c and c not in r["expected_causes"].split("+") for c in r["causes"].split("+"))
                        for r in rows), len(rows)))
    outside = [r for r in rows if r["expected"] == "unexplained"]
    print(rate_line("out-of-library answered unexplained, nothing named",
                    sum(r["verdict"] == "unexplained" and not r["causes"] for r in outside), len(outside)))
    clean = [r for r in rows if r["expected"] == "explained"]
    print(rate_line("false alarm (clean run not explained)", sum(r["verdict"] != "explained" for r in clean),
                    len(clean)))
    _times(rows)


def _times(rows: list[dict]) -> None:
    secs = sorted(r["diagnose_s"] for r in rows if r.get("diagnose_s") is not None)
    if secs:
        print(f"  diagnose time per run: median {secs[len(secs) // 2]:.1f} s, max {secs[-1]:.1f} s")


def main() -> None:
    from tsa_bench.sweep.engine import connect, run_study
    from tsa_bench.sweep.table import ResultsTable

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--generators", default="library,foreign")
    ap.add_argument("--seeds", type=int, default=2, help="seeds per case with an effect")
    ap.add_argument("--clean", type=int, default=10, help="clean runs of the foreign generator")
    ap.add_argument("--magnitudes", default=None, help="library: effect magnitudes (default: the study's)")
    ap.add_argument("--repeats", default=None, help="library: protocol blocks of ~10 min (default: the study's)")
    ap.add_argument("--effects", default=None, help="library: effects (default: the study's)")
    ap.add_argument("--cases", default=None, help="foreign: comma-separated subset of cases")
    ap.add_argument("--minutes", type=float, default=20.0, help="length of the foreign generator's walks")
    ap.add_argument("--workers", type=int, default=None, help="local cluster size (default: the machine's cores)")
    ap.add_argument("--scheduler", default=None, help="tcp://HOST:PORT of a running Dask scheduler")
    ap.add_argument("--out", default="sweeps/diagnose-power-script", help="results folder (resumable)")
    args = ap.parse_args()
    gens = [g.strip() for g in args.generators.split(",") if g.strip()]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    client, cluster = connect(args.scheduler, args.workers)
    try:
        for g in gens:
            study = library_study(args, out) if g == "library" else foreign_study(args)
            table = ResultsTable(out / g)
            s = run_study(study, table, client=client,
                          progress=lambda d, f, n: print(f"{g}: {d + f}/{n} points, {f} failed", file=sys.stderr))
            print(f"{g}: {s.done} done, {s.failed} failed, {s.skipped} from earlier runs, {s.wall_s:.0f} s wall",
                  file=sys.stderr)
            keys = {p.key for p in study.points}
            rows = [r for r in table.read().to_pylist() if r["key"] in keys and r["status"] == "done"]
            for r in table.read().to_pylist():
                if r["key"] in keys and r["status"] != "done":
                    print(f"  failed point {r['point']}: {r['error']}")
            (report_library if g == "library" else report_foreign)(rows)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


if __name__ == "__main__":
    main()
