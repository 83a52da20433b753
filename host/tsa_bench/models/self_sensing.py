"""Self-sensing inverse of the strain-resistance model, thesis eqs. 3.15-3.18.

Units: resistance in ohm, length in mm, time in s; ``u`` in ohm (the hysteresis part
of the resistance, times the sign s of dR/dL); envelope parameters rho_0, phi_0,
rho_3, phi_3 in ohm, rho_1, phi_1 in 1/ohm, rho_2, phi_2 dimensionless.

Contract: the length is estimated from the resistance and the motor-moving flag
alone. At each hold k (the motor-moving flag gives the stop instant t0_k and the step
duration) and each sample i of it::

    u_i = s * (mean_{j <= i in hold k}(y_j - y_t(t_j - t0_k)) - y0 - sum_c c_c x_c(k))    (eq. 3.16)
    L_i = pbar_0 u_i + sum_{n >= 1} pbar_n F_{rbar_n(k)}[u](i)                            (eq. 3.15)

with the generalized play operators of eq. 3.17 (rising input: ``max(o1(u) - rbar, F)``,
falling: ``min(o2(u) + rbar, F)``, measured against the previous hold's final u) and
the tanh envelopes of eq. 3.18. ``pbar``, ``rbar`` are the analytic inverse of the
identified PI weights and rate-dependent thresholds
(:func:`~tsa_bench.models.prandtl_ishlinskii.inverse_parameters`); the creep states
``x_c(k)`` are driven by the previous length estimates (eq. 3.13 depends on v(k-1)),
and the step rate by the estimated length step (two fixed-point passes). The state
before the first motion is the length whose steady model resistance equals the
median resistance measured there. The eight envelope parameters are identified by
bounded least squares (scipy) on the training runs' hold-mean lengths (step 6 of the
thesis's procedure), starting from envelopes that are the identity to 1e-4 over the
training range (above ``LONG_RUN_HOLDS`` holds the two-point Jacobian is computed in one
batched pass, :mod:`~tsa_bench.models.long_run_fits`). NaN while the motor turns and before
the first stop.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, least_squares

from tsa_bench.models.creep import creep_operators
from tsa_bench.models.long_run_fits import BatchedResiduals, batched_hold_estimates, one_blas_thread
from tsa_bench.models.prandtl_ishlinskii import inverse_parameters
from tsa_bench.models.steps import RunSeries, step_sequence
from tsa_bench.models import strain_resistance
from tsa_bench.models.strain_resistance import StrainResistanceModel

ENVELOPE_NAMES = ("rho0_ohm", "rho1_per_ohm", "rho2", "rho3_ohm", "phi0_ohm", "phi1_per_ohm", "phi2", "phi3_ohm")


def envelope(u: np.ndarray, k0: float, k1: float, k2: float, k3: float) -> np.ndarray:
    """Eq. 3.18: ``k0 tanh(k1 u + k2) + k3``."""
    return k0 * np.tanh(k1 * np.asarray(u, dtype=float) + k2) + k3


def identity_envelope(u_lo: float, u_hi: float, flatness: float = 0.01) -> tuple[float, float, float, float]:
    """Envelope parameters equal to the identity within ``~flatness^2`` relative over [u_lo, u_hi]."""
    c = 0.5 * (u_lo + u_hi)
    h = max(0.5 * (u_hi - u_lo), 1e-9)
    k1 = flatness / h
    return (1.0 / k1, k1, -k1 * c, c)


@dataclass(frozen=True)
class SelfSensingModel:
    """The inverse of ``forward`` with envelopes ``rho`` (o1, rising) and ``phi`` (o2, falling)."""

    forward: StrainResistanceModel
    rho: tuple[float, float, float, float]
    phi: tuple[float, float, float, float]

    def _loading(self, v: float) -> float:
        f = self.forward
        r0 = f.thresholds(np.array([0.0]))[0]
        return float(np.asarray(f.weights_ohm_per_mm) @ np.maximum(v - r0, 0.0))

    def _initial_length(self, y_init: float, lo: float, hi: float) -> float:
        f = self.forward
        csum = float(np.sum(f.creep_densities_ohm_per_mm))
        r0 = f.thresholds(np.array([0.0]))[0]
        p = np.asarray(f.weights_ohm_per_mm)

        def g(v: float) -> float:
            return f.offset_ohm + f.sign * float(p @ np.maximum(v - r0, 0.0)) + csum * v - y_init

        grid = np.linspace(lo, hi, 401)
        vals = f.offset_ohm + f.sign * np.maximum(grid[:, None] - r0[None, :], 0.0) @ p + csum * grid - y_init
        change = np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:]))
        if len(change):
            i = int(change[0])
            return float(brentq(g, grid[i], grid[i + 1]))
        return float(grid[int(np.argmin(np.abs(vals)))])

    def initial_length(self, run: RunSeries, length_range_mm: tuple[float, float] | None = None) -> float:
        """Length (mm) before the first motion, from the resistance measured there (module docstring).

        ``length_range_mm`` brackets the search (default 1-1000 mm).
        """
        f = self.forward
        seq = step_sequence(run)
        first = seq.curves[0]
        y_init = seq.initial_resistance_ohm
        if not np.isfinite(y_init):
            y_init = float(np.nanmean(run.resistance_ohm[first.start:first.stop]
                                      - f.transient(run.t_s[first.start:first.stop] - first.t0_s)))
        lo, hi = length_range_mm or (1.0, 1000.0)
        return self._initial_length(y_init, lo, hi)

    def estimate(self, run: RunSeries, per_sample: bool = True,
                 initial_length_mm: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Length estimates: (per-sample array with NaN off holds, per-hold final estimates (m,)).

        ``initial_length_mm`` defaults to :meth:`initial_length`.
        """
        f = self.forward
        seq, zs = self._prepared(run, per_sample)
        p = np.asarray(f.weights_ohm_per_mm)
        dens = np.asarray(f.creep_densities_ohm_per_mm)
        lam = np.asarray(f.creep_rates_per_s)
        v_prev = self.initial_length(run) if initial_length_mm is None else float(initial_length_mm)
        u_prev = self._loading(v_prev)
        rbar0, pbar = inverse_parameters(f.thresholds(np.array([0.0]))[0], p)
        state = np.maximum(envelope(u_prev, *self.rho) - rbar0, 0.0)
        x = np.full(len(lam), v_prev)
        t_prev = seq.t0_s[0]
        out = np.full(len(run.t_s), np.nan)
        finals = np.empty(len(seq.curves))
        for k, c in enumerate(seq.curves):
            dt = c.t0_s - t_prev
            d = np.exp(-lam * dt)
            x = d * x + (1.0 - d) * v_prev
            z = zs[k]
            if z is None:
                finals[k] = v_prev
                continue
            u = f.sign * (z - f.offset_ohm - x @ dens)
            v_est = v_prev
            for _ in range(2):
                rate = abs(v_est - v_prev) / max(dt, 1e-9)
                rbar, _ = inverse_parameters(f.thresholds(np.array([rate]))[0], p)
                lengths, last_state = self._apply(u, u_prev, state, rbar, pbar)
                v_est = float(lengths[-1])
            if per_sample:
                out[c.start:c.stop] = lengths
            finals[k] = v_est
            state, u_prev, v_prev, t_prev = last_state, float(u[-1]), v_est, c.t0_s
        return out, finals

    def _prepared(self, run: RunSeries, per_sample: bool) -> tuple:
        """The run's holds and, per hold, the running mean of ``y - y_t`` (only the last if not per_sample)."""
        key = (id(run), per_sample)
        cache = self.__dict__.setdefault("_cache", {})
        if key in cache and cache[key][0] is run:
            return cache[key][1]
        f = self.forward
        seq = step_sequence(run)
        zs: list[np.ndarray | None] = []
        for c in seq.curves:
            seg = run.resistance_ohm[c.start:c.stop] - f.transient(run.t_s[c.start:c.stop] - c.t0_s)
            good = np.isfinite(seg)
            if not good.any():
                zs.append(None)
                continue
            z = np.cumsum(np.where(good, seg, 0.0)) / np.maximum(np.cumsum(good), 1)
            zs.append(z if per_sample else z[-1:])
        cache[key] = (run, (seq, zs))
        return seq, zs

    def _apply(self, u: np.ndarray, u_prev: float, state: np.ndarray, rbar: np.ndarray,
               pbar: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rising = (u > u_prev)[:, None]
        falling = (u < u_prev)[:, None]
        up = np.maximum(envelope(u, *self.rho)[:, None] - rbar[None, 1:], state[None, 1:])
        down = np.minimum(envelope(u, *self.phi)[:, None] + rbar[None, 1:], state[None, 1:])
        f = np.where(rising, up, np.where(falling, down, state[None, 1:]))
        lengths = pbar[0] * u + f @ pbar[1:]
        new_state = state.copy()
        new_state[1:] = f[-1]
        return lengths, new_state

    def predict(self, run: RunSeries) -> np.ndarray:
        """Estimated length (mm) per sample (NaN while moving / before the first stop)."""
        return self.estimate(run)[0]

    @property
    def envelope_parameters(self) -> dict[str, float]:
        return dict(zip(ENVELOPE_NAMES, (*self.rho, *self.phi)))

    @classmethod
    def identify(cls, forward: StrainResistanceModel, runs: list[RunSeries],
                 max_evaluations: int = 40, long_form: bool | None = None) -> "SelfSensingModel":
        """Fit the eight envelope parameters to the training runs' hold-mean lengths
        (at most ``max_evaluations`` Jacobian evaluations of scipy's least_squares).

        ``long_form``: None (default) evaluates the two-point Jacobian in one batched pass
        over the holds (:func:`~tsa_bench.models.long_run_fits.batched_hold_estimates`) above
        :data:`~tsa_bench.models.strain_resistance.LONG_RUN_HOLDS` holds; True / False forces it.
        """
        seqs = [step_sequence(r) for r in runs]
        # the u range of the training data: the loading curve over the training lengths
        probe = cls(forward, (1.0, 1.0, 0.0, 0.0), (1.0, 1.0, 0.0, 0.0))
        us = [probe._loading(v) for s in seqs for v in s.length_mm]
        start = identity_envelope(min(us), max(us))
        targets = np.concatenate([s.length_mm[1:] for s in seqs])
        ok = np.isfinite(targets)
        lo_v, hi_v = float(np.nanmin(targets)), float(np.nanmax(targets))
        rng = (max(lo_v - (hi_v - lo_v) - 1.0, 1e-3), hi_v + (hi_v - lo_v) + 1.0)

        v0 = [probe.initial_length(r, rng) for r in runs]

        shared: dict = {}

        def residuals(q: np.ndarray) -> np.ndarray:
            m = cls(forward, tuple(q[:4]), tuple(q[4:]))
            object.__setattr__(m, "_cache", shared)
            est = np.concatenate([m.estimate(r, per_sample=False, initial_length_mm=v)[1] for r, v in zip(runs, v0)])
            return (est - targets)[ok]

        x0 = np.array(start + start)
        if long_form if long_form is not None else sum(len(s.curves) for s in seqs) > strain_resistance.LONG_RUN_HOLDS:
            probe_cache = cls(forward, start, start)
            object.__setattr__(probe_cache, "_cache", shared)

            def batch(qs: np.ndarray) -> np.ndarray:
                est = np.hstack([batched_hold_estimates(probe_cache, r, qs[:, :4], qs[:, 4:], v)
                                 for r, v in zip(runs, v0)])
                return (est - targets)[:, ok]

            both = BatchedResiduals(batch)
            with one_blas_thread():
                r0 = both.fun(x0)
                res = least_squares(both.fun, x0, jac=both.jac, x_scale="jac", max_nfev=max_evaluations)
        else:
            r0 = residuals(x0)
            res = least_squares(residuals, x0, x_scale="jac", max_nfev=max_evaluations)
        best = res.x if np.isfinite(res.cost) and 2 * res.cost <= float(r0 @ r0) else x0
        return cls(forward, tuple(float(v) for v in best[:4]), tuple(float(v) for v in best[4:]))
