"""Discretised Preisach operator (thesis eqs. 3.1, 3.2, 3.7) identified by non-negative least squares.

Units: the input ``u`` and output ``y`` keep the caller's units (turn, V or ohm in;
mm out); weights are in output units per relay, the offset in output units.

Contract: the input range ``[u_min, u_max]`` is cut into ``M`` levels of width
``du``; level centres ``c_k = u_min + (k + 1/2) du``, k = 0..M-1. Relay (i, j) with
``j <= i`` switches up when ``u >= c_i`` and down when ``u < c_j``, giving the
M (M + 1) / 2 relays of the triangular grid (``i + j <= M + 1`` in the thesis's
indexing). Relays start down (negative saturation). The output is
``y = offset + sign * sum_ij mu_ij s_ij(u history)``, ``s_ij`` in {0, 1}, ``mu_ij >= 0``.
``sign`` (+1 or -1) lets a falling characteristic (length vs twist) keep non-negative
weights; :meth:`PreisachModel.fit` picks it from the data. Relay states are computed
for all samples at once from "last time above level" / "last time below level"
indices (no loop over samples), so identification on 10,000 samples with M = 20 costs
a small fraction of a second.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls


def _levels(u_min: float, u_max: float, m: int) -> np.ndarray:
    du = (u_max - u_min) / m
    return u_min + (np.arange(m) + 0.5) * du


def relay_states(u: np.ndarray, u_min: float, u_max: float, m: int) -> np.ndarray:
    """(N, M(M+1)/2) array of 0/1 relay states after each sample of ``u``.

    Relay order: (i, j) for i in 0..M-1, j in 0..i (row-major over the lower triangle).
    """
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or len(u) == 0:
        raise ValueError("the Preisach input must be a non-empty 1-D array")
    if not np.all(np.isfinite(u)):
        raise ValueError("the Preisach input contains NaN or inf")
    c = _levels(u_min, u_max, m)
    idx = np.arange(len(u))[:, None]
    last_up = np.maximum.accumulate(np.where(u[:, None] >= c[None, :], idx, -1), axis=0)
    last_down = np.maximum.accumulate(np.where(u[:, None] < c[None, :], idx, -1), axis=0)
    ii, jj = np.tril_indices(m)
    return (last_up[:, ii] > last_down[:, jj]).astype(np.float64)


@dataclass(frozen=True)
class PreisachModel:
    """Identified discretised Preisach model; ``weights`` in relay order of :func:`relay_states`."""

    levels: int
    u_min: float
    u_max: float
    weights: tuple[float, ...]
    offset: float
    sign: float

    @classmethod
    def fit(cls, u: np.ndarray | list[np.ndarray], y: np.ndarray | list[np.ndarray], levels: int = 20,
            sign: float | None = None) -> "PreisachModel":
        """Identify the weights (scipy.optimize.nnls) and the offset on one input/output history
        or a list of them (each history starts from relays down).

        ``sign=None`` takes the sign of the least-squares slope of y on u (a falling
        characteristic gets -1). NaN outputs are skipped (their inputs still drive the relays).
        """
        us = [np.asarray(a, dtype=float) for a in (u if isinstance(u, list) else [u])]
        ys = [np.asarray(a, dtype=float) for a in (y if isinstance(y, list) else [y])]
        if len(us) != len(ys) or any(a.shape != b.shape for a, b in zip(us, ys)):
            raise ValueError("input and output histories differ in number or length")
        u = np.concatenate(us)
        y = np.concatenate(ys)
        if levels < 1:
            raise ValueError(f"levels must be >= 1, got {levels}")
        u_min, u_max = float(np.min(u)), float(np.max(u))
        if not u_max > u_min:
            raise ValueError("the Preisach input does not vary; nothing to identify")
        pad = 1e-9 * (u_max - u_min)
        u_min, u_max = u_min - pad, u_max + pad
        states = np.vstack([relay_states(a, u_min, u_max, levels) for a in us])
        ok = np.isfinite(y)
        a = states[ok]
        yy = y[ok]
        # the offset is free in sign: columns +1 and -1 with non-negative coefficients
        ones = np.ones((len(yy), 1))
        design = np.hstack([a, ones, -ones])
        if sign is None:
            s = 1.0 if np.polyfit(u[ok], yy, 1)[0] >= 0 else -1.0
        else:
            s = float(sign)
        coef, _ = nnls(design * np.r_[np.full(a.shape[1], s), 1.0, 1.0], yy, maxiter=50 * design.shape[1])
        nrel = a.shape[1]
        return cls(levels, u_min, u_max, tuple(float(w) for w in coef[:nrel]), float(coef[nrel] - coef[nrel + 1]), s)

    def predict(self, u: np.ndarray) -> np.ndarray:
        """Model output for the input history ``u`` (relays start down)."""
        states = relay_states(np.clip(np.asarray(u, dtype=float), self.u_min, self.u_max), self.u_min, self.u_max,
                              self.levels)
        return self.offset + self.sign * states @ np.asarray(self.weights)

    def weight_matrix(self) -> np.ndarray:
        """(M, M) lower-triangular array of weights, [i, j] = relay up at level i, down at level j."""
        w = np.full((self.levels, self.levels), np.nan)
        ii, jj = np.tril_indices(self.levels)
        w[ii, jj] = self.weights
        return w
