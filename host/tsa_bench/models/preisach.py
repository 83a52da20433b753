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
block by block from "last time above level" / "last time below level" indices (no
loop over samples), and the least squares runs on one weighted row per distinct relay
state (equal minimiser), so identification is linear in time and flat in memory in the number
of samples (10,000 samples with M = 20: a small fraction of a second).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls


def _levels(u_min: float, u_max: float, m: int) -> np.ndarray:
    du = (u_max - u_min) / m
    return u_min + (np.arange(m) + 0.5) * du


#: Samples per block when relay states are built block by block (memory bounded in N).
BLOCK = 8192


def _check_input(u: np.ndarray) -> np.ndarray:
    u = np.asarray(u, dtype=float)
    if u.ndim != 1 or len(u) == 0:
        raise ValueError("the Preisach input must be a non-empty 1-D array")
    if not np.all(np.isfinite(u)):
        raise ValueError("the Preisach input contains NaN or inf")
    return u


def relay_state_blocks(u: np.ndarray, u_min: float, u_max: float, m: int, block: int = BLOCK):
    """The rows of :func:`relay_states` in blocks of at most ``block`` samples: yields
    (first sample index, (n, M(M+1)/2) float array); memory bounded by the block."""
    u = _check_input(u)
    c = _levels(u_min, u_max, m)
    ii, jj = np.tril_indices(m)
    up_carry = np.full(m, -1, dtype=np.int64)    # last index at or above each level so far
    down_carry = np.full(m, -1, dtype=np.int64)  # last index below it
    for start in range(0, len(u), block):
        x = u[start:start + block]
        idx = np.arange(start, start + len(x))[:, None]
        last_up = np.maximum.accumulate(np.where(x[:, None] >= c[None, :], idx, -1), axis=0)
        last_down = np.maximum.accumulate(np.where(x[:, None] < c[None, :], idx, -1), axis=0)
        np.maximum(last_up, up_carry, out=last_up)
        np.maximum(last_down, down_carry, out=last_down)
        up_carry, down_carry = last_up[-1], last_down[-1]
        yield start, (last_up[:, ii] > last_down[:, jj]).astype(np.float64)


def relay_states(u: np.ndarray, u_min: float, u_max: float, m: int) -> np.ndarray:
    """(N, M(M+1)/2) array of 0/1 relay states after each sample of ``u``.

    Relay order: (i, j) for i in 0..M-1, j in 0..i (row-major over the lower triangle).
    """
    u = _check_input(u)
    return np.vstack([b for _, b in relay_state_blocks(u, u_min, u_max, m)])


class _StateSums:
    """Count and output sum per distinct relay state (rows of the design that repeat).

    Samples with the same relay states differ only in their output, so the squared error
    over them is ``n * (a x - mean y)^2`` plus a constant: least squares on one row per
    distinct state, weighted by ``sqrt(n)``, has the same minimiser. The number of
    distinct states is set by the level crossings, not by the number of samples.
    """

    def __init__(self) -> None:
        self.sums: dict[bytes, list[float]] = {}
        self.width = 0

    def add(self, states: np.ndarray, y: np.ndarray) -> None:
        keep = np.isfinite(y)
        if not keep.any():
            return
        self.width = states.shape[1]
        packed = np.packbits(states[keep].astype(bool), axis=1)
        keys, inverse = np.unique(packed, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        counts = np.bincount(inverse, minlength=len(keys))
        ysum = np.bincount(inverse, weights=y[keep], minlength=len(keys))
        for key, n, total in zip(keys, counts, ysum):
            k = key.tobytes()
            acc = self.sums.get(k)
            if acc is None:
                self.sums[k] = [float(n), float(total)]
            else:
                acc[0] += n
                acc[1] += total

    def rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distinct states as 0/1 rows, count of each, mean output of each)."""
        keys = np.frombuffer(b"".join(self.sums), dtype=np.uint8).reshape(len(self.sums), -1)
        states = np.unpackbits(keys, axis=1, count=self.width).astype(np.float64)
        acc = np.array(list(self.sums.values()))
        return states, acc[:, 0], acc[:, 1] / acc[:, 0]


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
        ok = np.isfinite(y)
        if sign is None:
            s = 1.0 if np.polyfit(u[ok], y[ok], 1)[0] >= 0 else -1.0
        else:
            s = float(sign)
        # Least squares on the design [sign * relay states, +1, -1] (the offset is free in
        # sign: two columns with non-negative coefficients), one weighted row per distinct
        # relay state (_StateSums): time linear and memory flat in the samples.
        sums = _StateSums()
        for ua, ya in zip(us, ys):
            for start, states in relay_state_blocks(ua, u_min, u_max, levels):
                sums.add(states, ya[start:start + len(states)])
        if not sums.sums:
            raise ValueError("the Preisach output has no finite value; nothing to identify")
        states, counts, means = sums.rows()
        w = np.sqrt(counts)[:, None]
        design = np.hstack([states * s, np.ones((len(states), 1)), -np.ones((len(states), 1))]) * w
        nrel = levels * (levels + 1) // 2
        coef, _ = nnls(design, means * w[:, 0], maxiter=50 * (nrel + 2))
        return cls(levels, u_min, u_max, tuple(float(w) for w in coef[:nrel]), float(coef[nrel] - coef[nrel + 1]), s)

    def predict(self, u: np.ndarray) -> np.ndarray:
        """Model output for the input history ``u`` (relays start down)."""
        u = np.clip(np.asarray(u, dtype=float), self.u_min, self.u_max)
        w = np.asarray(self.weights)
        out = np.empty(len(u)) if np.ndim(u) == 1 else None
        if out is None or len(u) == 0:
            _check_input(u)
        for start, states in relay_state_blocks(u, self.u_min, self.u_max, self.levels):  # memory flat in N
            out[start:start + len(states)] = self.offset + self.sign * states @ w
        return out

    def weight_matrix(self) -> np.ndarray:
        """(M, M) lower-triangular array of weights, [i, j] = relay up at level i, down at level j."""
        w = np.full((self.levels, self.levels), np.nan)
        ii, jj = np.tril_indices(self.levels)
        w[ii, jj] = self.weights
        return w
