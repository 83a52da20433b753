"""The long-run forms of the strain-resistance and self-sensing fits against the direct forms.

The pieces (play operators with their clip record, creep states by a doubling scan, the
analytic gradient of eq. 3.19, the batched self-sensing inverse) are checked against
the direct functions and finite differences; the whole identification is run both ways
on one generated step run (the forms forced), and the long form must reach the direct
form's objective and RMSE. The nonlinear strain-resistance parameters are not compared
one by one: eq. 3.19 is flat along directions of (alpha, beta, lambda, eps, Lambda) on such
data (different points reach the same cost to 1e-3), so the modelled steady resistances are.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import approx_fprime

from tsa_bench.models import strain_resistance as srm
from tsa_bench.models.creep import creep_operators
from tsa_bench.models.long_run_fits import (LongSteadyProblem, batched_hold_estimates, creep_and_sensitivity,
                                            forward_difference_jacobian, play_and_clips)
from tsa_bench.models.prandtl_ishlinskii import play, rate_thresholds
from tsa_bench.models.self_sensing import SelfSensingModel
from tsa_bench.models.steps import series_from_arrays, step_sequence
from tsa_bench.models.transient import fit_decay
from tests.models.generator_plant import generator_plant
from tsa_bench.reproduce.runs import history, simulate_history, step_duration_steps


@pytest.fixture(scope="module")
def run():
    """81 holds of 2 s, one-turn steps between 15 and 25 turns (the simulated bench)."""
    h = history(step_duration_steps(2.0, cycles=4, lo=15, hi=25, step=1), dt_s=0.1, load_g=350.0)
    sim = simulate_history(h, generator_plant(), seed=3)
    return series_from_arrays("gen", sim["t_s"], sim["length_mm"], sim["resistance_ohm"], h["motor_moving"])


@pytest.fixture(scope="module")
def problems(run):
    seq = step_sequence(run)
    curves = [(run.t_s[c.start:c.stop] - c.t0_s, run.resistance_ohm[c.start:c.stop]) for c in seq.curves]
    _, _, ys = fit_decay(curves)
    min_p0 = 0.1 * abs(np.polyfit(seq.length_mm[1:], ys, 1)[0])
    return (srm._SteadyProblem([seq], [ys], 20, 1.0, min_p0), LongSteadyProblem([seq], [ys], 20, 1.0, min_p0))


def test_play_with_clip_record_equals_play_and_its_threshold_sensitivity():
    rng = np.random.default_rng(4)
    v = np.cumsum(rng.normal(0, 1.0, 300))
    g = 0.5 + rng.random(300)
    unit = np.arange(8) / 7.0
    f, last, last_sign = play_and_clips(v, g[:, None] * unit[None, :])
    assert np.array_equal(f, play(v, g[:, None] * unit[None, :]))
    # the derivative of every output in g_j is sign * unit_n at the last clip row, else 0
    j, h = 150, 1e-7
    g2 = g.copy()
    g2[j] += h
    numeric = (play(v, g2[:, None] * unit[None, :]) - f) / h
    analytic = np.where(last == j, last_sign * unit[None, :], 0.0)
    assert np.allclose(numeric, analytic, atol=1e-5)


def test_creep_scan_equals_the_recurrence_and_its_rate_derivative():
    rng = np.random.default_rng(5)
    t = np.cumsum(rng.random(500) * 3.0)
    v = np.cumsum(rng.normal(0, 1.0, 500))
    rates = np.array([0.05, 2.0])
    x, dx = creep_and_sensitivity(v, t, rates)
    assert np.allclose(x, creep_operators(v, t, rates), rtol=0, atol=1e-10)
    h = 1e-6
    for i in range(2):
        up, down = rates.copy(), rates.copy()
        up[i] += h
        down[i] -= h
        numeric = (creep_operators(v, t, up)[:, i] - creep_operators(v, t, down)[:, i]) / (2 * h)
        assert np.allclose(numeric, dx[:, i], rtol=0, atol=1e-6)


def test_long_steady_cost_and_linear_parameters_equal_the_direct_form(problems):
    direct, long = problems
    for x in (np.array(srm.STARTS[1]), np.array([0.9, 1.2, 0.8, 1.1, 0.5, 0.9])):
        cost, _ = long.cost_and_gradient(x)
        assert cost == pytest.approx(direct.cost(x), rel=1e-7)   # + the ridge term, ~1e-10 of it
        assert np.allclose(long.linear(x), direct.linear(x), rtol=1e-6, atol=1e-9)


def test_long_steady_gradient_equals_finite_differences(problems):
    _, long = problems
    x = np.array([0.9, 1.2, 0.8, 1.1, 0.5, 0.9])
    _, grad = long.cost_and_gradient(x)
    numeric = approx_fprime(x, lambda z: long.cost_and_gradient(z)[0], 1e-7)
    assert np.allclose(grad, numeric, rtol=1e-3, atol=1e-3 * np.max(np.abs(numeric)))


def test_batched_self_sensing_estimates_equal_the_inverse_one_at_a_time(run):
    forward = srm.StrainResistanceModel.identify([run], n_hysteresis=20, long_form=True)
    probe = SelfSensingModel(forward, (1.0, 1.0, 0.0, 0.0), (1.0, 1.0, 0.0, 0.0))
    v0 = probe.initial_length(run)
    rng = np.random.default_rng(6)
    qs = np.array([[15.0, 0.06, -0.5, 8.0, 14.0, 0.06, -0.5, 9.0]]) * (1 + 0.05 * rng.random((3, 8)))
    batch = batched_hold_estimates(probe, run, qs[:, :4], qs[:, 4:], v0)
    for q, row in zip(qs, batch):
        one = SelfSensingModel(forward, tuple(q[:4]), tuple(q[4:])).estimate(run, per_sample=False,
                                                                              initial_length_mm=v0)[1]
        assert np.allclose(row, one, rtol=1e-10, atol=1e-9)
    # the batched two-point Jacobian is the one-column-at-a-time forward difference
    x = qs[0]
    jac = forward_difference_jacobian(lambda z: batched_hold_estimates(probe, run, z[:, :4], z[:, 4:], v0), x)
    h = np.sqrt(np.finfo(float).eps) * max(1.0, abs(x[3]))
    step = x.copy()
    step[3] += h
    col = (batched_hold_estimates(probe, run, step[None, :4], step[None, 4:], v0)[0] - batch[0]) / ((x[3] + h) - x[3])
    assert np.allclose(jac[:, 3], col, rtol=1e-5, atol=1e-6 * np.max(np.abs(col)))  # rounding / h


def test_long_and_direct_identifications_agree_on_a_generated_run(run):
    seq = step_sequence(run)
    models = {lf: srm.StrainResistanceModel.identify([run], long_form=lf) for lf in (False, True)}
    curves = [(run.t_s[c.start:c.stop] - c.t0_s, run.resistance_ohm[c.start:c.stop]) for c in seq.curves]
    _, _, ys = fit_decay(curves)
    objective = srm._SteadyProblem([seq], [ys], srm.N_HYSTERESIS, models[False].sign,
                                   0.1 * abs(np.polyfit(seq.length_mm[1:], ys, 1)[0])).cost
    x = {lf: np.r_[m.alpha_mm, m.beta, m.lam, m.epsilon, m.creep_rates_per_s] for lf, m in models.items()}
    assert objective(x[True]) <= 1.001 * objective(x[False])

    def rmse(pred, y):
        ok = np.isfinite(pred)
        return float(np.sqrt(np.mean((pred[ok] - y[ok]) ** 2)))

    r_direct = rmse(models[False].predict(run), run.resistance_ohm)
    r_long = rmse(models[True].predict(run), run.resistance_ohm)
    assert r_long <= 1.05 * r_direct
    steady = {lf: m.steady(seq)[1:] for lf, m in models.items()}
    span = np.ptp(steady[False])
    assert np.max(np.abs(steady[True] - steady[False])) < 0.1 * span
    # the envelopes on the same forward model: the batched Jacobian changes rounding only
    ss = {lf: SelfSensingModel.identify(models[False], [run], long_form=lf) for lf in (False, True)}
    assert np.allclose(np.r_[ss[True].rho, ss[True].phi], np.r_[ss[False].rho, ss[False].phi], rtol=1e-4, atol=1e-6)


def test_the_long_form_is_chosen_above_the_hold_threshold(run, monkeypatch):
    def fit(long_form=None):
        return srm.StrainResistanceModel.identify([run], n_hysteresis=20, starts=srm.STARTS[:1], long_form=long_form)

    forced_long, forced_direct = fit(True), fit(False)
    assert forced_long != forced_direct
    monkeypatch.setattr(srm, "LONG_RUN_HOLDS", len(step_sequence(run).curves) - 1)
    assert fit() == forced_long
    monkeypatch.setattr(srm, "LONG_RUN_HOLDS", len(step_sequence(run).curves))
    assert fit() == forced_direct
