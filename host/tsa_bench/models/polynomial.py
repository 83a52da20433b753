"""Third-order polynomial model of thesis eq. 3.4: ``y = sum_i p_i q^i``.

Units: ``p_i`` in (output unit) / (input unit)^i; input and output units are recorded
by the caller (e.g. turn -> mm, V -> mm, ohm -> mm).

Contract: :meth:`PolynomialModel.fit` is an ordinary least-squares fit (numpy.polyfit,
the thesis used MATLAB polyfit) on finite pairs; ``coefficients[i]`` multiplies q^i.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PolynomialModel:
    """``coefficients[i]`` = p_i of eq. 3.4 (lowest order first)."""

    coefficients: tuple[float, ...]

    @property
    def order(self) -> int:
        return len(self.coefficients) - 1

    @classmethod
    def fit(cls, q: np.ndarray, y: np.ndarray, order: int = 3) -> "PolynomialModel":
        """Least-squares fit of order ``order`` (3 in the thesis) to finite (q, y) pairs."""
        q = np.asarray(q, dtype=float)
        y = np.asarray(y, dtype=float)
        ok = np.isfinite(q) & np.isfinite(y)
        if ok.sum() <= order:
            raise ValueError(f"a polynomial of order {order} needs more than {order} finite samples, got {ok.sum()}")
        high_first = np.polyfit(q[ok], y[ok], order)
        return cls(tuple(float(c) for c in high_first[::-1]))

    def predict(self, q: np.ndarray) -> np.ndarray:
        """Eq. 3.4 evaluated at ``q`` (output unit)."""
        return np.polynomial.polynomial.polyval(np.asarray(q, dtype=float), self.coefficients)
