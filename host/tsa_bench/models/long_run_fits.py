"""Long-run forms of the strain-resistance and self-sensing identifications (thousands of holds).

Units as in :mod:`~tsa_bench.models.strain_resistance` and
:mod:`~tsa_bench.models.self_sensing`: length in mm, resistance in ohm, time in s.

Contract: the same models and parameters, the same objectives, computed so that the
time of one evaluation is linear in the number of holds and far fewer evaluations are
needed:

* :class:`LongSteadyProblem` is eq. 3.19 (the steady values ``y_s`` against the PI and
  creep design, the linear parameters solved inside by bounded least squares) with
  its gradient in the nonlinear parameters computed analytically (variable projection:
  the gradient of the minimum over the linear parameters is the partial gradient at
  the minimiser). The play operators' sensitivity to their thresholds is the threshold
  sensitivity at the hold where each operator last clipped; the creep operators and
  their derivatives in ``Lambda`` are affine recurrences solved by a doubling scan.
  The bounded least squares runs on the ``R`` factor of the design (QR), not the full
  design. The objective includes the small ridge the direct form adds to the least
  squares (so the gradient is exact); it is below 1e-9 of the residual for usual data.
* :func:`batched_hold_estimates` runs the self-sensing inverse at the hold ends for a
  batch of envelope parameter vectors at once, and :func:`forward_difference_jacobian`
  uses it for the two-point Jacobian (steps as scipy's ``2-point``), so one pass over
  the holds gives all nine residual vectors.

The direct forms stay the ones used on the thesis-sized fits (their results are what
the thesis records and calibrated presets were checked against); these forms are used
above :data:`~tsa_bench.models.strain_resistance.LONG_RUN_HOLDS` holds and are tested
to agree with the direct ones.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize import lsq_linear

from tsa_bench.models.steps import StepSequence


def one_blas_thread() -> Any:
    """Context in which BLAS runs on one thread: the long forms' QR and products of a tall,
    64-column design gain nothing from threads, and on a shared machine BLAS threads waiting
    for a core cost several times the work (measured: 5 s instead of 31 s CPU on a lifetime
    run). It also makes the long forms' rounding independent of the core count."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def play_and_clips(v: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 3.10 from a zero state for thresholds ``r`` (K, N): outputs (K, N), and for each
    entry the index of the row where that operator last clipped (-1: never) and the sign
    of the clip there (-1 at the lower bound ``v - r``, +1 at the upper ``v + r``)."""
    lo = v[:, None] - r
    hi = v[:, None] + r
    out = np.empty_like(lo)
    prev = np.zeros(r.shape[1])
    lower, upper = np.maximum, np.minimum
    for lo_k, hi_k, out_k in zip(lo, hi, out):   # the one sequential pass: two ufunc calls a hold
        upper(hi_k, prev, out=out_k)
        lower(lo_k, out_k, out=out_k)
        prev = out_k
    # event code 2k (lower clip) or 2k + 1 (upper clip) grows with k: its running maximum is the last clip
    code = np.where(out == lo, 0, np.where(out == hi, 1, -1 - 2 * len(v)))
    code += 2 * np.arange(len(v))[:, None]
    np.maximum.accumulate(code, axis=0, out=code)
    last = np.where(code >= 0, code >> 1, -1)
    last_sign = np.where(code >= 0, 2.0 * (code & 1) - 1.0, 0.0)
    return out, last, last_sign


def affine_scan(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``x_k = a_k x_{k-1} + b_k`` from ``x_{-1} = 0`` along axis 0 (doubling scan, |a| <= 1)."""
    a, b = a.copy(), b.copy()
    shift = 1
    while shift < len(a):
        b[shift:] = a[shift:] * b[:-shift] + b[shift:]
        a[shift:] = a[shift:] * a[:-shift]
        shift *= 2
    return b


def creep_and_sensitivity(v: np.ndarray, t_s: np.ndarray, rates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 3.13's states (K, Nc) from ``x(0) = v(0)`` and their derivatives in each rate (K, Nc)."""
    dt = np.diff(t_s)[:, None]
    d = np.exp(-dt * rates[None, :])
    x = np.empty((len(v), len(rates)))
    x[0] = v[0]
    # x_k - v_0 obeys the same recurrence with input v_{k-1} - v_0 from 0
    x[1:] = v[0] + affine_scan(d, (1.0 - d) * (v[:-1, None] - v[0]))
    dx = np.zeros_like(x)
    dx[1:] = affine_scan(d, -dt * d * (x[:-1] - v[:-1, None]))
    return x, dx


class SteadyData:
    """What both forms of the eq. 3.19 fit hold: the hold sequences, the stacked targets
    (ohm; ``ok`` where finite), ``nh`` play operators, the sign of the resistance-length
    slope, the least first weight ``min_p0`` and the length span ``scale`` (mm)."""

    def __init__(self, seqs: list[StepSequence], targets: list[np.ndarray], nh: int, sign: float,
                 min_p0: float) -> None:
        self.seqs, self.nh, self.sign, self.min_p0 = seqs, nh, sign, max(min_p0, 1e-12)
        self.y = np.concatenate(targets)
        self.ok = np.isfinite(self.y)
        vs = np.concatenate([s.length_mm for s in seqs])
        self.scale = max(float(np.ptp(vs)), 1e-9)


class LongSteadyProblem(SteadyData):
    """Eq. 3.19 in the nonlinear parameters (alpha, beta, lambda, eps, Lambda_1, Lambda_2):
    :meth:`cost_and_gradient` for scipy's L-BFGS-B (``jac=True``), :meth:`linear` the
    linear parameters (p_0..p_{N-1}, c_1, c_2, y0) at a point."""

    def __init__(self, seqs: list[StepSequence], targets: list[np.ndarray], nh: int, sign: float,
                 min_p0: float) -> None:
        super().__init__(seqs, targets, nh, sign, min_p0)
        self.unit = np.arange(nh) / max(nh - 1, 1)
        n_ok = int(self.ok.sum())
        self.ridge = 1e-6 * np.sqrt(n_ok) * self.scale * np.r_[np.ones(nh + 2), 0.0]
        self.lo = np.r_[self.min_p0, np.zeros(nh - 1), -np.inf, -np.inf, -np.inf]

    def _parts(self, x: np.ndarray) -> list[dict[str, Any]]:
        alpha, beta, lam, eps, l1, l2 = (float(v) for v in x)
        parts = []
        for seq in self.seqs:
            rate = np.abs(seq.rate_mm_per_s)
            powered = rate ** eps
            base = beta + lam * powered
            g = alpha * np.log(base)
            log_rate = np.log(np.where(rate > 0, rate, 1.0))
            dg = np.stack([np.log(base), alpha / base, alpha * powered / base, alpha * lam * powered * log_rate / base])
            f, last, last_sign = play_and_clips(seq.length_mm, np.maximum(g[:, None] * self.unit[None, :], 0.0))
            c, dc = creep_and_sensitivity(seq.length_mm, seq.t0_s, np.array([l1, l2]))
            parts.append({"f": f, "last": last, "last_sign": last_sign, "dg": dg, "c": c, "dc": dc})
        return parts

    def _design(self, parts: list[dict[str, Any]]) -> np.ndarray:
        nh = self.nh
        a = np.empty((len(self.y), nh + 3))
        pos = 0
        for p in parts:
            m = len(p["f"]) - 1
            np.multiply(p["f"][1:], self.sign, out=a[pos:pos + m, :nh])
            a[pos:pos + m, nh:nh + 2] = p["c"][1:]
            pos += m
        a[:, -1] = 1.0
        return a if self.ok.all() else a[self.ok]

    def _solve(self, a: np.ndarray) -> np.ndarray:
        """Bounded least squares of ``[a; ridge] lin = [y; 0]`` on the R factor of ``[a, y]``."""
        r = np.linalg.qr(np.hstack([a, self.y[self.ok][:, None]]), mode="r")
        p = a.shape[1]
        aa = np.vstack([np.triu(r[:p, :p]), np.diag(self.ridge)[:-1]])
        bb = np.r_[r[:p, p], np.zeros(len(self.ridge) - 1)]
        return lsq_linear(aa, bb, bounds=(self.lo, np.full(len(self.lo), np.inf)), method="bvls").x

    def linear(self, x: np.ndarray) -> np.ndarray:
        return self._solve(self._design(self._parts(x)))

    def cost_and_gradient(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        parts = self._parts(x)
        a = self._design(parts)
        lin = self._solve(a)
        res_ok = a @ lin - self.y[self.ok]
        cost = float(res_ok @ res_ok) + float(np.sum((self.ridge * lin) ** 2))
        res = np.zeros(len(self.y))
        res[self.ok] = res_ok
        grad = np.zeros(6)
        p = lin[:self.nh]
        pos = 0
        for part in parts:
            m = len(part["f"]) - 1
            rk = np.r_[0.0, res[pos:pos + m]]     # row 0 (before the first motion) is not fitted
            pos += m
            # d cost / d g_j = 2 s sum_{k, n: operator n last clipped at j} res_k p_n unit_n sign
            w = rk[:, None] * (p * self.unit)[None, :] * part["last_sign"]
            # (w is 0 where an operator never clipped: its last_sign is 0)
            by_row = np.bincount(np.maximum(part["last"], 0).ravel(), weights=w.ravel(), minlength=len(rk))
            grad[:4] += 2.0 * self.sign * (part["dg"] @ by_row)
            grad[4:] += 2.0 * (rk @ part["dc"]) * lin[self.nh:self.nh + 2]
        return cost, grad


def batched_hold_estimates(model: Any, run: Any, rho: np.ndarray, phi: np.ndarray,
                           initial_length_mm: float) -> np.ndarray:
    """Per-hold final length estimates (Q, m) of the self-sensing inverse for Q envelope
    parameter vectors ``rho``, ``phi`` (Q, 4) at once (``SelfSensingModel.estimate`` with
    ``per_sample=False``: the same recursion, vectorised over the batch, with what does not
    depend on the envelopes computed once: creep decay factors, the first pass's zero rate)."""
    from tsa_bench.models.prandtl_ishlinskii import inverse_parameters

    f = model.forward
    seq, zs = model._prepared(run, False)
    p = np.asarray(f.weights_ohm_per_mm)
    dens = np.asarray(f.creep_densities_ohm_per_mm)
    lam = np.asarray(f.creep_rates_per_s)
    nh = len(p)
    rbar_unit, pbar = inverse_parameters(np.arange(nh) / max(nh - 1, 1), p)   # rbar is linear in the scale
    rbar1, pbar0, pbar1 = rbar_unit[1:], float(pbar[0]), pbar[1:]
    rbar0 = inverse_parameters(f.thresholds(np.array([0.0]))[0], p)[0]
    alpha, beta, lmb, eps = f.alpha_mm, f.beta, f.lam, f.epsilon
    rb_still = max(alpha * np.log(beta), 0.0) * rbar1   # the first pass: rate 0
    # per hold, independent of the envelopes: time since the last hold with data, creep decay
    m = len(seq.curves)
    has = np.array([z is not None for z in zs])
    zlast = np.array([float(z[-1]) if z is not None else np.nan for z in zs])
    t0 = np.array([c.t0_s for c in seq.curves])
    prev_t = np.r_[seq.t0_s[0], t0][np.maximum.accumulate(np.where(np.r_[True, has], np.arange(m + 1), 0))][:m]
    dts = t0 - prev_t
    decay = np.exp(-np.outer(dts, lam))
    q = len(rho)
    k0, k1, k2, k3 = (rho[:, i].copy() for i in range(4))
    h0, h1, h2, h3 = (phi[:, i].copy() for i in range(4))
    v_prev = np.full(q, float(initial_length_mm))
    u_prev = np.full(q, model._loading(float(initial_length_mm)))
    state = np.maximum((k0 * np.tanh(k1 * u_prev + k2) + k3)[:, None] - rbar0[None, :], 0.0)[:, 1:]
    x = np.full((q, len(lam)), float(initial_length_mm))
    finals = np.empty((q, m))
    inf = np.inf
    for k in range(m):
        d = decay[k]
        x = d * x + (1.0 - d) * v_prev[:, None]
        if not has[k]:
            finals[:, k] = v_prev
            continue
        u = f.sign * (zlast[k] - f.offset_ohm - x @ dens)
        # rising: F = max(o1(u) - rbar, F); falling: F = min(o2(u) + rbar, F); else F kept
        up = np.where(u > u_prev, k0 * np.tanh(k1 * u + k2) + k3, -inf)[:, None]
        down = np.where(u < u_prev, h0 * np.tanh(h1 * u + h2) + h3, inf)[:, None]
        new = np.minimum(np.maximum(up - rb_still, state), down + rb_still)
        v_est = pbar0 * u + new @ pbar1
        rate = np.abs(v_est - v_prev) / max(dts[k], 1e-9)
        rb = np.maximum(alpha * np.log(beta + lmb * rate ** eps), 0.0)[:, None] * rbar1
        new = np.minimum(np.maximum(up - rb, state), down + rb)
        v_est = pbar0 * u + new @ pbar1
        finals[:, k] = v_est
        state, u_prev, v_prev = new, u, v_est
    return finals


class BatchedResiduals:
    """Residuals and their two-point Jacobian (scipy's ``2-point`` steps, ``sqrt(eps)
    max(1, |x|)`` signed like x) from one batched call of ``residuals_batch`` ((Q, n) ->
    (Q, m)): every residual evaluation computes the Jacobian's columns too, so the Jacobian
    scipy asks for next at the same point costs nothing more."""

    def __init__(self, residuals_batch) -> None:
        self.batch = residuals_batch
        self.x: np.ndarray | None = None

    def _at(self, x: np.ndarray) -> None:
        if self.x is not None and np.array_equal(x, self.x):
            return
        h = np.sqrt(np.finfo(float).eps) * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        h = (x + h) - x
        r = self.batch(np.vstack([x, x + np.diag(h)]))
        self.x, self.r, self.j = x.copy(), r[0], ((r[1:] - r[0]) / h[:, None]).T

    def fun(self, x: np.ndarray) -> np.ndarray:
        self._at(x)
        return self.r

    def jac(self, x: np.ndarray) -> np.ndarray:
        self._at(x)
        return self.j


def forward_difference_jacobian(residuals_batch, x: np.ndarray) -> np.ndarray:
    """The two-point Jacobian of :class:`BatchedResiduals` at ``x``."""
    return BatchedResiduals(residuals_batch).jac(x)
