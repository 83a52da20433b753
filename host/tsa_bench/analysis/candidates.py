"""Candidate causes: generic signals and library-effect signatures, scored on the residual.

Units: signals in their own units (s, cycles, 1, W); scores are fractions of the
noise-normalised training residual variance.

Contract: :func:`generic_signals` builds the generic candidate signals of a run
(time, cycle count, motor angle within a turn, direction of motion, time since the
motor stopped, heater power) as columns. :func:`explained` regresses a residual on
columns (with intercept) and returns the error reduction ratio (R^2) and the change in
BIC. :func:`screen_effect` computes an effect's signature (replay with it on minus
replay without, for each screening variant) and keeps the variant that explains most.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tsa_bench.analysis.calibrate import OUTPUTS, Problem
from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.modelspec import SCREEN_VARIANTS, switch

GENERIC = ("time", "cycle_count", "motor_angle", "direction", "time_since_stop", "heater_power")


def generic_signals(r: RunInputs, r0_ohm: float = 5.0) -> dict[str, np.ndarray]:
    """name -> (n, k) array of columns."""
    n = len(r)
    starts = np.r_[False, (r.moving[1:] & ~r.moving[:-1])]
    if r.cycle is not None and (r.cycle >= 0).any():
        cyc = np.maximum.accumulate(np.where(r.cycle >= 0, r.cycle + 1, 0)).astype(float)
        cyc += np.cumsum(starts) / 1e6  # tie-break only
    else:
        cyc = np.cumsum(starts) / 2.0
    d = np.diff(np.abs(r.turns), prepend=np.abs(r.turns[0]))
    step = np.sign(d)
    idx = np.where(step != 0, np.arange(n), 0)
    np.maximum.accumulate(idx, out=idx)
    last_dir = step[idx]
    stops = np.r_[False, (~r.moving[1:] & r.moving[:-1])]
    last_stop = np.where(stops, np.arange(n), -1)
    np.maximum.accumulate(last_stop, out=last_stop)
    since = np.where(last_stop >= 0, r.t - r.t[np.maximum(last_stop, 0)], np.inf)
    since = np.where(r.moving, 0.0, since)
    lg = np.log1p(np.minimum(since, 600.0))
    p = r.volts ** 2 / max(r0_ohm, 1e-9)
    cols_p = [p]
    for tau in (3.0, 30.0):
        y = np.empty(n)
        acc = 0.0
        dt = np.diff(r.t, prepend=r.t[0])
        a = np.exp(-dt / tau)
        # first-order low-pass (vectorised enough: n ~ 1e5 loop in numpy is too slow -> use lfilter-free recursion)
        for i in range(n):
            acc = a[i] * acc + (1 - a[i]) * p[i]
            y[i] = acc
        cols_p.append(y)
    ang = 2 * np.pi * r.turns
    return {
        "time": r.t[:, None],
        "cycle_count": cyc[:, None],
        "motor_angle": np.c_[np.sin(ang), np.cos(ang)],
        "direction": np.c_[last_dir, step],
        "time_since_stop": lg[:, None],
        "heater_power": np.column_stack(cols_p),
    }


def explained(y: np.ndarray, x: np.ndarray) -> tuple[float, float, np.ndarray]:
    """(ERR = R^2, delta BIC, coefficients) of OLS of y on [1, x]; NaN rows dropped."""
    x = np.asarray(x, float)
    if x.ndim == 1:
        x = x[:, None]
    ok = np.isfinite(y) & np.all(np.isfinite(x), axis=1)
    y, x = y[ok], x[ok]
    n = len(y)
    if n < 10:
        return 0.0, 0.0, np.zeros(x.shape[1])
    x = x - x.mean(axis=0)
    keep = np.std(x, axis=0) > 0
    y0 = y - y.mean()
    tss = float(y0 @ y0)
    if not keep.any() or tss <= 0:
        return 0.0, 0.0, np.zeros(x.shape[1])
    beta, *_ = np.linalg.lstsq(x[:, keep], y0, rcond=None)
    rss = float(np.sum((y0 - x[:, keep] @ beta) ** 2))
    err = max(0.0, 1.0 - rss / tss)
    dbic = n * np.log(max(rss, 1e-300) / tss) + keep.sum() * np.log(n)
    full = np.zeros(x.shape[1])
    full[keep] = beta
    return err, float(dbic), full


def pooled(res: dict[str, np.ndarray], cols: dict[str, np.ndarray]) -> tuple[float, float, dict]:
    """Pooled ERR over outputs (each its own coefficients) and summed delta BIC."""
    tss = sum(float(np.sum((r - r.mean()) ** 2)) for r in res.values() if len(r))
    gained, dbic, per = 0.0, 0.0, {}
    for o, r in res.items():
        if o not in cols or len(r) < 10:
            continue
        err, db, _ = explained(r, cols[o])
        r0 = r - r.mean()
        gained += err * float(r0 @ r0)
        dbic += db
        per[o] = err
    return (gained / tss if tss > 0 else 0.0), dbic, per


def screen_effect(problem: Problem, cfg: Mapping[str, Any], name: str, res: dict[str, np.ndarray],
                  base_sim: dict[str, list[np.ndarray]]) -> dict:
    """Best screening variant of effect ``name``: {err, delta_bic, per_output, params, signature}."""
    best = {"err": 0.0, "delta_bic": 0.0, "per_output": {}, "params": {}, "signature": None}
    for variant in SCREEN_VARIANTS.get(name, ({},)):
        cfg_on = switch(cfg, name, True, variant)
        sig = sim_outputs(problem, cfg_on)
        cols = {o: np.concatenate(sig[o]) - np.concatenate(base_sim[o]) for o in OUTPUTS}
        # align with the residual (NaN-dropped) ordering
        cols = {o: cols[o][problem_masks(problem)[o]] for o in OUTPUTS}
        err, dbic, per = pooled(res, cols)
        if err > best["err"]:
            best = {"err": err, "delta_bic": dbic, "per_output": per, "params": dict(variant), "signature": cols}
    return best


def sim_outputs(problem: Problem, cfg: Mapping[str, Any]) -> dict[str, list[np.ndarray]]:
    from tsa_bench.analysis.replay import replay
    out = {o: [] for o in OUTPUTS}
    for r, idx in zip(problem.runs, problem.idx):
        if len(idx) == 0:
            continue
        length, res = replay(cfg, r, idx)
        out["length"].append(length)
        out["resistance"].append(res)
    return out


def problem_masks(problem: Problem) -> dict[str, np.ndarray]:
    """Finite-measurement masks over the concatenated training subsample, per output."""
    out = {}
    for o in OUTPUTS:
        out[o] = np.concatenate([np.isfinite(getattr(r, o)[idx]) for r, idx in zip(problem.runs, problem.idx)
                                 if len(idx)]) if any(len(i) for i in problem.idx) else np.zeros(0, bool)
    return out
