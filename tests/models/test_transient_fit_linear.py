"""The transient-decay fit (eq. 3.9, shared b1, b2 and one level per hold curve) solved on
curve-demeaned columns gives the optimum of the full design matrix (one column per curve),
with bounds active or not, in memory linear in the samples."""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear

from tsa_bench.models.transient import EPS_S, fit_decay


def _dense(curves):
    """Reference: the full bounded least squares with one level column per curve."""
    m = len(curves)
    rows, ys = [], []
    for i, (dt, y) in enumerate(curves):
        ok = np.isfinite(y)
        lg = np.log(dt[ok] + EPS_S)
        block = np.zeros((ok.sum(), m + 2))
        block[:, 0], block[:, 1], block[:, 2 + i] = lg * lg, lg, 1.0
        rows.append(block)
        ys.append(y[ok])
    lo = np.r_[-np.inf, -np.inf, np.full(m, -np.inf)]
    hi = np.r_[0.0, 0.0, np.full(m, np.inf)]
    x = lsq_linear(np.vstack(rows), np.concatenate(ys), bounds=(lo, hi), method="bvls").x
    return x[0], x[1], x[2:]


def _curves(b1: float, b2: float, seed: int):
    rng = np.random.default_rng(seed)
    curves = []
    for i in range(30):
        n = int(rng.integers(1, 50))
        dt = np.arange(n) * 0.1
        lg = np.log(dt + EPS_S)
        y = 5 + rng.normal() * 0.1 + b1 * lg * lg + b2 * lg + rng.normal(0, 1e-3, n)
        if i % 7 == 0:
            y[::3] = np.nan
        if i == 5:
            y[:] = np.nan
        curves.append((dt, y))
    return curves


def test_demeaned_fit_equals_the_full_design_matrix():
    for b1, b2, seed in ((-2e-3, -1e-2, 0), (3e-3, -1e-2, 1), (2e-3, 2e-2, 2)):   # free, b1 bound, both bound
        curves = _curves(b1, b2, seed)
        got = fit_decay(curves)
        ref = _dense(curves)
        assert abs(got[0] - ref[0]) < 1e-9 and abs(got[1] - ref[1]) < 1e-9
        assert got[0] <= 0 and got[1] <= 0
        assert np.isnan(got[2][5])
        ok = np.isfinite(got[2])
        assert np.allclose(got[2][ok], ref[2][ok], atol=1e-9)
