"""The sensor-noise model, estimated from the data alone (no model involved).

Units: each output's own (length mm, resistance ohm).

Contract: :func:`noise_model` estimates, per output, from samples where nothing is
commanded to change (motor still, heater and load constant, at least 1 s into the
pause): the quantisation step ``step`` (when the readings sit on a lattice), the white
noise standard deviation ``sigma`` from a trimmed variance of first differences (robust
to the odd jump and to slow drifts, which barely move a first difference), and the
noise-model RMS ``rms = max(sigma, step / sqrt(12), marginal)``. Correlated (coloured) noise
is seen in the settled second halves of quiet stretches, each detrended by a straight line:
their mean square is the ``marginal`` variance, and ``inflation`` is how much larger the
variance of a window mean is than the within-window variance over the window length (1 for
white noise; the structure test expects that much from noise alone). ``floor`` =
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


    @property
    def floor(self) -> float:
        return RELEVANT * self.rms

    def to_json(self) -> dict:
        return {"sigma": self.sigma, "quantisation_step": self.step, "rms": self.rms, "relevance_floor": self.floor,
                "rounding_bias_rms": float(np.sqrt(self.bias_var)), "window_inflation": self.inflation,
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


def _colour(runs: list[RunInputs], output: str, w: int) -> tuple[float, float, int]:
    """(marginal variance, window inflation, windows used) of the noise from the settled second
    halves of quiet stretches, each detrended by a straight line (slow signal removed)."""
    det, means, within = [], [], []
    for r in runs:
        x = r.output(output)
        q = quiet_mask(r) & np.isfinite(x)
        d = np.diff(np.r_[0, q.astype(np.int8), 0])
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            a = (a + b) // 2
            if b - a < 4 * w:
                continue
            y = x[a:b]
            k = np.arange(len(y), dtype=float)
            y = y - np.polyval(np.polyfit(k, y, 1), k)
            det.append(y)
            m = len(y) // w
            blocks = y[: m * w].reshape(m, w)
            means.append(blocks.mean(axis=1))
            within.append(blocks.var(axis=1, ddof=1))
    if not det:
        return 0.0, 1.0, 0
    allm, allw = np.concatenate(means), np.concatenate(within)
    y = np.concatenate(det)
    marginal = float(np.mean(y * y))
    inflation = float(w * np.mean(allm * allm) / np.mean(allw)) if np.mean(allw) > 0 else 1.0
    return marginal, max(1.0, inflation), len(allm)


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
    marginal, inflation, windows = _colour(runs, output, window_length(rate))
    if windows < 20:   # too little quiet data to see the noise's colour: white
        marginal, inflation = 0.0, 1.0
    rms = float(np.sqrt(max(sigma * sigma, step * step / 12.0, marginal)))
    return Noise(sigma, step, max(rms, 1e-12), len(d), rounding_bias_var(sigma, step), inflation)


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
