"""Play operators and the (rate-dependent) Prandtl-Ishlinskii model, thesis eqs. 3.10-3.12, 3.15, 3.17.

Units: thresholds ``r`` are in input units (mm of length for the strain-resistance
model); weights in output units per input unit; the output in output units.

Contract:

* :func:`play` is eq. 3.10, ``F(k) = max(v(k) - r, min(v(k) + r, F(k-1)))`` with the
  initial state ``F(-1) = w0`` (0 by default, as ``F_r[v](0) = f_r(v(0), 0)``).
  Thresholds may change with time (shape ``(N, K)``) for the rate-dependent model.
* :func:`generalized_play` is eq. 3.17 with envelope functions ``o_up``/``o_down``
  (eq. 3.18); with identity envelopes it equals :func:`play`.
* :class:`PIModel` is ``y = sum_n p_n F_{r_n}[v]`` (eq. 3.11) with sorted thresholds,
  ``r_0 = 0`` (the linear term) and ``p_0 > 0``, ``p_n >= 0``. :meth:`PIModel.inverse`
  is the analytic inverse, another PI model (eq. 3.15) whose thresholds and weights
  come from the initial loading curve: ``rbar_j = sum_{i<j} p_i (r_j - r_i)``,
  ``pbar_0 = 1 / p_0``, ``pbar_j = 1/s_j - 1/s_{j-1}`` with ``s_j = sum_{i<=j} p_i``; both
  start from zero states, so ``PI(PI^-1(y)) = y`` to rounding.
* :func:`rate_thresholds` is eq. 3.12, ``r_n = (n / (N - 1)) alpha ln(beta + lambda |vdot|^eps)``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Envelope = Callable[[np.ndarray], np.ndarray]


def _thresholds(r: np.ndarray, n: int) -> np.ndarray:
    r = np.asarray(r, dtype=float)
    if r.ndim == 1:
        return np.broadcast_to(r, (n, len(r)))
    if r.ndim != 2 or r.shape[0] != n:
        raise ValueError(f"thresholds must be (K,) or (N, K) with N = {n}, got {r.shape}")
    return r


def play(v: np.ndarray, r: np.ndarray, w0: np.ndarray | float = 0.0) -> np.ndarray:
    """Eq. 3.10 for K thresholds at once: returns (N, K) operator outputs."""
    v = np.asarray(v, dtype=float)
    rr = _thresholds(r, len(v))
    if np.any(rr < 0):
        raise ValueError("play-operator thresholds must be >= 0")
    out = np.empty(rr.shape)
    w = np.broadcast_to(np.asarray(w0, dtype=float), rr.shape[1:]).copy()
    for k, (vk, rk) in enumerate(zip(v, rr)):
        w = np.maximum(vk - rk, np.minimum(vk + rk, w))
        out[k] = w
    return out


def generalized_play(u: np.ndarray, r: np.ndarray, o_up: Envelope, o_down: Envelope,
                     w0: np.ndarray | float = 0.0) -> np.ndarray:
    """Eq. 3.17: rising input ``F = max(o_up(u) - r, F)``, falling ``F = min(o_down(u) + r, F)``,
    constant input keeps ``F``. The first sample is treated as rising or falling from 0. (N, K)."""
    u = np.asarray(u, dtype=float)
    rr = _thresholds(r, len(u))
    up = np.asarray(o_up(u), dtype=float)
    down = np.asarray(o_down(u), dtype=float)
    out = np.empty(rr.shape)
    w = np.broadcast_to(np.asarray(w0, dtype=float), rr.shape[1:]).copy()
    prev = 0.0
    for k in range(len(u)):
        if u[k] > prev:
            w = np.maximum(up[k] - rr[k], w)
        elif u[k] < prev:
            w = np.minimum(down[k] + rr[k], w)
        out[k] = w
        prev = u[k]
    return out


def rate_thresholds(rate: np.ndarray, n_operators: int, alpha: float, beta: float, lam: float,
                    eps: float) -> np.ndarray:
    """Eq. 3.12 spread over ``n_operators`` thresholds: (N, K), ``r_n = n/(K-1) alpha ln(beta + lambda |rate|^eps)``.

    ``rate`` in input units per s; ``alpha`` in input units; ``beta >= 1`` keeps r >= 0.
    """
    rate = np.abs(np.atleast_1d(np.asarray(rate, dtype=float)))
    scale = alpha * np.log(beta + lam * rate ** eps)
    unit = np.arange(n_operators) / max(n_operators - 1, 1)
    return np.maximum(scale[:, None] * unit[None, :], 0.0)


def inverse_parameters(thresholds: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Analytic inverse (rbar, pbar) of a PI model with sorted thresholds, r_0 = 0 (module docstring).

    ``thresholds`` may be (K,) or (N, K) (time-varying, weights fixed).
    """
    p = np.asarray(weights, dtype=float)
    r = np.asarray(thresholds, dtype=float)
    if p[0] <= 0 or np.any(p[1:] < 0):
        raise ValueError("the analytic inverse needs p_0 > 0 and p_n >= 0")
    s = np.cumsum(p)
    pbar = np.empty_like(s)
    pbar[0] = 1.0 / s[0]
    pbar[1:] = 1.0 / s[1:] - 1.0 / s[:-1]
    # rbar_j = sum_{i<=j} p_i (r_j - r_i) = r_j s_j - sum_{i<=j} p_i r_i
    rbar = r * s - np.cumsum(r * p, axis=-1)
    return rbar, pbar


@dataclass(frozen=True)
class PIModel:
    """Rate-independent PI model ``y = sum_n weights[n] F_{thresholds[n]}[v]`` (eq. 3.11)."""

    thresholds: tuple[float, ...]
    weights: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.thresholds) != len(self.weights) or not self.thresholds:
            raise ValueError("thresholds and weights must be non-empty and equally long")
        if np.any(np.diff(self.thresholds) < 0) or self.thresholds[0] < 0:
            raise ValueError("thresholds must be sorted and >= 0")

    def __call__(self, v: np.ndarray) -> np.ndarray:
        return play(v, np.asarray(self.thresholds)) @ np.asarray(self.weights)

    def inverse(self) -> "PIModel":
        """The analytic inverse PI model (requires thresholds[0] == 0, weights[0] > 0)."""
        if self.thresholds[0] != 0:
            raise ValueError("the analytic inverse needs thresholds[0] == 0 (a linear term)")
        rbar, pbar = inverse_parameters(np.asarray(self.thresholds), np.asarray(self.weights))
        return PIModel(tuple(float(x) for x in rbar), tuple(float(x) for x in pbar))
