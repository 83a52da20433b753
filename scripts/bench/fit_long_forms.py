#!/usr/bin/env python3
"""The long-run and direct forms of the strain-resistance and self-sensing fits side by side.

Usage: PYTHONPATH=host python3 scripts/bench/fit_long_forms.py RUN.h5 [--fractions 0.05,0.1,1]
                                                                     [--self-sensing]

``RUN.h5`` is a run with holds (e.g. `tsa-bench run configs/protocols/lifetime.yaml
--output RUN.h5 --seed 1`); each fraction cuts its first part. For each cut, the
strain-resistance model is identified with the direct form and the long-run form
(alternately, in this process; CPU s), and printed: the nonlinear parameters, the
objective of eq. 3.19 (the direct form's own function) at each result, the RMSE over the
hold samples, the offset y0 and p_0. With ``--self-sensing`` the envelopes are then
identified both ways on the direct form's forward model (CPU s, largest relative
difference of the eight parameters, RMSE of the length estimate).

``--thesis-json OUT.json`` instead writes the thesis-sized fits (the step-duration
procedure of `tsa-bench reproduce`: both models on the 6 s + 32 s runs, 42 holds) as JSON
with every float in full; run it with another checkout's ``PYTHONPATH`` and ``cmp`` the two
files to see that the direct forms give the same bits.
"""

from __future__ import annotations

import argparse
import time

import numpy as np



def rmse(pred: np.ndarray, y: np.ndarray) -> float:
    ok = np.isfinite(pred) & np.isfinite(y)
    return float(np.sqrt(np.mean((pred[ok] - y[ok]) ** 2)))


def timed(fn):
    c0 = time.process_time()
    out = fn()
    return time.process_time() - c0, out


def thesis_json(out: str) -> None:
    import json
    import tempfile
    from pathlib import Path

    from tsa_bench.reproduce.procedures import step_duration_procedure

    res = step_duration_procedure(Path(tempfile.mkdtemp(prefix="fit-forms-")))
    doc = {m: {"parameters": {k: v["value"] for k, v in o["saved"].parameters.items()}, "rows": o["rows"]}
           for m, o in res.items()}
    with open(out, "w") as fh:
        json.dump(doc, fh, indent=1, sort_keys=True, default=repr)   # json writes floats round-trip exact
    print(f"wrote {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", nargs="?")
    ap.add_argument("--thesis-json", default=None)
    ap.add_argument("--fractions", default="0.05,0.1")
    ap.add_argument("--self-sensing", action="store_true")
    args = ap.parse_args()
    if args.thesis_json:
        thesis_json(args.thesis_json)
        return
    if not args.run:
        ap.error("give RUN.h5 (or --thesis-json OUT.json)")
    # imported here: --thesis-json also runs against a checkout without the long forms
    from tsa_bench.models.fitting import series
    from tsa_bench.models.self_sensing import SelfSensingModel
    from tsa_bench.models.steps import step_sequence
    from tsa_bench.models.strain_resistance import (LONG_RUN_HOLDS, MIN_LINEAR_FRACTION, N_HYSTERESIS,
                                                    StrainResistanceModel, _SteadyProblem)
    from tsa_bench.models.transient import fit_decay
    from tsa_bench.store import read_run
    from tsa_bench.rundata import RunData

    whole = read_run(args.run)
    print(f"fit_long_forms: {args.run}, long-run form above {LONG_RUN_HOLDS} holds (forms forced here)")
    for frac in (float(f) for f in args.fractions.split(",")):
        n = int(len(whole.samples["t"]) * frac)
        s = series(RunData(whole.path, whole.attrs, {k: v[:n] for k, v in whole.samples.items()}, whole.units,
                           None, None))
        seq = step_sequence(s)
        curves = [(s.t_s[c.start:c.stop] - c.t0_s, s.resistance_ohm[c.start:c.stop]) for c in seq.curves]
        _, _, ys = fit_decay(curves)
        slope = np.polyfit(seq.length_mm[1:], ys, 1)[0]
        objective = _SteadyProblem([seq], [ys], N_HYSTERESIS, 1.0 if slope >= 0 else -1.0,
                                   MIN_LINEAR_FRACTION * abs(slope)).cost
        print(f"\n{frac:g} of the run: {n:,} samples, {len(seq.curves):,} holds")
        models = {}
        for name, lf in (("direct", False), ("long", True)):
            cpu, m = timed(lambda: StrainResistanceModel.identify([s], long_form=lf))
            models[name] = m
            x = np.r_[m.alpha_mm, m.beta, m.lam, m.epsilon, m.creep_rates_per_s]
            print(f"  strain-resistance {name:6s}: CPU {cpu:7.2f} s, eq. 3.19 objective {objective(x):.6g} ohm^2, "
                  f"RMSE {rmse(m.predict(s), s.resistance_ohm):.6g} ohm; alpha {x[0]:.4g} mm, beta {x[1]:.4g}, "
                  f"lambda {x[2]:.4g}, eps {x[3]:.4g}, Lambda {x[4]:.4g} / {x[5]:.4g} 1/s, "
                  f"c {m.creep_densities_ohm_per_mm[0]:.4g} / {m.creep_densities_ohm_per_mm[1]:.4g} ohm/mm, "
                  f"y0 {m.offset_ohm:.5g} ohm, p0 {m.weights_ohm_per_mm[0]:.5g} ohm/mm", flush=True)
        if args.self_sensing:
            env = {}
            for name, lf in (("direct", False), ("long", True)):
                cpu, ss = timed(lambda: SelfSensingModel.identify(models["direct"], [s], long_form=lf))
                env[name] = np.r_[ss.rho, ss.phi]
                print(f"  self-sensing {name:6s}: CPU {cpu:7.2f} s, RMSE {rmse(ss.predict(s), s.length_mm):.6g} mm, "
                      f"rho {np.round(ss.rho, 5).tolist()}, phi {np.round(ss.phi, 5).tolist()}", flush=True)
            rel = np.max(np.abs(env["long"] - env["direct"]) / np.maximum(np.abs(env["direct"]), 1e-12))
            print(f"  self-sensing envelopes: largest relative difference {rel:.2e}")


if __name__ == "__main__":
    main()
