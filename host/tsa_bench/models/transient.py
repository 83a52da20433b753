"""Transient resistance decay after each motor stop, thesis eq. 3.9.

Units: time in s, b1 and b2 in ohm (or the output unit), eps = 1e-5 s.

Contract: ``y_t(t) = b1 ln^2(t - t0 + eps) + b2 ln(t - t0 + eps)`` with ``t0`` the start
of the current hold (first sample with the motor stopped after it moved) and
``b1, b2 <= 0``; it is zero at ``t - t0 = 1 s - eps`` and restarts at every stop.
While the motor turns, and before the first stop, ``y_t = 0``. :func:`hold_curves`
cuts a run into its transient curves; :func:`fit_decay` identifies b1, b2 shared by all
curves plus one steady value ``y_s`` per curve (bounded linear least squares).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

EPS_S = 1e-5


@dataclass(frozen=True)
class HoldCurve:
    """Samples ``start:stop`` (slice into the run) of one hold; ``t0_s`` the stop instant."""

    start: int
    stop: int
    t0_s: float


def hold_curves(t_s: np.ndarray, motor_moving: np.ndarray) -> list[HoldCurve]:
    """Every maximal run of stopped samples that follows a moving sample, in time order."""
    moving = np.asarray(motor_moving).astype(bool)
    t = np.asarray(t_s, dtype=float)
    curves = []
    n = len(moving)
    k = 1
    while k < n:
        if not moving[k] and moving[k - 1]:
            j = k
            while j < n and not moving[j]:
                j += 1
            curves.append(HoldCurve(k, j, float(t[k])))
            k = j
        else:
            k += 1
    return curves


def decay(dt_s: np.ndarray, b1: float, b2: float, eps_s: float = EPS_S) -> np.ndarray:
    """Eq. 3.9's ``y_t`` for times since the stop ``dt_s >= 0``."""
    lg = np.log(np.asarray(dt_s, dtype=float) + eps_s)
    return b1 * lg * lg + b2 * lg


def decay_series(t_s: np.ndarray, motor_moving: np.ndarray, b1: float, b2: float,
                 eps_s: float = EPS_S) -> np.ndarray:
    """``y_t`` at every sample of a run (0 while moving and before the first stop)."""
    t = np.asarray(t_s, dtype=float)
    out = np.zeros(len(t))
    for c in hold_curves(t, motor_moving):
        out[c.start:c.stop] = decay(t[c.start:c.stop] - c.t0_s, b1, b2, eps_s)
    return out


#: Above this many matrix entries (samples x (curves + 2)) the curve levels are taken out
#: first; below, the one-column-per-curve problem is solved as it stands.
DENSE_MAX_ENTRIES = 4_000_000


def fit_decay(curves: list[tuple[np.ndarray, np.ndarray]], eps_s: float = EPS_S) -> tuple[float, float, np.ndarray]:
    """Fit shared ``b1, b2 <= 0`` and per-curve ``y_s`` to curves ``(dt_s, y)``; NaNs skipped.

    Returns ``(b1, b2, y_s)`` with ``y_s`` one value per curve (NaN for a curve with no data).
    A long run (thousands of holds) would make the one-column-per-curve matrix grow as
    samples x curves; there the unbounded levels are taken out first (same solution, time
    and memory linear in samples). Small problems keep the direct form, whose results the
    calibrated presets and thesis comparisons were made with (the downstream nonconvex
    fits notice differences of 1e-12 in the levels).
    """
    if not curves:
        raise ValueError("no transient (hold) curves to fit")
    m = len(curves)
    lgs, ys, ids = [], [], []
    for i, (dt, y) in enumerate(curves):
        dt = np.asarray(dt, dtype=float)
        y = np.asarray(y, dtype=float)
        ok = np.isfinite(y)
        lgs.append(np.log(dt[ok] + eps_s))
        ys.append(y[ok])
        ids.append(np.full(int(ok.sum()), i))
    lg, b, gid = np.concatenate(lgs), np.concatenate(ys), np.concatenate(ids)
    if len(b) < m + 2:
        raise ValueError(f"too few samples ({len(b)}) on {m} hold curves to fit the transient decay")
    solve = _decay_dense if len(b) * (m + 2) <= DENSE_MAX_ENTRIES else _decay_centred
    b1, b2, level = solve(lg, b, gid, m)
    level[np.bincount(gid, minlength=m) == 0] = np.nan
    return b1, b2, level


def _decay_dense(lg: np.ndarray, y: np.ndarray, gid: np.ndarray, m: int) -> tuple[float, float, np.ndarray]:
    """Columns ``lg^2, lg`` and one level column per curve; bounded ``b1, b2 <= 0``."""
    a = np.zeros((len(y), m + 2))
    a[:, 0], a[:, 1] = lg * lg, lg
    a[np.arange(len(y)), 2 + gid] = 1.0
    hi = np.r_[0.0, 0.0, np.full(m, np.inf)]
    x = lsq_linear(a, y, bounds=(np.full(m + 2, -np.inf), hi), method="bvls").x
    return float(x[0]), float(x[1]), x[2:].copy()


def _decay_centred(lg: np.ndarray, y: np.ndarray, gid: np.ndarray, m: int) -> tuple[float, float, np.ndarray]:
    """The same problem with each curve's mean removed from data and regressors (the
    levels are unbounded, so this is exact), then the levels from the means."""
    safe = np.maximum(np.bincount(gid, minlength=m), 1)

    def centred(v: np.ndarray) -> np.ndarray:
        return v - (np.bincount(gid, weights=v, minlength=m) / safe)[gid]

    a = np.column_stack([centred(lg * lg), centred(lg)])
    sol = lsq_linear(a, centred(y), bounds=([-np.inf, -np.inf], [0.0, 0.0]), method="bvls")
    b1, b2 = float(sol.x[0]), float(sol.x[1])
    return b1, b2, np.bincount(gid, weights=y - b1 * lg * lg - b2 * lg, minlength=m) / safe
