"""Rig constants and the quasi-static TSA of the independent generator.

Units: lengths and radii in mm, twist in motor turns, load in g (force in N), resistance
in ohm, time in s, torque in N m.

The strings stretch under the hanging mass as a linear spring normalised to length
(``L = L0 (1 + F / K)``); twisting shortens the pair with a radius that grows as the
strings bunch up (constant volume: ``r^2 X = r0^2 L0``), so ``X^2 = L^2 - (2 pi n r)^2``
becomes ``X^3 - L^2 X + (2 pi n)^2 r0^2 L0 = 0``. The largest root is found by Newton
iteration from ``X = L`` (the cubic is convex there, so the iteration descends
monotonically onto the root); past the fully twisted length ``L / sqrt(3)`` the length
stays there. The resistance is linear in length with a contact term that lowers it as
the strings twist together.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

G = 9.80665


@dataclass(frozen=True)
class Rig:
    """One string pair on one bench (all plausible thesis-range strings, none the library default)."""

    name: str
    untwisted_mm: float          # L0
    radius_mm: float             # r0
    stiffness_N: float           # K, normalised stiffness
    r0_ohm: float                # resistance at L0, untwisted
    ohm_per_mm: float            # dR/dX
    contact_ohm_per_turn: float  # resistance drop per turn of twist
    rate_hz: float               # sampling rate
    loads_g: tuple[float, ...]   # hanging masses used by the walk (first one first)
    length_noise_mm: float
    resistance_noise_ohm: float
    length_step_mm: float = 0.0       # position quantisation (0: none)
    resistance_step_ohm: float = 0.0  # resistance quantisation (0: none)
    reach: float = 0.8                # the walk reaches this fraction of the full twist
    noise_ar: float = 0.0             # lag-1 correlation of the sensor noise (0: white)

    def with_(self, **kw) -> "Rig":
        return replace(self, **kw)


#: Rigs unlike the library's default (248 mm, 0.51 mm, 31.88 N, 5 ohm, 10 Hz, 500 g).
RIGS: dict[str, Rig] = {
    "long-8ply": Rig("long-8ply", 360.0, 0.62, 58.0, 9.4, 0.021, 0.0021, 25.0, (800.0, 650.0, 900.0),
                     0.03, 0.002, 0.05, 1e-4),
    "short-3ply": Rig("short-3ply", 172.0, 0.34, 24.6, 3.3, 0.0075, 0.0004, 5.0, (180.0, 120.0, 220.0),
                      0.08, 0.0006, 0.1, 0.0),
    "uhmwpe-scheme1": Rig("uhmwpe-scheme1", 305.0, 0.43, 1800.0, 6.6, 0.012, 0.0012, 10.0, (450.0, 550.0),
                          0.05, 0.001, 0.0, 1e-5),
    "mid-4ply-12ohm": Rig("mid-4ply-12ohm", 226.0, 0.47, 33.0, 11.8, 0.034, 0.0035, 10.0, (300.0, 380.0, 250.0),
                          0.04, 0.003, 0.02, 2e-4),
}


def stretched_mm(rig: Rig, load_g: np.ndarray) -> np.ndarray:
    """Untwisted length under the hanging mass (mm)."""
    return rig.untwisted_mm * (1.0 + np.asarray(load_g, float) * G * 1e-3 / rig.stiffness_N)


def tsa_length_mm(rig: Rig, turns: np.ndarray, load_g: np.ndarray, untwisted_mm: float | np.ndarray | None = None
                  ) -> np.ndarray:
    """TSA length X at ``turns`` under ``load_g`` (vectorised Newton on the cubic, clamped at L/sqrt(3))."""
    turns = np.asarray(turns, float)
    big_l = np.broadcast_to(stretched_mm(rig, load_g), turns.shape).astype(float)
    if untwisted_mm is not None:
        big_l = big_l * np.asarray(untwisted_mm, float) / rig.untwisted_mm
    c = (2.0 * np.pi * turns) ** 2 * rig.radius_mm ** 2 * rig.untwisted_mm
    floor = big_l / np.sqrt(3.0)
    x = big_l.copy()
    for _ in range(80):
        f = x ** 3 - big_l ** 2 * x + c
        fp = 3.0 * x ** 2 - big_l ** 2
        step = np.where(fp > 1e-9, f / np.maximum(fp, 1e-9), 0.0)
        x = np.maximum(x - step, floor)
        if np.all(np.abs(step) < 1e-10):
            break
    return x


def full_twist_turns(rig: Rig, load_g: float) -> float:
    """Twist at which the pair is fully twisted (X = L / sqrt(3))."""
    big_l = float(stretched_mm(rig, load_g))
    c_max = 2.0 * big_l ** 3 / (3.0 * np.sqrt(3.0))
    return float(np.sqrt(c_max / (rig.radius_mm ** 2 * rig.untwisted_mm)) / (2.0 * np.pi))


def load_torque_Nm(rig: Rig, turns: np.ndarray, load_g: np.ndarray) -> np.ndarray:
    """Torque the hanging load puts on the motor: F dX/dtheta with dX/dtheta = theta r^2 / X."""
    x = tsa_length_mm(rig, turns, load_g)
    theta = 2.0 * np.pi * np.abs(np.asarray(turns, float))
    r2 = rig.radius_mm ** 2 * rig.untwisted_mm / x
    return np.asarray(load_g, float) * G * 1e-3 * theta * r2 / x * 1e-3


def resistance_ohm(rig: Rig, length_mm: np.ndarray, turns: np.ndarray) -> np.ndarray:
    """Quasi-static resistance: linear in length, lowered by contact as the strings twist."""
    return rig.r0_ohm + rig.ohm_per_mm * (np.asarray(length_mm) - rig.untwisted_mm) \
        - rig.contact_ohm_per_turn * np.abs(np.asarray(turns))
