"""Bounded least-squares calibration of a plant config's free parameters on training data.

Units: parameters in their own units (modelspec); residuals in units of each output's
noise level (dimensionless), so length (mm) and resistance (ohm) weigh by information.

Contract: a :class:`Problem` holds the runs, the training subsample of each run and the
noise levels. :func:`calibrate` fits ``specs`` (scipy.optimize.least_squares, 'trf',
variables mapped to [0, 1] between physical bounds, forward differences) starting from
the config's current values (or ``start``), drops parameters the data do not inform,
and returns the fitted config, the values and the training residual sum of squares.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.modelspec import ParamSpec, get_value, set_values
from tsa_bench.analysis.replay import replay

OUTPUTS = ("length", "resistance")


@dataclass
class Problem:
    runs: list[RunInputs]
    idx: list[np.ndarray]          # training subsample per run
    sigma: dict[str, float]        # noise level per output

    def residuals(self, cfg: Mapping[str, Any]) -> dict[str, np.ndarray]:
        """Noise-normalised model-minus-measured residuals per output (NaN samples dropped)."""
        out = {o: [] for o in OUTPUTS}
        for r, idx in zip(self.runs, self.idx):
            if len(idx) == 0:
                continue
            length, res = replay(cfg, r, idx)
            for o, sim in (("length", length), ("resistance", res)):
                meas = getattr(r, o)[idx]
                d = (sim - meas) / self.sigma[o]
                out[o].append(d[np.isfinite(d)])
        return {o: np.concatenate(v) if v else np.zeros(0) for o, v in out.items()}

    def vector(self, cfg: Mapping[str, Any]) -> np.ndarray:
        res = self.residuals(cfg)
        return np.concatenate([res[o] for o in OUTPUTS])


@dataclass
class Fit:
    cfg: dict
    values: dict[str, float]
    rss: float
    n: int
    k: int
    dropped: list[str]
    nfev: int


def calibrate(problem: Problem, cfg: Mapping[str, Any], specs: list[ParamSpec],
              start: Mapping[str, float] | None = None, max_nfev: int = 30, probe: float = 0.05) -> Fit:
    start = dict(start or {})
    u0 = np.array([s.to_u(start.get(s.key, get_value(cfg, s.key))) for s in specs])

    def build(u: np.ndarray, active: list[int]) -> dict:
        vals = {s.key: s.to_value(u0[i]) for i, s in enumerate(specs)}
        for j, i in enumerate(active):
            vals[specs[i].key] = specs[i].to_value(u[j])
        return set_values(cfg, vals)

    all_i = list(range(len(specs)))
    f0 = problem.vector(build(u0, all_i))
    # identifiability probe: drop parameters whose +-probe step changes nothing
    active, dropped = [], []
    for i in all_i:
        u = u0.copy()
        u[i] = u0[i] + probe if u0[i] + probe <= 1.0 else u0[i] - probe
        f = problem.vector(build(u, all_i))
        if len(f) == len(f0) and np.sqrt(np.mean((f - f0) ** 2)) > 1e-3:
            active.append(i)
        else:
            dropped.append(specs[i].key)
    nfev = 1 + len(specs)
    if active:
        sol = least_squares(lambda u: problem.vector(build(u, active)), u0[active], bounds=(0.0, 1.0),
                            method="trf", diff_step=1e-3, x_scale=1.0, max_nfev=max_nfev,
                            ftol=1e-6, xtol=1e-6, gtol=1e-8)
        u_best = sol.x
        nfev += sol.nfev * (1 + len(active))
        rss = float(2.0 * sol.cost)
        if rss > float(f0 @ f0):   # never worse than the start
            u_best, rss = u0[active], float(f0 @ f0)
    else:
        u_best, rss = np.zeros(0), float(f0 @ f0)
    fitted = build(u_best, active)
    values = {s.key: get_value(fitted, s.key) for s in specs}
    return Fit(fitted, values, rss, len(f0), len(active), dropped, nfev)
