"""Kinematics of a stiff twisted string actuator, thesis eqs. 4.4-4.7, 4.18, 4.21-4.22.

Units: SI throughout: lengths and radii in m, twist angle T in rad (2 pi per motor
revolution), rates in m/s and rad/s; h(T) in m/rad.

Contract: ``X = sqrt(X0^2 - T^2 w^2)`` (eq. 4.4). With radius growth ``w = w0 sqrt(L0/L)``
(eq. 4.5) the length is found as in the thesis by the recursion of eqs. 4.6-4.7 along a
twist history (:func:`length_with_radius_growth`: ``L[k]`` uses ``w[k-1]``, ``w[0] = w0``),
or for one twist as the converged fixed point of the same map
(:func:`length_fixed_point`). Twists beyond full contraction (``T w >= L0``) give NaN.
"""

from __future__ import annotations

import numpy as np

TWO_PI = 2.0 * np.pi


def turns_to_rad(turns: np.ndarray | float) -> np.ndarray:
    """Motor revolutions -> twist angle (rad)."""
    return np.asarray(turns, dtype=float) * TWO_PI


def length_constant_radius(twist_rad: np.ndarray | float, l0_m: float, w_m: float) -> np.ndarray:
    """Eq. 4.4 with a constant radius ``w`` (m); NaN past full contraction."""
    t = np.asarray(twist_rad, dtype=float)
    arg = l0_m * l0_m - t * t * w_m * w_m
    return np.where(arg > 0, np.sqrt(np.maximum(arg, 0.0)), np.nan)


def length_with_radius_growth(twist_rad: np.ndarray, l0_m: float, w0_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 4.6-4.7 along a twist history: returns (L[k], w[k]) in m."""
    t = np.atleast_1d(np.asarray(twist_rad, dtype=float))
    lengths = np.empty(len(t))
    radii = np.empty(len(t))
    w = w0_m
    for k, tk in enumerate(t):
        arg = l0_m * l0_m - tk * tk * w * w
        if not arg > 0:
            lengths[k:] = np.nan
            radii[k:] = np.nan
            break
        lk = np.sqrt(arg)
        w = w0_m * np.sqrt(l0_m / lk)
        lengths[k], radii[k] = lk, w
    return lengths, radii


def length_fixed_point(twist_rad: float, l0_m: float, w0_m: float, tol_m: float = 1e-15,
                       max_iter: int = 10_000) -> tuple[float, float]:
    """The self-consistent (L, w) with ``L = sqrt(L0^2 - T^2 w^2)``, ``w = w0 sqrt(L0/L)`` (m)."""
    w = w0_m
    lk = l0_m
    for _ in range(max_iter):
        arg = l0_m * l0_m - twist_rad * twist_rad * w * w
        if not arg > 0:
            return float("nan"), float("nan")
        new = float(np.sqrt(arg))
        w = w0_m * np.sqrt(l0_m / new)
        if abs(new - lk) < tol_m:
            return new, float(w)
        lk = new
    raise RuntimeError("radius-growth fixed point did not converge (twist near full contraction)")


def reduction_ratio(twist_rad: np.ndarray | float, l0_m: float, w_m: np.ndarray | float) -> np.ndarray:
    """Eq. 4.18: generalized reduction ratio ``h(T) = w^2 T / sqrt(L0^2 - T^2 w^2)`` (m/rad), |dL/dT|."""
    t = np.asarray(twist_rad, dtype=float)
    w = np.asarray(w_m, dtype=float)
    return w * w * t / np.sqrt(l0_m * l0_m - t * t * w * w)


def reduction_ratio_linearised(twist_rad: np.ndarray | float, l0_m: float, w_m: np.ndarray | float) -> np.ndarray:
    """Eq. 4.21-4.22: ``h~(T) = w^2 T / L0`` (m/rad), the Maclaurin approximation of h."""
    w = np.asarray(w_m, dtype=float)
    return w * w * np.asarray(twist_rad, dtype=float) / l0_m
