"""Screen candidate forms by how much of the training residual their signature explains.

Units: scores are fractions of the noise-normalised training residual (outputs pooled).

Contract: :func:`screen` replays the current model with one form switched on (each of
its screening parameter sets, :func:`tsa_bench.analysis.families.screen_params`) on the
training subsample; the signature is that replay minus the current one, both outputs
stacked in noise units, and its score is the share of the training residual a single
least-squares multiple of it removes (one amplitude for both outputs, so a length
effect must also move the resistance the way the model's dR/dX says). The signature is
first projected off the directions in which the model's own parameters move the
replay (:func:`jacobian`), because a re-calibration absorbs those: the score is then the
Lagrange-multiplier (score) test statistic of adding the form, as a share of the
residual. Forms whose physics fixes the sign (a slip only loses twist) only score with a
positive multiple. It returns the best variant's score and parameters.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tsa_bench.analysis.calibrate import Problem
from tsa_bench.analysis.families import screen_params, RunScale
from tsa_bench.analysis.modelspec import switch

#: forms whose signature cannot flip sign by a parameter
SIGN_FIXED = ("missed_steps", "missed_steps_pullout", "missed_steps_saturating", "twist_hysteresis", "length_creep",
              "length_creep_twist", "thermal_dynamics", "load_dependence", "resistance_hysteresis")


def stacked(res: dict[str, np.ndarray], outputs: tuple[str, ...]) -> np.ndarray:
    return np.concatenate([res[o] for o in outputs])


def jacobian(problem: Problem, cfg: Mapping[str, Any], base: np.ndarray, step: float = 1e-3) -> np.ndarray:
    """Columns: how the stacked training residual moves with each of the model's own
    parameters (finite differences in the optimiser's [0, 1] variables)."""
    from tsa_bench.analysis.modelspec import baseline_specs, get_value, set_values
    cols = []
    for spec in baseline_specs(cfg):
        u = spec.to_u(get_value(cfg, spec.key))
        u2 = u + step if u + step <= 1.0 else u - step
        moved = stacked(problem.residuals(set_values(cfg, {spec.key: spec.to_value(u2)})), problem.outputs)
        if len(moved) == len(base):
            cols.append((moved - base) / (u2 - u))
    return np.column_stack(cols) if cols else np.zeros((len(base), 0))


def _project_off(sig: np.ndarray, jac: np.ndarray) -> np.ndarray:
    if jac.shape[1] == 0:
        return sig
    coef, *_ = np.linalg.lstsq(jac, sig, rcond=1e-10)
    return sig - jac @ coef


def screen(problem: Problem, cfg: Mapping[str, Any], form: str, residual: np.ndarray, base: np.ndarray,
           scale: RunScale, jac: np.ndarray | None = None) -> dict:
    """Best screening variant of ``form``: {score, params, per_output}."""
    best = {"score": 0.0, "params": {}, "per_output": {}}
    tss = float(residual @ residual)
    if tss <= 0:
        return best
    for params in screen_params(form, scale):
        on = stacked(problem.residuals(switch(cfg, form, True, params)), problem.outputs)
        sig = on - base
        if len(sig) != len(residual):
            continue
        if jac is not None:
            sig = _project_off(sig, jac)
        ss = float(sig @ sig)
        if ss <= 1e-18:
            continue
        beta = -float(residual @ sig) / ss     # residual + beta * sig ~ 0
        if form in SIGN_FIXED and beta < 0:
            continue
        score = beta * beta * ss / tss
        if score > best["score"]:
            per, k = {}, 0
            for o, n in zip(problem.outputs, _lengths(problem)):
                r, s = residual[k:k + n], sig[k:k + n]
                left = r + beta * s
                per[o] = float(min(1.0, max(0.0, 1.0 - (left @ left) / (r @ r)))) if r @ r > 0 else 0.0
                k += n
            best = {"score": float(min(score, 1.0)), "params": dict(params), "per_output": per, "amplitude": beta}
    return best


def _lengths(problem: Problem) -> list[int]:
    n = []
    for o in problem.outputs:
        c = 0
        for r, idx, tr in zip(problem.runs, problem.idx, problem.train):
            meas = r.output(o)[idx]
            c += int(np.sum(tr & np.isfinite(meas) & r.scored[idx]))
        n.append(c)
    return n
