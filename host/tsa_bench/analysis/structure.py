"""Is a residual only sensor noise? If not, what does it follow?

Units: residuals in the output's units; noise from :mod:`tsa_bench.analysis.noise`.

Contract: :func:`structure_test` compares a residual with the data's noise model. The
residual is cut into contiguous windows of ``w`` samples (about 2 s); if it were the
noise alone, the mean square of the window means would be ``k s_w^2 / w`` (``s_w^2`` the
within-window variance, ``k`` the noise model's window inflation, 1 for white noise) plus
the rounding bias the noise model predicts, and ``F = w * mean(m_j^2) / (k s_w^2)`` would
follow about an F(J, J(w-1)) law (J windows). The
structured RMS ``S = sqrt(mean(m_j^2) - s_w^2 / w - bias)`` estimates the part that is
not noise. The residual is **structured** when p < :data:`ALPHA` **and** S is at least the
noise model's relevance floor (half its RMS). :func:`follows` regresses the residual on
each signal basis (:mod:`tsa_bench.analysis.signals`) and keeps the signals that explain
a significant and sizeable share of the structured variance (F-test with an effective
sample size from the residual's lag-1 autocorrelation, share >= :data:`SHARE_MIN`); on a
residual longer than :data:`LEAN_N` samples through the basis' k x k normal equations (the
same least-squares fit, without the copies of the n x k basis a QR or SVD makes).
:func:`ljung_box` (whiteness, reported) and :func:`jumps` (abrupt level changes) help
describe what is left.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2, f as fdist

from tsa_bench.analysis.noise import Noise, window_length

ALPHA = 0.01
SHARE_MIN = 0.2
#: residuals longer than this (samples) are regressed through the normal equations and their
#: autocorrelation (Ljung-Box) summed directly
LEAN_N = 250_000


def _windows(res: np.ndarray, w: int) -> tuple[np.ndarray, np.ndarray]:
    ok = np.isfinite(res)
    x = res[ok]
    m = len(x) // w
    x = x[: m * w].reshape(m, w) if m else np.zeros((0, w))
    return x.mean(axis=1), x.var(axis=1, ddof=1)


def structure_test(res: np.ndarray, noise: Noise, rate_hz: float, bases: dict[str, np.ndarray] | None = None
                   ) -> dict:
    """{structured, testable, p, structured_rms, rms, excess_rms, follows, n, window}; see the module docstring."""
    ok = np.isfinite(res)
    n = int(ok.sum())
    w = window_length(rate_hz)
    if n < 4 * w or not np.isfinite(noise.rms):
        return {"structured": False, "testable": False, "p": None, "structured_rms": None, "follows": [],
                "rms": float(np.sqrt(np.mean(res[ok] ** 2))) if n else None, "n": n, "window": w}
    means, within = _windows(res, w)
    s_w2 = float(np.mean(within))
    ms = float(np.mean(means ** 2))
    j = len(means)
    fstat = w * ms / max(noise.inflation * s_w2, 1e-300)
    p = float(fdist.sf(fstat, j, j * (w - 1)))
    s_rms = float(np.sqrt(max(ms - noise.inflation * s_w2 / w - noise.bias_var, 0.0)))
    slow = bool(p < ALPHA and s_rms >= noise.floor)
    signals = _signal_fits(res, bases or {})
    fast = [f for f in signals if f["p"] < ALPHA and f["rms"] >= noise.floor]
    structured_rms = max([s_rms] + [f["rms"] for f in fast])
    fl = []
    for f in signals:
        share = min(1.0, f["rms"] ** 2 / structured_rms ** 2) if structured_rms > 0 else 0.0
        if f["p"] < ALPHA and share >= SHARE_MIN:
            fl.append({"signal": f["signal"], "share": share, "p": f["p"], "r2": f["r2"]})
    rms = float(np.sqrt(np.mean(res[ok] ** 2)))
    return {"structured": slow or bool(fast), "testable": True, "p": p, "structured_rms": structured_rms,
            "window_rms": s_rms, "rms": rms, "excess_rms": float(np.sqrt(max(rms ** 2 - noise.rms ** 2, 0.0))),
            "follows": sorted(fl, key=lambda d: -d["share"]), "n": n, "window": w, "floor": noise.floor}


def _signal_fits(res: np.ndarray, bases: dict[str, np.ndarray]) -> list[dict]:
    """OLS of the (mean-removed) residual on each signal basis: {signal, rms, p, r2}; the F-test
    uses an effective sample size from the residual's lag-1 autocorrelation."""
    ok = np.isfinite(res)
    y = res[ok] - np.mean(res[ok]) if ok.any() else res
    n = len(y)
    if n < 50 or not bases:
        return []
    lean = n > LEAN_N
    if lean:
        rho = _lag1_correlation(y) if n > 2 and np.std(y) > 0 else 0.0
    else:
        rho = float(np.corrcoef(y[1:], y[:-1])[0, 1]) if n > 2 and np.std(y) > 0 else 0.0
    rho = min(max(rho, 0.0), 0.999)
    n_eff = max(10.0, n * (1 - rho) / (1 + rho))
    tss = float(y @ y)
    out = []
    for name, b in bases.items():
        if lean:
            fit = _normal_fit(b, ok, y, owned=bool(getattr(bases, "fresh", False)))
            if fit is None or tss <= 0:
                continue
            ess, k = fit
        else:
            x = b[ok]
            x -= x.mean(axis=0)
            keep = np.std(x, axis=0) > 1e-12
            if not keep.any() or tss <= 0:
                continue
            x = x[:, keep]
            beta, *_ = np.linalg.lstsq(x, y, rcond=None)
            ess = float(np.sum((x @ beta) ** 2))
            k = x.shape[1]
        r2 = ess / tss
        fstat = (r2 / k) / max((1 - r2) / max(n_eff - k - 1, 1.0), 1e-300)
        out.append({"signal": name, "rms": float(np.sqrt(ess / n)), "r2": r2,
                    "p": float(fdist.sf(fstat, k, max(n_eff - k - 1, 1.0)))})
    return out


def _lag1_correlation(y: np.ndarray) -> float:
    """Pearson correlation of ``y[1:]`` with ``y[:-1]`` without stacking copies of them."""
    a, b = y[1:], y[:-1]
    m = len(a)
    ma, mb = float(a.sum()) / m, float(b.sum()) / m
    sab = float(a @ b) - m * ma * mb
    saa, sbb = float(a @ a) - m * ma * ma, float(b @ b) - m * mb * mb
    return sab / np.sqrt(saa * sbb) if saa > 0 and sbb > 0 else 0.0


def _normal_fit(b: np.ndarray, ok: np.ndarray, y: np.ndarray, owned: bool) -> tuple[float, int] | None:
    """(explained sum of squares, columns used) of the least-squares fit of ``y`` on the
    mean-removed columns of ``b[ok]`` that vary, by the k x k normal equations; ``b`` is
    centred in place when ``owned`` (built for this fit alone)."""
    if ok.all():
        x = b if owned else b.copy()
    else:
        x = b[ok]
    x -= x.mean(axis=0)
    g = x.T @ x
    keep = np.sqrt(np.maximum(np.diag(g), 0.0) / len(x)) > 1e-12
    if not keep.any():
        return None
    g = g[np.ix_(keep, keep)]
    xty = (x.T @ y)[keep]
    beta = np.linalg.lstsq(g, xty, rcond=None)[0]
    return max(float(beta @ g @ beta), 0.0), int(keep.sum())


def jumps(res: np.ndarray, noise: Noise, moving: np.ndarray) -> int:
    """Abrupt level changes: first differences beyond 8 noise sigmas away from motor starts/stops."""
    d = np.diff(res)
    edge = np.r_[moving[1:] != moving[:-1]] | moving[1:] | moving[:-1]
    ok = np.isfinite(d) & ~edge
    lim = 8.0 * np.sqrt(2.0) * max(noise.sigma, noise.step / np.sqrt(12.0), 1e-12)
    return int(np.sum(np.abs(d[ok]) > lim))


def ljung_box(x: np.ndarray, lags: int = 20) -> tuple[float, float]:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 5:
        return float("nan"), float("nan")
    lags = min(lags, max(1, n // 3))
    x = x - x.mean()
    if n > LEAN_N:     # a few lags of a long series: direct sums, not a transform twice its length
        c = np.array([float(x @ x)] + [float(x[k:] @ x[:-k]) for k in range(1, lags + 1)])
    else:
        m = 1 << int(np.ceil(np.log2(2 * n)))
        f = np.fft.rfft(x, m)
        c = np.fft.irfft(f * np.conj(f), m)[: lags + 1]
    rho = c[1:] / c[0] if c[0] > 0 else np.zeros(lags)
    k = np.arange(1, lags + 1)
    q = float(n * (n + 2) * np.sum(rho ** 2 / (n - k)))
    return q, float(chi2.sf(q, lags))
