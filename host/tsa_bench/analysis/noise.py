"""The sensor-noise model, estimated from the data alone (no model involved).

Units: each output's own (length mm, resistance ohm).

Contract: :func:`noise_model` estimates, per output, from samples where nothing is
commanded to change (motor still, heater and load constant, at least 1 s into the
pause): the quantisation step ``step`` (when the readings sit on a lattice), the white
noise standard deviation ``sigma`` from a trimmed variance of first differences (robust
to the odd jump and to slow drifts, which barely move a first difference), and the
noise-model RMS ``rms = max(marginal, step / sqrt(12))``. The noise may be correlated: an
AR(1) coefficient ``phi`` follows from the lag-1 correlation of consecutive quiet first
differences (-(1 - phi)/2; -1/2 for white noise; slow signal in the holds barely moves a
difference, so it does not pass for noise), the ``marginal`` variance is
``sigma^2 / (1 - phi)`` and ``inflation`` how much larger the variance of a window mean is
than the within-window variance over the window length (1 for white noise): the
structure test expects that much from noise alone. ``floor`` =
:data:`RELEVANT` x ``rms`` is the smallest structure worth a verdict: a systematic error
smaller than half the per-sample noise is not called structure, however many samples
make it statistically detectable (see docs/diagnose.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tsa_bench.analysis.inputs import RunInputs

#: Relevance floor as a fraction of the noise RMS.
RELEVANT = 0.5


@dataclass
class Noise:
    sigma: float
    step: float
    rms: float
    n: int
    bias_var: float = 0.0   # variance of the rounding bias that stays put while the signal does
    inflation: float = 1.0  # variance of a window mean over (within-window variance / w): 1 for white noise
    phi: float = 0.0        # AR(1) coefficient of the noise


    @property
    def floor(self) -> float:
        return RELEVANT * self.rms

    def to_json(self) -> dict:
        return {"sigma": self.sigma, "quantisation_step": self.step, "rms": self.rms, "relevance_floor": self.floor,
                "rounding_bias_rms": float(np.sqrt(self.bias_var)), "window_inflation": self.inflation, "ar1": self.phi,
                "n_differences": self.n}


def quiet_mask(r: RunInputs, settle_s: float = 1.0) -> np.ndarray:
    """Samples where nothing commanded changes: motor still >= settle_s, heater and load constant."""
    n = len(r)
    still = ~r.moving
    last_move = np.where(~still, np.arange(n), -1)
    np.maximum.accumulate(last_move, out=last_move)
    since = np.where(last_move >= 0, r.t - r.t[np.maximum(last_move, 0)], np.inf)
    change = np.r_[True, (np.diff(r.volts) != 0) | (np.abs(np.diff(r.load_g)) > 1e-9)]
    last_change = np.where(change, np.arange(n), 0)
    np.maximum.accumulate(last_change, out=last_change)
    since_c = r.t - r.t[last_change]
    return still & (since >= settle_s) & (since_c >= settle_s)


def lattice_step(x: np.ndarray) -> float:
    """The quantisation step if the values sit on a lattice (0.0 otherwise)."""
    x = x[np.isfinite(x)]
    if len(x) < 50:
        return 0.0
    d = np.abs(np.diff(x))
    d = d[d > 1e-12 * max(1.0, float(np.max(np.abs(x))))]
    if len(d) < 20:
        return 0.0
    q = float(np.quantile(d, 0.02))
    if q <= 0:
        return 0.0
    ratio = d / q
    on = np.abs(ratio - np.round(ratio)) < 0.02
    if np.mean(on) < 0.97:
        return 0.0
    # refine: the smallest difference seen often
    small = d[np.round(ratio) == 1]
    return float(np.median(small)) if len(small) else q


def window_length(rate_hz: float) -> int:
    """Samples per window of the structure test (about 2 s)."""
    return int(max(5, min(200, round(2.0 * rate_hz))))


def _lag1_of_differences(runs: list[RunInputs], output: str) -> tuple[float, int]:
    """Lag-1 correlation of consecutive first differences on quiet samples (trimmed of the
    largest 2 %), and the number of pairs; -0.5 for white noise."""
    pairs = []
    for r in runs:
        x = r.output(output)
        q = quiet_mask(r) & np.isfinite(x)
        d = np.diff(x)
        ok = q[2:] & q[1:-1] & q[:-2]
        a, b = d[:-1][ok], d[1:][ok]
        pairs.append(np.column_stack([a, b]))
    p = np.concatenate(pairs) if pairs else np.zeros((0, 2))
    if len(p) < 50:
        return -0.5, len(p)
    big = np.abs(p).max(axis=1)
    p = p[big <= np.quantile(big, 0.98)]
    sa, sb = np.std(p[:, 0]), np.std(p[:, 1])
    if sa == 0 or sb == 0:
        return -0.5, len(p)
    return float(np.corrcoef(p[:, 0], p[:, 1])[0, 1]), len(p)


def ar1_inflation(phi: float, w: int) -> float:
    """``w var(window mean) / E[within-window variance]`` for AR(1) noise of coefficient ``phi``."""
    k = np.arange(1, w)
    s = w + 2.0 * np.sum((w - k) * phi ** k)      # sum over i, j of phi^|i-j|
    var_mean = s / (w * w)                        # in units of the marginal variance
    within = w / (w - 1.0) * (1.0 - var_mean)
    return float(w * var_mean / max(within, 1e-12))


def noise_model(runs: list[RunInputs], output: str) -> Noise:
    diffs = []
    steps = []
    for r in runs:
        x = r.output(output)
        q = quiet_mask(r)
        ok = q[1:] & q[:-1]
        d = np.diff(x)[ok]
        diffs.append(d[np.isfinite(d)])
        steps.append(lattice_step(x))
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    step = float(np.median(steps)) if steps else 0.0
    var_factor = 2.0
    if len(d) < 50:   # hardly any quiet samples (continuous motion): second differences of everything
        d = np.concatenate([np.diff(r.output(output), 2) for r in runs])
        d = d[np.isfinite(d)]
        var_factor = 6.0
    if len(d) < 20:
        return Noise(float("nan"), step, float("nan"), len(d))
    d2 = np.sort(d * d)
    keep = max(1, int(0.98 * len(d2)))
    # a 98 % trim of a Gaussian's squares keeps 0.856 of its second moment
    sigma = float(np.sqrt(np.mean(d2[:keep]) / 0.856 / var_factor))
    # dithered readings (sigma >~ step/2): the differences already hold the step's share;
    # coarse steps: the error is the rounding itself, RMS step/sqrt(12)
    rate = float(np.median([r.rate_hz for r in runs]))
    rho, _ = _lag1_of_differences(runs, output)
    # AR(1) noise: corr(d_k, d_k+1) = -(1 - phi) / 2 and var(d) = 2 sigma^2 (1 - phi); white: phi = 0
    phi = float(np.clip(1.0 + 2.0 * rho, 0.0, 0.95))
    marginal = sigma * sigma / (1.0 - phi)
    inflation = ar1_inflation(phi, window_length(rate)) if phi > 0 else 1.0
    rms = float(np.sqrt(max(marginal, step * step / 12.0)))
    return Noise(sigma, step, max(rms, 1e-12), len(d), rounding_bias_var(sigma, step), inflation, phi)


def _bias_var(s: float, q: float) -> float:
    """Variance over the signal of the mean rounding error of a Gaussian-noisy reading
    (noise std s before rounding to step q): sum_k q^2 / (2 pi^2 k^2) exp(-4 pi^2 k^2 s^2 / q^2)."""
    k = np.arange(1, 40)
    return float(np.sum(q * q / (2 * np.pi ** 2 * k * k) * np.exp(-4 * np.pi ** 2 * k * k * s * s / (q * q))))


def rounding_bias_var(sigma_seen: float, step: float) -> float:
    """The rounding bias variance for readings whose sample-to-sample scatter is ``sigma_seen``.

    The scatter seen holds the noise and the part of the rounding error that changes from
    sample to sample: ``sigma_seen^2 = s^2 + q^2/12 - bias(s)``; solved for ``s`` by bisection.
    """
    if not step > 0 or not np.isfinite(sigma_seen):
        return 0.0
    target = sigma_seen * sigma_seen
    lo, hi = 0.0, max(sigma_seen, step)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if mid * mid + step * step / 12.0 - _bias_var(mid, step) < target:
            lo = mid
        else:
            hi = mid
    return _bias_var(lo, step)
