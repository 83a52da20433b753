"""Rigs of the second generator and its quasi-static TSA, solved through the helix angle.

Units: mm, turns, g (N for forces), ohm, s.

A twisted pair is a double helix: with the strings' stretched length ``l`` (a linear
spring, ``l = L0 (1 + F / K)``), helix angle ``a`` and bundle radius ``r`` the axial length
is ``X = l cos a`` and ``l sin a = 2 pi n r``; the bundle thickens as it shortens at constant
volume, ``r = r0 sqrt(L0 / X)``. Eliminating ``X`` and ``r``:
``sin a sqrt(cos a) = 2 pi n r0 sqrt(L0) / l^(3/2)``, whose left side rises from 0 to its
maximum at ``tan^2 a = 2`` (fully twisted); it is solved by bisection on ``a`` (60 halvings),
and beyond the maximum the pair stays fully twisted. The resistance is referred to the
untwisted pair under the first load (``R_ref`` at ``X_ref``): ``R = R_ref + s (X - X_ref) -
c |n|``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GRAVITY = 9.80665
A_MAX = float(np.arctan(np.sqrt(2.0)))


@dataclass(frozen=True)
class Rig:
    name: str
    untwisted_mm: float
    radius_mm: float
    stiffness_N: float
    r_ref_ohm: float             # resistance of the untwisted pair under the first load
    ohm_per_mm: float
    contact_ohm_per_turn: float
    rate_hz: float
    loads_g: tuple[float, ...]
    length_noise_mm: float
    resistance_noise_ohm: float
    length_step_mm: float = 0.0
    resistance_step_ohm: float = 0.0
    top_fraction: float = 0.75   # highest twist as a fraction of the fully twisted one


RIGS = {
    "long-6ply-20ohm": Rig("long-6ply-20ohm", 480.0, 0.62, 55.0, 19.5, 0.052, 0.006, 4.0, (300.0, 420.0), 0.06, 0.004,
                           length_step_mm=0.05),
    "short-2ply-1ohm": Rig("short-2ply-1ohm", 125.0, 0.33, 14.0, 1.45, 0.008, 0.0004, 20.0, (150.0, 90.0), 0.02,
                           0.0004, resistance_step_ohm=5e-5),
    "mid-scp-uhmwpe": Rig("mid-scp-uhmwpe", 305.0, 0.47, 210.0, 8.2, 0.021, 0.0015, 8.0, (600.0, 480.0, 700.0), 0.04,
                          0.0015),
}


def stretched_mm(rig: Rig, load_g: np.ndarray) -> np.ndarray:
    return rig.untwisted_mm * (1.0 + np.asarray(load_g) * GRAVITY / 1000.0 / rig.stiffness_N)


def helix_length_mm(rig: Rig, turns: np.ndarray, load_g: np.ndarray) -> np.ndarray:
    """Axial length X of the pair (module docstring), element by element."""
    ell = stretched_mm(rig, load_g) * np.ones_like(np.asarray(turns, float))
    target = 2.0 * np.pi * np.abs(np.asarray(turns, float)) * rig.radius_mm * np.sqrt(rig.untwisted_mm) / ell ** 1.5
    lo, hi = np.zeros_like(ell), np.full_like(ell, A_MAX)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        below = np.sin(mid) * np.sqrt(np.cos(mid)) < target
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return ell * np.cos(0.5 * (lo + hi))


def full_twist_turns(rig: Rig, load_g: float) -> float:
    """Twist at which the pair is fully twisted under ``load_g``."""
    ell = float(stretched_mm(rig, load_g))
    peak = np.sin(A_MAX) * np.sqrt(np.cos(A_MAX))
    return float(peak * ell ** 1.5 / (2.0 * np.pi * rig.radius_mm * np.sqrt(rig.untwisted_mm)))


def resistance_ohm(rig: Rig, x_mm: np.ndarray, turns: np.ndarray) -> np.ndarray:
    x_ref = float(stretched_mm(rig, rig.loads_g[0]))
    return rig.r_ref_ohm + rig.ohm_per_mm * (x_mm - x_ref) - rig.contact_ohm_per_turn * np.abs(turns)


def load_torque_Nm(rig: Rig, turns: np.ndarray, load_g: np.ndarray) -> np.ndarray:
    """Motor torque that holds the load: F dX/dtheta (numerical derivative of the helix)."""
    dn = 1e-3
    dx = helix_length_mm(rig, np.abs(turns) + dn, load_g) - helix_length_mm(rig, np.abs(turns), load_g)
    return np.asarray(load_g) * GRAVITY / 1000.0 * np.abs(dx) / 1000.0 / (2.0 * np.pi * dn)
