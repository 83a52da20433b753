"""Hold-to-hold offsets as a variance component (the plant's settling), with its likelihood-ratio test.

Units: the output's own (length mm, resistance ohm).

Contract: a rig settles a little differently at every stop (contacts re-seat, strings
bed in): an offset drawn anew at every motor stop and heater change and constant until
the next one (the library's ``length_settling`` and ``resistance_settling``).
:func:`hold_groups` numbers those intervals. :func:`variance_component` takes a residual
(measured minus model) and models the training mean of each hold, ``m_i`` over ``n_i``
samples, as ``x_i b + u_i + e_i``: ``u_i ~ N(0, tau^2)`` the offsets, ``e_i`` the noise's
share (variance ``k sigma^2 / n_i``, ``k`` the noise model's inflation for correlated
noise) and ``x_i b`` a smooth fixed part (the hold's twist, its square, load, time, the direction
of the last move and its product with the twist: what a deterministic misfit would leave). ``tau^2`` by maximum likelihood with ``b``
profiled out; the likelihood-ratio statistic against ``tau = 0`` is referred to the
boundary mixture ``chi2_0 / 2 + chi2_1 / 2``. The component is **named** when p <
:data:`ALPHA` and ``tau`` is at least the relevance floor (half the noise RMS); its 95 %
interval is the profile-likelihood one. Offsets that follow a signal from hold to hold (the
twist, the direction, the load, time, travel, the measured length, the heater: weighted
F-test over the holds) or that change smoothly from one hold to the next (lag-1 correlation of
consecutive offsets significantly positive) or that repeat where the state repeats (the
offsets of holds nearest in twist, load and measured length correlated, either sign) are a
deterministic misfit, not settling, and are not named. :func:`conditional` removes each hold's predicted
offset (its mean's deviation from the weighted mean of all holds, shrunk by ``tau^2 /
(tau^2 + k sigma^2 / n_i)``) from every sample of the hold; it is applied only to a component
whose offsets follow nothing (a misfit is never hidden as settling).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import brentq, minimize_scalar
from scipy.stats import chi2
from scipy.stats import f as fdist

from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.noise import Noise

ALPHA = 0.01
MIN_SAMPLES = 5        # a hold with fewer training samples is left out of the estimate
MIN_HOLDS = 8          # fewer holds: not testable
#: consecutive holds' offsets correlated beyond this many standard errors (one-sided 1 %) change
#: smoothly from hold to hold: a deterministic misfit, not independent draws
SERIAL_Z = 2.33
#: offsets of holds nearest in state correlated (either sign: up and down at one twist may differ by
#: a hysteresis misfit) beyond this many standard errors (two-sided 1 %) repeat with the state
REPEAT_Z = 2.58
#: signals that change from hold to hold (the within-hold ones, speed or time since the stop, do not);
#: the motor angle stands still in a hold, so a once-per-turn error is a hold offset that follows it
HOLD_SIGNALS = ("turns", "motor_angle", "direction", "load", "time", "travel", "length", "heater_power")
#: the library effect that models the component, and its parameter, per output
EFFECT = {"length": ("length_settling", "hold_sd_mm"), "resistance": ("resistance_settling", "hold_sd_ohm")}


@dataclass
class Component:
    output: str
    testable: bool
    tau: float = 0.0                   # sd of the offsets, output units
    ci95: tuple[float, float] = (0.0, 0.0)
    lr: float = 0.0
    p: float = 1.0
    n_holds: int = 0
    heldout_tau: float | None = None   # the same sd estimated on the held-out holds (fixed part from training)
    named: bool = False
    follows: list[str] = field(default_factory=list)   # signals the hold offsets follow (then not settling)
    serial: float = 0.0               # lag-1 correlation of consecutive holds' offsets
    repeat: float = 0.0               # correlation of offsets of holds nearest in state
    beta: np.ndarray | None = None
    scale: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None    # covariate centre, spread, columns used

    def to_json(self) -> dict:
        effect, param = EFFECT[self.output]
        return {"output": self.output, "effect": effect, "parameter": param, "testable": self.testable,
                "sd": self.tau, "sd_ci95": list(self.ci95), "likelihood_ratio": self.lr, "p": self.p,
                "n_holds": self.n_holds, "heldout_sd": self.heldout_tau, "named": self.named,
                "offsets_follow": self.follows, "serial_correlation": self.serial,
                "nearest_state_correlation": self.repeat}


def hold_groups(r: RunInputs) -> np.ndarray:
    """Interval number of every sample: a new interval starts at each motor stop and heater change."""
    mv, v = r.moving, r.volts
    new = np.zeros(len(r), bool)
    new[1:] = (mv[:-1] & ~mv[1:]) | (v[1:] != v[:-1])
    return np.cumsum(new)


def _design(turns: np.ndarray, load: np.ndarray, t: np.ndarray, direction: np.ndarray | None) -> np.ndarray:
    d = np.zeros_like(turns) if direction is None else direction
    return np.column_stack([turns, turns ** 2, load, t, d, d * turns])


class _Means:
    """Per-hold means of the residual and of the covariates over a sample mask."""

    def __init__(self, res: np.ndarray, mask: np.ndarray, groups: np.ndarray, cov: np.ndarray) -> None:
        g = groups[mask]
        keys, inv, n = np.unique(g, return_inverse=True, return_counts=True)
        self.keys, self.n = keys, n.astype(float)
        self.m = np.bincount(inv, weights=res[mask]) / n
        self.x = np.column_stack([np.bincount(inv, weights=c) / n for c in cov[mask].T]) if len(keys) else \
            np.zeros((0, cov.shape[1]))

    def keep(self, sel: np.ndarray) -> None:
        self.keys, self.n, self.m, self.x = self.keys[sel], self.n[sel], self.m[sel], self.x[sel]


def _loglik(tau2: float, m: np.ndarray, x: np.ndarray, s2: np.ndarray, beta: np.ndarray | None = None
            ) -> tuple[float, np.ndarray]:
    v = tau2 + s2
    w = 1.0 / v
    if beta is None:
        xw = x * w[:, None]
        beta = np.linalg.lstsq(xw.T @ x, xw.T @ m, rcond=None)[0]
    r = m - x @ beta
    return float(-0.5 * np.sum(np.log(v) + w * r * r)), beta


def _neighbours(z: np.ndarray, feats: np.ndarray) -> float:
    """Correlation of each hold's standardised offset with that of the hold nearest to it in state
    (standardised features): random draws do not repeat, a function of the state does."""
    if len(z) < MIN_HOLDS:
        return 0.0
    f = (feats - feats.mean(axis=0)) / np.where(feats.std(axis=0) > 1e-12, feats.std(axis=0), 1.0)
    d = ((f[:, None, :] - f[None, :, :]) ** 2).sum(axis=2)
    np.fill_diagonal(d, np.inf)
    nn = np.argmin(d, axis=1)
    a, b = z - z.mean(), z[nn] - z.mean()
    return float(a @ b / np.sqrt((a @ a) * (b @ b))) if a @ a > 0 and b @ b > 0 else 0.0


def _serial(z: np.ndarray) -> float:
    """Lag-1 correlation of consecutive holds' standardised offsets (0 for independent draws)."""
    z = z - z.mean()
    return float(z[1:] @ z[:-1] / (z @ z)) if len(z) > 2 and z @ z > 0 else 0.0


def _hold_follows(tr: "_Means", r: np.ndarray, var: np.ndarray, p: int, bases: Mapping[str, np.ndarray],
                  mask: np.ndarray, groups: np.ndarray) -> list[str]:
    """Signals the holds' offsets follow (weighted F-test over the holds at :data:`ALPHA`, Bonferroni
    over the signals): offsets that
    follow the twist, the direction, the load ... are a deterministic misfit, not settling."""
    out = []
    w = 1.0 / var
    for name in HOLD_SIGNALS:
        if name not in bases:
            continue
        b = bases[name]
        pos = np.searchsorted(tr.keys, groups[mask])
        inside = (pos < len(tr.keys)) & (tr.keys[np.minimum(pos, len(tr.keys) - 1)] == groups[mask])
        xb = np.column_stack([np.bincount(pos[inside], weights=c[mask][inside], minlength=len(tr.keys))
                              for c in b.T]) / tr.n[:, None]
        xb = xb - (w @ xb) / w.sum()
        keep = np.std(xb, axis=0) > 1e-12
        k = int(keep.sum())
        dof = len(r) - p - k
        if k == 0 or dof < 3:
            continue
        xw = xb[:, keep] * np.sqrt(w)[:, None]
        yw = (r - (w @ r) / w.sum()) * np.sqrt(w)
        coef = np.linalg.lstsq(xw, yw, rcond=None)[0]
        ess = float(np.sum((xw @ coef) ** 2))
        rss = float(yw @ yw) - ess
        if rss > 0 and float(fdist.sf((ess / k) / (rss / dof), k, dof)) < ALPHA / len(HOLD_SIGNALS):
            out.append(name)
    return out


def variance_component(output: str, res: np.ndarray, train: np.ndarray, heldout: np.ndarray, groups: np.ndarray,
                       turns: np.ndarray, load: np.ndarray, t: np.ndarray, noise: Noise,
                       bases: Mapping[str, np.ndarray] | None = None, level: np.ndarray | None = None,
                       direction: np.ndarray | None = None) -> Component:
    """Fit and test the hold-to-hold variance component of ``res`` (module docstring). ``train`` and
    ``heldout`` mask the usable samples of each side; ``groups`` from :func:`hold_groups` (distinct
    across runs); ``bases`` (:class:`tsa_bench.analysis.signals.RunBases`) the signals whose hold means
    the offsets must not follow for the component to be named."""
    cov = _design(turns, load, t, direction)
    ok = np.isfinite(res) & np.all(np.isfinite(cov), axis=1)
    tr = _Means(res, ok & train, groups, cov)
    tr.keep(tr.n >= MIN_SAMPLES)
    k = max(noise.inflation, (1 + noise.phi) / max(1 - noise.phi, 1e-3))
    if len(tr.m) < MIN_HOLDS or not np.isfinite(noise.rms):
        return Component(output, False, n_holds=len(tr.m))
    centre, spread = tr.x.mean(axis=0), tr.x.std(axis=0)
    spread = np.where(spread > 1e-12, spread, 1.0)
    cols = np.r_[True, np.std(tr.x, axis=0) > 1e-12 * np.maximum(1.0, np.abs(centre))]
    x = np.column_stack([np.ones(len(tr.m)), (tr.x - centre) / spread])[:, cols]
    s2 = k * noise.rms ** 2 / tr.n
    ll0, beta0 = _loglik(0.0, tr.m, x, s2)
    top = max(float(np.var(tr.m)) * 4.0, float(np.max(s2)))

    def neg(log_tau2: float) -> float:
        return -_loglik(float(np.exp(log_tau2)), tr.m, x, s2)[0]

    lo_b = np.log(max(1e-6 * float(np.min(s2)), 1e-300))
    grid = np.linspace(lo_b, np.log(top), 40)
    start = grid[int(np.argmin([neg(g) for g in grid]))]
    sol = minimize_scalar(neg, bounds=(max(lo_b, start - 1.0), min(np.log(top), start + 1.0)), method="bounded",
                          options={"xatol": 1e-4})
    tau2 = float(np.exp(sol.x))
    ll1, beta = _loglik(tau2, tr.m, x, s2)
    if ll1 <= ll0:
        tau2, ll1, beta = 0.0, ll0, beta0
    lr = max(0.0, 2.0 * (ll1 - ll0))
    p = float(0.5 * chi2.sf(lr, 1)) if lr > 0 else 1.0
    crit = float(chi2.ppf(0.95, 1))

    def excess(log_tau2: float) -> float:
        return 2.0 * (ll1 - _loglik(float(np.exp(log_tau2)), tr.m, x, s2)[0]) - crit

    lo = 0.0
    if tau2 > 0 and excess(lo_b) > 0:
        lo = float(np.exp(brentq(excess, lo_b, np.log(tau2))))
    hi_b = np.log(top * 100.0)
    hi = float(np.exp(brentq(excess, np.log(max(tau2, np.exp(lo_b))), hi_b))) if excess(hi_b) > 0 else float(
        np.exp(hi_b))
    comp = Component(output, True, float(np.sqrt(tau2)), (float(np.sqrt(lo)), float(np.sqrt(hi))), lr, p,
                     len(tr.m), beta=beta, scale=(centre, spread, cols))
    r = tr.m - x @ beta
    comp.follows = _hold_follows(tr, r, tau2 + s2, x.shape[1], bases or {}, ok & train, groups)
    both = _Means(res, ok & (train | heldout), groups, cov)      # every hold, in time order
    both.keep(both.n >= MIN_SAMPLES)
    z = (both.m - _fixed(comp, both.x)) / np.sqrt(tau2 + k * noise.rms ** 2 / both.n)
    comp.serial = _serial(z)
    if comp.serial * np.sqrt(len(z)) > SERIAL_Z:
        comp.follows.append("hold order")
    if level is not None:
        lv = np.where(np.isfinite(level), level, np.nanmean(level) if np.isfinite(level).any() else 0.0)
        held = _Means(lv, ok & (train | heldout), groups, lv[:, None])
        held.keep(held.n >= MIN_SAMPLES)
        comp.repeat = _neighbours(z, np.column_stack([both.x[:, 0], both.x[:, 2], held.m]))
        if abs(comp.repeat) * np.sqrt(len(z)) > REPEAT_Z:
            comp.follows.append("the hold's state (holds alike in twist, load and length have alike offsets)")
    comp.named = bool(p < ALPHA and comp.tau >= noise.floor and not comp.follows)
    ho = _Means(res, ok & heldout, groups, cov)
    ho.keep(ho.n >= MIN_SAMPLES)
    if len(ho.m) >= 3:
        r = ho.m - _fixed(comp, ho.x)
        comp.heldout_tau = float(np.sqrt(max(float(np.mean(r ** 2 - k * noise.rms ** 2 / ho.n)), 0.0)))
    return comp


def _fixed(comp: Component, xm: np.ndarray) -> np.ndarray:
    centre, spread, cols = comp.scale
    return np.column_stack([np.ones(len(xm)), (xm - centre) / spread])[:, cols] @ comp.beta


def conditional(comp: Component, res: np.ndarray, groups: np.ndarray, turns: np.ndarray, load: np.ndarray,
                t: np.ndarray, noise: Noise, direction: np.ndarray | None = None) -> np.ndarray:
    """``res`` less each hold's predicted offset (every finite sample; see the module docstring)."""
    if not comp.testable or comp.tau <= 0 or comp.beta is None:
        return res
    cov = _design(turns, load, t, direction)
    ok = np.isfinite(res) & np.all(np.isfinite(cov), axis=1)
    allm = _Means(res, ok, groups, cov)
    k = max(noise.inflation, (1 + noise.phi) / max(1 - noise.phi, 1e-3))
    var = comp.tau ** 2 + k * noise.rms ** 2 / allm.n
    centre = float(np.sum(allm.m / var) / np.sum(1.0 / var))
    offset = comp.tau ** 2 / var * (allm.m - centre)
    out = res.copy()
    pos = np.searchsorted(allm.keys, groups[ok])
    out[ok] -= offset[pos]
    return out
