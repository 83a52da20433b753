"""Strain-resistance model of thesis section 3.2.2: ``y = y_t + y_h + y_c`` (eqs. 3.8-3.14, 3.19-3.20).

Units: length (the input v) in mm, resistance (the output y) in ohm, time in s,
rates in mm/s, ``alpha`` in mm, ``lambda`` in (s/mm)^eps, ``Lambda_i`` in 1/s, ``b1``, ``b2``
in ohm, PI weights in ohm/mm, creep densities in ohm/mm.

Model, evaluated on the holds of a run (one step k per hold, :mod:`~tsa_bench.models.steps`)::

    y(t)   = y_s(k) + b1 ln^2(t - t0_k + eps) + b2 ln(t - t0_k + eps)           (eq. 3.9)
    y_s(k) = y0 + s * sum_n p_n F_{r_n(k)}[v](k) + sum_i c_i x_i(k)            (eqs. 3.11, 3.13-3.14)
    r_n(k) = n/(N_h - 1) alpha ln(beta + lambda |vdot_k|^eps)                   (eq. 3.12)

with v(k) the mean length over hold k, ``vdot_k`` the length step over the step
duration, ``r_0 = 0`` so ``p_0`` is the linear term (the thesis's ``a = s p_0``), ``p_n >= 0``,
``s = +-1`` the sign of dR/dL, ``p_0`` at least :data:`MIN_LINEAR_FRACTION` of the
least-squares slope |dR/dL| (so the inverse stays well conditioned), and an offset ``y0`` (the resistance at zero length
extrapolated; eq. 3.14 has none because the thesis's y is measured from a datum).
Identification follows the thesis's procedure: (1) cut every training run into its
hold curves, (2) fit the transient decay with b1, b2 <= 0 shared by all curves and a
steady value ``y_s`` per curve, (3) fit the hysteresis and creep to the ``y_s``
sequence by bounded optimisation of eq. 3.19 (scipy L-BFGS-B over alpha, beta,
lambda, eps, Lambda_1, Lambda_2 from several starts, the linear parameters solved
inside by bounded least squares), (4) ``y_model = y_s,model + y_t`` (eq. 3.20). Samples
while the motor turns and before the first stop are not modelled (NaN). Above
:data:`LONG_RUN_HOLDS` holds step (3) uses the analytic gradient of the same objective
(:class:`~tsa_bench.models.long_run_fits.LongSteadyProblem`) instead of finite differences.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear, minimize

from tsa_bench.models.creep import creep_operators
from tsa_bench.models.long_run_fits import LongSteadyProblem, SteadyData, one_blas_thread
from tsa_bench.models.prandtl_ishlinskii import play, rate_thresholds
from tsa_bench.models.steps import RunSeries, StepSequence, step_sequence
from tsa_bench.models.transient import EPS_S, decay, fit_decay

N_HYSTERESIS = 60
N_CREEP = 2
#: Bounds of the nonlinear parameters (alpha mm, beta 1, lambda, eps 1, Lambda_1, Lambda_2 1/s).
BOUNDS = ((1e-3, 20.0), (1.0, 20.0), (0.0, 100.0), (0.2, 3.0), (1e-4, 1.0), (1e-3, 10.0))
NONLINEAR = ("alpha_mm", "beta", "lambda", "epsilon", "Lambda1_per_s", "Lambda2_per_s")
#: Lower bound of p_0 (the linear term) as a fraction of the overall slope dR/dL: keeps the
#: analytic inverse's gain 1/p_0 bounded so the self-sensing inverse does not amplify noise.
MIN_LINEAR_FRACTION = 0.1
STARTS = ((1.0, 1.0, 1.0, 1.0, 1.0, 1.0), (0.5, 1.5, 1.0, 1.0, 0.01, 0.5), (2.0, 1.2, 0.2, 0.7, 0.003, 0.1))
#: Above this many holds (all training runs together) step (3) and the self-sensing envelopes
#: use the long-run forms (:mod:`~tsa_bench.models.long_run_fits`: analytic gradient, time
#: linear in holds); at or below it, the direct forms the thesis comparisons were made with.
LONG_RUN_HOLDS = 500


@dataclass(frozen=True)
class StrainResistanceModel:
    """Identified parameters (module docstring). ``weights`` are p_0..p_{N_h-1} (ohm/mm)."""

    b1_ohm: float
    b2_ohm: float
    alpha_mm: float
    beta: float
    lam: float
    epsilon: float
    creep_rates_per_s: tuple[float, ...]
    creep_densities_ohm_per_mm: tuple[float, ...]
    weights_ohm_per_mm: tuple[float, ...]
    sign: float
    offset_ohm: float
    eps_s: float = EPS_S

    # -- building blocks -------------------------------------------------
    def thresholds(self, rate_mm_per_s: np.ndarray) -> np.ndarray:
        """(m, N_h) thresholds (mm) for the step rates (eq. 3.12)."""
        return rate_thresholds(rate_mm_per_s, len(self.weights_ohm_per_mm), self.alpha_mm, self.beta, self.lam,
                               self.epsilon)

    def creep_states(self, seq_v: np.ndarray, t0_s: np.ndarray) -> np.ndarray:
        return creep_operators(seq_v, t0_s, np.asarray(self.creep_rates_per_s))

    def steady(self, seq: StepSequence, v: np.ndarray | None = None) -> np.ndarray:
        """``y_s,model`` (ohm) for every row of ``seq`` (row 0 = before the first motion)."""
        vv = seq.length_mm if v is None else v
        f = play(vv, self.thresholds(seq.rate_mm_per_s))
        x = self.creep_states(vv, seq.t0_s)
        return (self.offset_ohm + self.sign * f @ np.asarray(self.weights_ohm_per_mm)
                + x @ np.asarray(self.creep_densities_ohm_per_mm))

    def transient(self, dt_s: np.ndarray) -> np.ndarray:
        return decay(dt_s, self.b1_ohm, self.b2_ohm, self.eps_s)

    def predict(self, run: RunSeries) -> np.ndarray:
        """Modelled resistance (ohm) at every sample of ``run``; NaN while moving / before the first stop."""
        seq = step_sequence(run)
        ys = self.steady(seq)
        out = np.full(len(run.t_s), np.nan)
        for k, c in enumerate(seq.curves, start=1):
            out[c.start:c.stop] = ys[k] + self.transient(run.t_s[c.start:c.stop] - c.t0_s)
        return out

    # -- identification --------------------------------------------------
    @classmethod
    def identify(cls, runs: list[RunSeries], n_hysteresis: int = N_HYSTERESIS,
                 starts: tuple[tuple[float, ...], ...] = STARTS,
                 long_form: bool | None = None) -> "StrainResistanceModel":
        """The thesis's procedure (module docstring) on one or more training runs.

        ``long_form`` picks the form of step (3): None (default) the long-run form above
        :data:`LONG_RUN_HOLDS` holds, True / False forces one (for tests).
        """
        if not runs:
            raise ValueError("no training runs")
        seqs = [step_sequence(r) for r in runs]
        curves = []
        for r, seq in zip(runs, seqs):
            for c in seq.curves:
                curves.append((r.t_s[c.start:c.stop] - c.t0_s, r.resistance_ohm[c.start:c.stop]))
        b1, b2, ys_all = fit_decay(curves)
        targets, pos = [], 0
        for seq in seqs:
            m = len(seq.curves)
            targets.append(ys_all[pos:pos + m])
            pos += m
        slope = np.polyfit(np.concatenate([s.length_mm[1:] for s in seqs]), np.concatenate(targets), 1)[0]
        sign = 1.0 if slope >= 0 else -1.0
        long_run = long_form if long_form is not None else sum(len(s.curves) for s in seqs) > LONG_RUN_HOLDS
        problem: _SteadyProblem | LongSteadyProblem
        if long_run:
            problem = LongSteadyProblem(seqs, targets, n_hysteresis, sign, MIN_LINEAR_FRACTION * abs(slope))
            cost, jac = problem.cost_and_gradient, True
        else:
            problem = _SteadyProblem(seqs, targets, n_hysteresis, sign, MIN_LINEAR_FRACTION * abs(slope))
            cost, jac = problem.cost, None
        best = None
        with one_blas_thread() if long_run else contextlib.nullcontext():
            for x0 in starts:
                res = minimize(cost, np.clip(x0, [b[0] for b in BOUNDS], [b[1] for b in BOUNDS]), jac=jac,
                               method="L-BFGS-B", bounds=BOUNDS, options={"maxiter": 300})
                if best is None or res.fun < best.fun:
                    best = res
            lin = problem.linear(best.x)
        alpha, beta, lam, eps, l1, l2 = (float(x) for x in best.x)
        nh = n_hysteresis
        return cls(b1, b2, alpha, beta, lam, eps, (l1, l2), (float(lin[nh]), float(lin[nh + 1])),
                   # bvls may return a bound-constrained weight a rounding error below 0 (-1e-20)
                   tuple(max(float(p), 0.0) for p in lin[:nh]), sign, float(lin[nh + 2]))

    @property
    def a_ohm_per_mm(self) -> float:
        """The thesis's linear creep-model term ``a`` (eq. 3.14) = ``s p_0``."""
        return self.sign * self.weights_ohm_per_mm[0]


class _SteadyProblem(SteadyData):
    """Eq. 3.19 as a function of the nonlinear parameters; the linear ones solved inside."""

    def design(self, x: np.ndarray) -> np.ndarray:
        alpha, beta, lam, eps, l1, l2 = x
        blocks = []
        for seq in self.seqs:
            r = rate_thresholds(seq.rate_mm_per_s, self.nh, alpha, beta, lam, eps)
            f = self.sign * play(seq.length_mm, r)
            c = creep_operators(seq.length_mm, seq.t0_s, np.array([l1, l2]))
            blocks.append(np.hstack([f, c, np.ones((len(seq.length_mm), 1))])[1:])
        return np.vstack(blocks)

    def linear(self, x: np.ndarray) -> np.ndarray:
        a = self.design(x)[self.ok]
        nh = self.nh
        lo = np.r_[np.full(nh, 0.0), -np.inf, -np.inf, -np.inf]
        lo[0] = self.min_p0
        # a small ridge keeps the collinear creep and linear columns bounded
        ridge = 1e-6 * np.sqrt(len(a)) * np.eye(a.shape[1])[:-1] * np.r_[np.full(nh + 2, 1.0), 0.0] * self.scale
        aa = np.vstack([a, ridge])
        bb = np.r_[self.y[self.ok], np.zeros(len(ridge))]
        return lsq_linear(aa, bb, bounds=(lo, np.full(nh + 3, np.inf)), method="bvls").x

    def cost(self, x: np.ndarray) -> float:
        lin = self.linear(x)
        res = self.design(x)[self.ok] @ lin - self.y[self.ok]
        return float(res @ res)
