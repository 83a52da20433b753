"""Reproduce the thesis's chapter-3 modelling procedures on simulated runs and print the tables.

Usage: PYTHONPATH=host python3 scripts/reproduce_thesis_models.py [--cycles N] [--keep DIR]

1. Strain-resistance and self-sensing (section 3.2.2): identify on the 6 s and 32 s
   step-duration runs, validate on 2.4, 17 and 98 s; eq. 3.21 errors. Thesis
   validation: strain-resistance <= 0.65 % of y, self-sensing <= 0.14 % of L.
2. Preisach (M = 20) vs third-order polynomial (Fig. 3.1(a), Table 3.1): twisting and
   heating, 3-ply (100/150/200 g) and 4-ply (150/200/250 g); E_aver, sigma in mm.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from tsa_bench.reproduce.procedures import preisach_vs_polynomial, step_duration_procedure


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cycles", type=int, default=2, help="staircases per step-duration run (default 2)")
    ap.add_argument("--keep", default=None, help="directory to keep the simulated run files in")
    args = ap.parse_args()
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="thesis-models-"))
    work.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    res = step_duration_procedure(work, cycles=args.cycles)
    print("Strain-resistance and self-sensing models (identified on 6 s + 32 s; eq. 3.21)")
    print(f"{'model':18s} {'step s':>6s} {'set':>14s} {'n':>6s} {'mean %':>8s} {'max %':>8s} {'E_aver':>12s}")
    for model, r in res.items():
        for row in r["rows"]:
            print(f"{model:18s} {row['step_s']:6g} {row['set']:>14s} {row['n']:6d} {row['mean_percent']:8.4f} "
                  f"{row['max_percent']:8.4f} {row['e_aver']:9.5f} {row['unit']}")
    sr = res["strain-resistance"]["saved"].parameters
    print("strain-resistance parameters: " + ", ".join(
        f"{k}={sr[k]['value']:.4g} {sr[k]['unit']}" for k in ("b1", "b2", "alpha", "beta", "lambda", "epsilon", "a",
                                                              "offset")))
    print(f"  Lambda={sr['Lambda']['value']} 1/s, c={sr['c']['value']} ohm/mm")
    print(f"({time.perf_counter() - t0:.1f} s)\n")
    t0 = time.perf_counter()
    rows = preisach_vs_polynomial(work)
    print("Preisach (M = 20) vs third-order polynomial, quasi-static samples (E_aver +- sigma, mm)")
    print(f"{'string':7s} {'load g':>6s} {'mode':>9s} {'Preisach':>18s} {'polynomial':>18s} {'ratio':>7s}")
    for r in rows:
        print(f"{r['string']:7s} {r['load_g']:6g} {r['mode']:>9s} "
              f"{r['preisach_e_aver_mm']:8.4f} +- {r['preisach_sigma_mm']:6.4f} "
              f"{r['polynomial_e_aver_mm']:8.4f} +- {r['polynomial_sigma_mm']:6.4f} {r['ratio']:7.1f}")
    print(f"({time.perf_counter() - t0:.1f} s; run files in {work})")


if __name__ == "__main__":
    main()
