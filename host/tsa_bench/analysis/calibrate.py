"""Bounded least-squares calibration of a plant config's free parameters on training data.

Units: parameters in their own units (modelspec); residuals in units of each output's
noise RMS (dimensionless), so length (mm) and resistance (ohm) weigh by information.

Contract: a :class:`Problem` holds the runs, the replay subsample of each run (training
and held-out samples alike, so the plant state runs through) with its training mask, the
noise RMS per output and the outputs judged. :func:`calibrate` fits ``specs``
(scipy.optimize.least_squares, 'trf', variables mapped to [0, 1] between the bounds)
from ``start`` with weak priors around ``centre`` (modelspec), after dropping
parameters whose change moves nothing; it returns a :class:`Fit` that also lists the
parameters that ended at a soft (non-physical) bound and those the data left
undetermined (posterior variance more than a quarter of the prior's).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from tsa_bench.analysis.inputs import OUTPUTS, RunInputs
from tsa_bench.analysis.modelspec import get_value, set_values
from tsa_bench.analysis.paramspec import ParamSpec
from tsa_bench.analysis.replay import ReplayCache, replay


@dataclass
class Problem:
    runs: list[RunInputs]
    idx: list[np.ndarray]          # replay subsample per run (sorted)
    train: list[np.ndarray]        # training mask over idx
    sigma: dict[str, float]        # noise RMS per output
    outputs: tuple[str, ...] = OUTPUTS
    cache: ReplayCache | None = None   # shared by the problems of one diagnosis
    state: list[np.ndarray] | None = None   # per run: samples replayed for the plant state only

    def simulate(self, cfg: Mapping[str, Any]) -> list[dict[str, np.ndarray]]:
        out = []
        for k, (r, idx) in enumerate(zip(self.runs, self.idx)):
            length, res = replay(cfg, r, idx, self.cache, self.state[k] if self.state else None)
            out.append({"length": length, "resistance": res})
        return out

    def residuals(self, cfg: Mapping[str, Any], sims: list[dict] | None = None) -> dict[str, np.ndarray]:
        """Noise-normalised model-minus-measured training residuals per output (unmeasured samples dropped)."""
        sims = sims if sims is not None else self.simulate(cfg)
        out: dict[str, list] = {o: [] for o in self.outputs}
        for r, idx, tr, sim in zip(self.runs, self.idx, self.train, sims):
            for o in self.outputs:
                meas = r.output(o)[idx]
                keep = tr & np.isfinite(meas) & r.scored[idx]
                d = (sim[o][keep] - meas[keep]) / self.sigma[o]
                out[o].append(np.nan_to_num(d, nan=1e3, posinf=1e3, neginf=-1e3))
        return {o: np.concatenate(v) if v else np.zeros(0) for o, v in out.items()}

    def vector(self, cfg: Mapping[str, Any]) -> np.ndarray:
        res = self.residuals(cfg)
        return np.concatenate([res[o] for o in self.outputs])


@dataclass
class Fit:
    cfg: dict
    values: dict[str, float]
    rss: float
    n: int
    k: int
    dropped: list[str]
    nfev: int
    at_bound: list[dict] = field(default_factory=list)     # {key, value, bound, side}
    undetermined: list[str] = field(default_factory=list)
    cost: float = 0.0      # rss plus the squared prior residuals (what the fit minimised)


def calibrate(problem: Problem, cfg: Mapping[str, Any], specs: list[ParamSpec],
              start: Mapping[str, float] | None = None, centre: Mapping[str, float] | None = None,
              max_nfev: int = 40, probe: float = 0.02) -> Fit:
    start = dict(start or {})
    centre = dict(centre or {})
    # priors only where a centre is given (the judged model's own values): a candidate's
    # parameters are free within their physical range
    centres = [centre.get(s.key) for s in specs]
    u0 = np.array([s.to_u(start.get(s.key, get_value(cfg, s.key))) for s in specs])

    def build(u: np.ndarray, active: list[int]) -> dict:
        vals = {s.key: s.to_value(u0[i]) for i, s in enumerate(specs)}
        for j, i in enumerate(active):
            vals[specs[i].key] = specs[i].to_value(u[j])
        return set_values(cfg, vals)

    def prior(u: np.ndarray, active: list[int]) -> np.ndarray:
        return np.array([specs[i].prior_residual(specs[i].to_value(u[j]), centres[i]) for j, i in enumerate(active)
                         if specs[i].prior > 0 and centres[i] is not None])

    all_i = list(range(len(specs)))
    f0 = problem.vector(build(u0, all_i))
    active, dropped = [], []
    for i in all_i:
        u = u0.copy()
        u[i] = u0[i] + probe if u0[i] + probe <= 1.0 else u0[i] - probe
        f = problem.vector(build(u, all_i))
        if len(f) == len(f0) and np.sqrt(np.mean((f - f0) ** 2)) > 1e-4:
            active.append(i)
        else:
            dropped.append(specs[i].key)
    nfev = 1 + len(specs)

    def fun(u: np.ndarray) -> np.ndarray:
        return np.r_[problem.vector(build(u, active)), prior(u, active)]

    at_bound, undetermined = [], []
    if active:
        x0 = np.clip(u0[active], 1e-6, 1 - 1e-6)
        sol = least_squares(fun, x0, bounds=(0.0, 1.0), method="trf", diff_step=1e-3, x_scale=1.0,
                            max_nfev=max_nfev, ftol=1e-7, xtol=1e-7, gtol=1e-9)
        u_best = sol.x
        nfev += sol.nfev * (1 + len(active))
        total0 = float(fun(x0) @ fun(x0))
        if 2.0 * sol.cost > total0:   # never worse than the start
            u_best = x0
        jac = sol.jac[: len(f0)] if sol.jac is not None else None
        for j, i in enumerate(active):
            s = specs[i]
            if u_best[j] <= 1e-3 and not s.hard_lo:
                at_bound.append({"key": s.key, "value": s.to_value(u_best[j]), "bound": s.lo, "side": "lower"})
            elif u_best[j] >= 1 - 1e-3 and not s.hard_hi:
                at_bound.append({"key": s.key, "value": s.to_value(u_best[j]), "bound": s.hi, "side": "upper"})
        if jac is not None and jac.shape[1] == len(active):
            undetermined = _undetermined(jac, [specs[i] for i in active], [centres[i] for i in active])
    else:
        u_best = np.zeros(0)
    fitted = build(u_best, active)
    res = problem.vector(fitted)
    values = {s.key: get_value(fitted, s.key) for s in specs}
    pri = prior(u_best, active) if active else np.zeros(0)
    return Fit(fitted, values, float(res @ res), len(res), len(active), dropped, nfev, at_bound, undetermined,
               float(res @ res + pri @ pri))


def _undetermined(jac: np.ndarray, specs: list[ParamSpec], centres: list) -> list[str]:
    """Parameters (with a prior) whose posterior variance stays above a quarter of the prior's."""
    prior_u = []
    for s, c in zip(specs, centres):
        width = (np.log(s.hi) - np.log(s.lo)) if s.log else (s.hi - s.lo)
        prior_u.append((s.prior_sd(c) / width) if s.prior > 0 and c is not None else np.inf)
    prior_u = np.array(prior_u)
    info = jac.T @ jac + np.diag(np.where(np.isfinite(prior_u), 1.0 / np.maximum(prior_u, 1e-12) ** 2, 0.0))
    try:
        cov = np.linalg.pinv(info)
    except np.linalg.LinAlgError:
        return []
    out = []
    for i, s in enumerate(specs):
        if np.isfinite(prior_u[i]) and cov[i, i] > 0.25 * prior_u[i] ** 2:
            out.append(s.key)
    return out
