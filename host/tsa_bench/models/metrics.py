"""Error metrics of the thesis: E_aver and sigma (eqs. 3.5-3.6) and the relative errors of eq. 3.21.

Units: the absolute metrics carry the unit of the compared quantity (mm, ohm, deg, ...);
the relative ones are in percent of the measured value.

Contract: every function takes equal-length ``measured`` and ``predicted`` arrays,
ignores pairs where either is NaN and raises ValueError when nothing is left.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


def _pairs(measured: np.ndarray, predicted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    if m.shape != p.shape:
        raise ValueError(f"measured and predicted differ in shape: {m.shape} vs {p.shape}")
    ok = np.isfinite(m) & np.isfinite(p)
    if not ok.any():
        raise ValueError("no finite (measured, predicted) pairs to compare")
    return m[ok], p[ok]


def e_aver(measured: np.ndarray, predicted: np.ndarray) -> float:
    """Eq. 3.5: mean absolute error (unit of the data)."""
    m, p = _pairs(measured, predicted)
    return float(np.mean(np.abs(p - m)))


def sigma(measured: np.ndarray, predicted: np.ndarray) -> float:
    """Eq. 3.6: standard deviation (N - 1) of the absolute errors about E_aver (unit of the data).

    Zero for a single pair.
    """
    m, p = _pairs(measured, predicted)
    e = np.abs(p - m)
    if len(e) < 2:
        return 0.0
    return float(np.sqrt(np.sum((e - e.mean()) ** 2) / (len(e) - 1)))


def relative_errors_percent(measured: np.ndarray, predicted: np.ndarray) -> np.ndarray:
    """Eq. 3.21: ``|model - exp| / exp * 100`` per point (%); measured values must be nonzero."""
    m, p = _pairs(measured, predicted)
    if np.any(m == 0):
        raise ValueError("eq. 3.21 divides by the measured value, which is zero somewhere")
    return np.abs(p - m) / np.abs(m) * 100.0


@dataclass(frozen=True)
class Metrics:
    """Summary of one comparison: ``unit`` of the data; ``n`` points.

    ``e_aver`` and ``sigma`` (eqs. 3.5-3.6) and ``max_abs`` in ``unit``;
    ``mean_percent`` and ``max_percent`` are eq. 3.21 (percent of the measured value),
    over the points whose measured value is not zero (NaN when all are zero, e.g. a
    strain that starts at 0).
    """

    n: int
    unit: str
    e_aver: float
    sigma: float
    max_abs: float
    mean_percent: float
    max_percent: float

    def as_dict(self) -> dict[str, float | int | str]:
        return asdict(self)


def compare(measured: np.ndarray, predicted: np.ndarray, unit: str) -> Metrics:
    """All metrics of :class:`Metrics` for one measured/predicted pair of arrays."""
    m, p = _pairs(measured, predicted)
    nonzero = m != 0
    rel = relative_errors_percent(m[nonzero], p[nonzero]) if nonzero.any() else np.array([np.nan])
    e = np.abs(p - m)
    return Metrics(n=int(len(m)), unit=unit, e_aver=e_aver(m, p), sigma=sigma(m, p), max_abs=float(e.max()),
                   mean_percent=float(rel.mean()), max_percent=float(rel.max()))
