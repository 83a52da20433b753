"""Residual whiteness and cross-correlation tests.

Units: dimensionless (correlations); inputs are any residual and signal arrays.

Contract: :func:`ljung_box` returns the Ljung-Box Q and its chi-square p-value (numpy +
scipy.stats.chi2). :func:`xcorr` returns the lag-0 correlation of a residual with a
signal and its 95 % bound from Bartlett's formula
``var(r) = (1 + 2 sum_k rho_x(k) rho_y(k)) / n``, so smooth residuals against smooth
signals are not over-flagged the way ``1.96/sqrt(n)`` would.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

#: p-value below which a residual is called structured.
ALPHA = 0.01


def acf(x: np.ndarray, nlags: int) -> np.ndarray:
    x = np.asarray(x, float) - np.mean(x)
    n = len(x)
    if n < 2:
        return np.zeros(nlags + 1)
    m = 1 << int(np.ceil(np.log2(2 * n)))
    f = np.fft.rfft(x, m)
    c = np.fft.irfft(f * np.conj(f), m)[: nlags + 1]
    return c / c[0] if c[0] > 0 else np.zeros(nlags + 1)


def ljung_box(x: np.ndarray, lags: int = 20) -> tuple[float, float]:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 3 * lags:
        lags = max(1, n // 3)
    if n < 5:
        return float("nan"), float("nan")
    rho = acf(x, lags)[1:]
    k = np.arange(1, lags + 1)
    q = float(n * (n + 2) * np.sum(rho ** 2 / (n - k)))
    return q, float(chi2.sf(q, lags))


def xcorr(res: np.ndarray, sig: np.ndarray, max_lag: int | None = None) -> tuple[float, float]:
    """(r, bound95) of a residual with a signal (finite pairs only)."""
    ok = np.isfinite(res) & np.isfinite(sig)
    x, y = res[ok], sig[ok]
    n = len(x)
    if n < 5 or np.std(x) == 0 or np.std(y) == 0:
        return 0.0, float("nan")
    r = float(np.corrcoef(x, y)[0, 1])
    lags = max_lag if max_lag is not None else min(n // 4, 500)
    rx, ry = acf(x, lags)[1:], acf(y, lags)[1:]
    var = max(1.0, 1.0 + 2.0 * float(np.sum(rx * ry))) / n
    return r, float(1.96 * np.sqrt(var))


def test_residuals(res: dict[str, np.ndarray], signals: dict[str, np.ndarray]) -> dict:
    """{output: {ljung_box_q, ljung_box_p, structured, rms, n, xcorr: {signal: (r, bound)}}}."""
    out = {}
    for o, r in res.items():
        ok = np.isfinite(r)
        q, p = ljung_box(r[ok])
        xc = {name: xcorr(r, s) for name, s in signals.items()}
        out[o] = {"ljung_box_q": q, "ljung_box_p": p, "structured": bool(p < ALPHA) if p == p else False,
                  "rms": float(np.sqrt(np.mean(r[ok] ** 2))) if ok.any() else float("nan"), "n": int(ok.sum()),
                  "xcorr": xc, "xcorr_flagged": [k for k, (c, b) in xc.items() if b == b and abs(c) > b]}
    return out
