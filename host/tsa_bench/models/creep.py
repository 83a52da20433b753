"""Creep operators, thesis eqs. 3.13-3.14.

Units: ``Lambda`` in 1/s, sampling intervals in s; operator states in input units.

Contract: :func:`creep_operators` returns, for each sample k, the states
``x_i(k) = exp(-Lambda_i T_k) x_i(k-1) + (1 - exp(-Lambda_i T_k)) v(k-1)`` (eq. 3.13)
for ``T_k = t_k - t_{k-1}`` (time-varying sampling allowed), with ``x_i(0) = x0``
(default ``v(0)``). A unit step in v at k = 0 from x0 = 0 gives ``1 - exp(-Lambda t)``
at the sample times after the step. The creep output ``y_c = sum_i c_i x_i + a v`` is
eq. 3.14 (:func:`creep_output`).
"""

from __future__ import annotations

import numpy as np


def creep_operators(v: np.ndarray, t_s: np.ndarray, rates_per_s: np.ndarray,
                    x0: np.ndarray | float | None = None) -> np.ndarray:
    """(N, Nc) creep operator states for input ``v`` sampled at times ``t_s`` (nondecreasing)."""
    v = np.asarray(v, dtype=float)
    t = np.asarray(t_s, dtype=float)
    lam = np.atleast_1d(np.asarray(rates_per_s, dtype=float))
    if v.shape != t.shape:
        raise ValueError(f"v and t_s differ in shape: {v.shape} vs {t.shape}")
    if np.any(lam <= 0):
        raise ValueError("creep rates Lambda must be > 0")
    n = len(v)
    out = np.empty((n, len(lam)))
    if n == 0:
        return out
    dt = np.diff(t)
    if np.any(dt < 0):
        raise ValueError("sample times must be nondecreasing")
    decay = np.exp(-np.outer(dt, lam))
    x = np.broadcast_to(np.asarray(v[0] if x0 is None else x0, dtype=float), lam.shape).copy()
    out[0] = x
    for k in range(1, n):
        d = decay[k - 1]
        x = d * x + (1.0 - d) * v[k - 1]
        out[k] = x
    return out


def creep_output(v: np.ndarray, states: np.ndarray, densities: np.ndarray, a: float) -> np.ndarray:
    """Eq. 3.14: ``y_c = sum_i c_i x_i(k) + a v(k)``."""
    return states @ np.asarray(densities, dtype=float) + a * np.asarray(v, dtype=float)
