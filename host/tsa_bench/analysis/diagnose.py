"""The diagnose engine (issue 5): calibrate, replay, test, rank, name, extend, measure.

Units: length mm, resistance ohm, time s; scores are fractions of residual variance.

Contract: see :func:`diagnose`. Decision rule for naming a cause (false-alarm control):
a candidate effect, refitted together with the model's own parameters on the training
part, is named when (a) its held-out RMSE falls by at least :data:`GAIN_MIN` on some
output, (b) no output's held-out RMSE rises by more than :data:`GAIN_MIN`, (c) the
training delta-BIC is below :data:`DBIC_MAX`, and (d) the gain is the effect's own:
switching the effect off again in the refitted model loses at least half of it (so a
better optimum of the old parameters is never credited to the new effect). On clean data
the extended model nests the judged one (each candidate's amplitude can go to zero),
so it can only fit noise: k extra parameters on n training points lower the held-out
RMSE by O(k/n) ~ 0.1 %, far below 15 %; the held-out gate, not the training BIC (which
over-counts evidence on autocorrelated residuals), carries the false-alarm control.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from tsa_bench.analysis.calibrate import OUTPUTS, Fit, Problem, calibrate
from tsa_bench.analysis.candidates import generic_signals, pooled, problem_masks, screen_effect, sim_outputs
from tsa_bench.analysis.inputs import RunInputs, run_inputs, split
from tsa_bench.analysis.modelspec import (CANDIDATE_SPECS, baseline_specs, candidate_effects, enabled_effects,
                                          get_value, switch)
from tsa_bench.analysis.replay import noise_level, replay, subsample
from tsa_bench.analysis.residual_tests import test_residuals
from tsa_bench.analysis.result import Candidate, DiagnoseResult, Gain

GAIN_MIN = 0.15        # relative held-out RMSE gain needed on an output
DBIC_MAX = -10.0       # training delta-BIC needed ("very strong" on the Kass-Raftery scale)
SCREEN_DBIC = -10.0    # screening: only effects whose signature explains this much are refitted
REFIT_TOP = 3          # refit at most this many effects per iteration
N_CAL = 1500           # training subsample size (per all runs)
N_EVAL = 2500          # evaluation subsample size per run (gating)


def _heldout_rmse(cfg: Mapping[str, Any], runs: list[RunInputs], idxs: list[np.ndarray]) -> dict[str, float]:
    sq = {o: [] for o in OUTPUTS}
    for r, idx in zip(runs, idxs):
        if not r.heldout[idx].any():
            continue
        length, res = replay(cfg, r, idx)
        h = r.heldout[idx]
        for o, sim in (("length", length), ("resistance", res)):
            d = (sim - getattr(r, o)[idx])[h]
            sq[o].append(d[np.isfinite(d)])
    out = {}
    for o in OUTPUTS:
        d = np.concatenate(sq[o]) if sq[o] else np.zeros(0)
        out[o] = float(np.sqrt(np.mean(d ** 2))) if len(d) else float("nan")
    return out


def _rel(before: float, after: float) -> float:
    return (before - after) / before if before > 0 and np.isfinite(before) and np.isfinite(after) else 0.0


def diagnose(runs: list, model_plant_cfg: Mapping[str, Any], holdout: str | None = None, *,
             max_causes: int = 3, seed: int = 0) -> DiagnoseResult:
    """Judge ``model_plant_cfg`` against ``runs`` (RunData); see the module docstring."""
    t_start = time.perf_counter()
    notes: list[str] = []
    rng = np.random.default_rng(seed)
    del rng  # deterministic procedure; seed kept for API stability
    init_load = float(model_plant_cfg.get("initial_load_g", 0.0))
    inputs = [run_inputs(r, init_load) for r in runs]
    if not inputs or not any(len(r) for r in inputs):
        raise ValueError("diagnose: no samples")
    notes.append(split(inputs, holdout))
    n_train_total = sum(r.n_train for r in inputs)
    if n_train_total < 20:
        raise ValueError("diagnose: too few training samples after the holdout split")
    # noise levels (training part, motor still)
    sigma = {}
    for o in OUTPUTS:
        vals = [noise_level(getattr(r, o)[: r.n_train], ~r.moving[: r.n_train]) for r in inputs if r.n_train > 20]
        vals = [v for v in vals if np.isfinite(v) and v > 0]
        sigma[o] = float(np.median(vals)) if vals else 1.0
    sigma = {o: max(s, 1e-9) for o, s in sigma.items()}
    notes.append("noise levels: " + ", ".join(f"{o} {s:.3g}" for o, s in sigma.items()))
    train_idx = [subsample(r, r.n_train, max(200, N_CAL * r.n_train // max(1, n_train_total))) for r in inputs]
    eval_idx = [subsample(r, len(r), N_EVAL) for r in inputs]
    problem = Problem(inputs, train_idx, sigma)

    # 1. calibrate the judged model
    model = dict(model_plant_cfg)
    specs = baseline_specs(model)
    fit0 = calibrate(problem, model, specs, max_nfev=40)
    if fit0.dropped:
        notes.append("not informed by the data (kept at their values): " + ", ".join(fit0.dropped))
    effects_before = [e for e in enabled_effects(model)]
    calibrated = {"before": dict(fit0.values)}

    current: Fit = fit0
    causes: list[str] = []
    cand_by_name: dict[str, Candidate] = {}
    masks = problem_masks(problem)
    for iteration in range(1, max_causes + 1):
        res = problem.residuals(current.cfg)
        base_sim = sim_outputs(problem, current.cfg)
        # generic signals (first iteration only: they describe the judged model's residual)
        if iteration == 1:
            r0 = get_value(current.cfg, "geometry.resistance_ohm")
            gens = [generic_signals(r, r0) for r in inputs]
            for name in ("time", "cycle_count", "motor_angle", "direction", "time_since_stop", "heater_power"):
                cols = {}
                for o in OUTPUTS:
                    parts = [g[name][idx] for g, idx in zip(gens, train_idx) if len(idx)]
                    cols[o] = np.concatenate(parts)[masks[o]]
                err, dbic, per = pooled(res, cols)
                cand_by_name[name] = Candidate(name, "signal", err, {"delta_bic": dbic, "err_per_output": per,
                                                                     "output": max(per, key=per.get) if per else None})
        # screen the effects the model leaves off
        screened = []
        for name in candidate_effects(current.cfg):
            s = screen_effect(problem, current.cfg, name, res, base_sim)
            screened.append((name, s))
            ev = {"err": s["err"], "delta_bic_screen": s["delta_bic"], "err_per_output": s["per_output"],
                  "screen_params": s["params"], "iteration": iteration,
                  "output": max(s["per_output"], key=s["per_output"].get) if s["per_output"] else None}
            cand_by_name[name] = Candidate(name, "effect", s["err"], ev)
        screened.sort(key=lambda x: -x[1]["err"])
        to_refit = [(n, s) for n, s in screened if s["delta_bic"] < SCREEN_DBIC and s["err"] > 0.01][:REFIT_TOP]
        if not to_refit:
            notes.append(f"iteration {iteration}: no candidate effect's signature explains the residual "
                         f"(screening delta-BIC >= {SCREEN_DBIC})")
            break
        best = None
        hold_cur = _heldout_rmse(current.cfg, inputs, eval_idx)
        for name, s in to_refit:
            cfg_on = switch(current.cfg, name, True, s["params"])
            specs_ext = baseline_specs(cfg_on)
            start = dict(current.values)
            for sp in CANDIDATE_SPECS[name]:
                start[sp.key] = get_value(cfg_on, sp.key)
            fit = calibrate(problem, cfg_on, specs_ext, start=start, max_nfev=30)
            n = fit.n
            dbic = n * np.log(max(fit.rss, 1e-300) / max(current.rss, 1e-300)) + (fit.k - current.k) * np.log(n)
            score = max(0.0, 1.0 - fit.rss / current.rss) if current.rss > 0 else 0.0
            hold = _heldout_rmse(fit.cfg, inputs, eval_idx)
            ablated = _heldout_rmse(switch(fit.cfg, name, False), inputs, eval_idx)
            gains = {o: _rel(hold_cur[o], hold[o]) for o in OUTPUTS}
            own = {o: _rel(ablated[o], hold[o]) for o in OUTPUTS}
            best_o = max(gains, key=lambda o: gains[o])
            ok = (gains[best_o] >= GAIN_MIN and min(gains.values()) > -GAIN_MIN and dbic < DBIC_MAX
                  and own[best_o] >= 0.5 * gains[best_o])
            ev = cand_by_name[name].evidence
            ev.update({"output": best_o, "delta_bic": float(dbic), "heldout_gain": gains[best_o],
                       "heldout_gain_per_output": gains, "own_gain_per_output": own, "refit": True,
                       "params": {sp.key: fit.values.get(sp.key) for sp in CANDIDATE_SPECS[name]},
                       "significant": bool(ok)})
            cand_by_name[name].score = score
            if ok and (best is None or dbic < best[2]):
                best = (name, fit, dbic)
        if best is None:
            notes.append(f"iteration {iteration}: refitted {', '.join(n for n, _ in to_refit)}; "
                         f"none gives a significant held-out improvement (>= {GAIN_MIN:.0%})")
            break
        name, fit, dbic = best
        causes.append(name)
        current = fit
        notes.append(f"iteration {iteration}: named {name} (training delta-BIC {dbic:.0f}, held-out gain "
                     f"{cand_by_name[name].evidence['heldout_gain']:.0%} on {cand_by_name[name].evidence['output']})")

    calibrated["after"] = dict(current.values)
    # full-resolution replays for the final numbers and figures
    series: dict[str, np.ndarray] = {}
    full_res_before = {o: [] for o in OUTPUTS}
    full_res_after = {o: [] for o in OUTPUTS}
    parts: dict[str, list] = {k: [] for k in ("t", "heldout", "length_measured", "length_before", "length_after",
                                              "resistance_measured", "resistance_before", "resistance_after")}
    t_off = 0.0
    for r in inputs:
        lb, rb = replay(fit0.cfg, r, None)
        if causes:
            la, ra = replay(current.cfg, r, None)
        else:
            la, ra = lb, rb
        parts["t"].append(r.t + t_off)
        t_off += r.t[-1] - r.t[0] + 1.0 if len(r.t) else 0.0
        parts["heldout"].append(r.heldout)
        for o, b, a in (("length", lb, la), ("resistance", rb, ra)):
            meas = getattr(r, o)
            parts[f"{o}_measured"].append(meas)
            parts[f"{o}_before"].append(b)
            parts[f"{o}_after"].append(a)
            full_res_before[o].append(b - meas)
            full_res_after[o].append(a - meas)
    series = {k: np.concatenate(v) for k, v in parts.items()}
    gain = []
    ho = series["heldout"]
    for o in OUTPUTS:
        db = series[f"{o}_before"][ho] - series[f"{o}_measured"][ho]
        da = series[f"{o}_after"][ho] - series[f"{o}_measured"][ho]
        db, da = db[np.isfinite(db)], da[np.isfinite(da)]
        b = float(np.sqrt(np.mean(db ** 2))) if len(db) else float("nan")
        a = float(np.sqrt(np.mean(da ** 2))) if len(da) else float("nan")
        gain.append(Gain(o, b, a, _rel(b, a)))
    # residual tests on the full-resolution residuals
    sigs = {}
    gens = [generic_signals(r) for r in inputs]
    for name in ("time", "cycle_count", "motor_angle", "direction", "time_since_stop", "heater_power"):
        sigs[name] = np.concatenate([g[name][:, 0] for g in gens])
    sigs["turns"] = np.concatenate([r.turns for r in inputs])
    sigs["load"] = np.concatenate([r.load_g for r in inputs])
    rt_before = test_residuals({o: np.concatenate(v) for o, v in full_res_before.items()}, sigs)
    rt_after = test_residuals({o: np.concatenate(v) for o, v in full_res_after.items()}, sigs)
    if causes:
        # the named cause's signature: extended model minus the same model with the cause off
        cfg_off = switch(current.cfg, causes[0], False)
        sig_parts = []
        for r in inputs:
            lo, ro = replay(cfg_off, r, None)
            la, ra = replay(current.cfg, r, None)
            o = cand_by_name[causes[0]].evidence.get("output", "length")
            sig_parts.append((la - lo) if o == "length" else (ra - ro))
        series["cause_signal"] = np.concatenate(sig_parts)
    candidates = sorted(cand_by_name.values(), key=lambda c: (c.kind != "effect", -c.score))
    notes.append(f"diagnose took {time.perf_counter() - t_start:.1f} s")
    return DiagnoseResult(causes[0] if causes else None, causes, candidates, gain,
                          {"before": rt_before, "after": rt_after}, effects_before, enabled_effects(current.cfg),
                          calibrated, series, notes)
