"""The models against independent references: published PI example, closed forms, hand-derived values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tsa_bench.models.creep import creep_operators
from tsa_bench.models.manipulator import ManipulatorGeometry, bending_angle, savgol_derivative, velocity_models
from tsa_bench.models.metrics import compare, e_aver, sigma
from tsa_bench.models.polynomial import PolynomialModel
from tsa_bench.models.prandtl_ishlinskii import PIModel, generalized_play, play
from tsa_bench.models.preisach import PreisachModel, relay_states
from tsa_bench.models.tsa_kinematics import (length_constant_radius, length_fixed_point, length_with_radius_growth,
                                             reduction_ratio, reduction_ratio_linearised)

R_EX = [0.45 * (j - 1) for j in range(1, 8)]
P_EX = [0.72, 0.6, 0.48, 0.36, 0.24, 0.12, 0.012]


def reference_play(v: list[float], r: float) -> list[float]:
    """Straightforward scalar loop of eq. 3.10, initial state 0."""
    out, w = [], 0.0
    for x in v:
        w = max(x - r, min(x + r, w))
        out.append(w)
    return out


def test_pi_example_matches_an_independent_loop() -> None:
    t = np.arange(0, 2, 1e-3)
    v = 4 * np.sin(2 * np.pi * t)
    y = PIModel(tuple(R_EX), tuple(P_EX))(v)
    expected = [sum(p * f for p, f in zip(P_EX, fs)) for fs in zip(*(reference_play(list(v), r) for r in R_EX))]
    np.testing.assert_allclose(y, expected, rtol=0, atol=1e-12)


def test_pi_example_hand_points() -> None:
    # initial loading 0 -> 4 (t = 0.25 s): y = sum p_j (4 - r_j) for r_j < 4
    y = PIModel(tuple(R_EX), tuple(P_EX))(np.array([0.0, 4.0, 0.0]))
    assert y[1] == pytest.approx(sum(p * (4 - r) for p, r in zip(P_EX, R_EX)))
    # unloading 4 -> 0: F_r = min(0 + r, 4 - r) per operator
    assert y[2] == pytest.approx(sum(p * min(r, 4 - r) for p, r in zip(P_EX, R_EX)))
    assert y[2] > 0  # hysteresis: the output does not return to 0


def test_inverse_round_trip_to_1e9() -> None:
    pi = PIModel(tuple(R_EX), tuple(P_EX))
    t = np.linspace(0, 3, 3001)
    y = 5 * np.sin(2 * np.pi * t) * np.exp(-0.3 * t) + 0.5 * np.sin(9 * t)
    np.testing.assert_allclose(pi(pi.inverse()(y)), y, atol=1e-9)
    np.testing.assert_allclose(pi.inverse()(pi(y)), y, atol=1e-9)


def test_generalized_play_with_identity_envelopes_is_the_play() -> None:
    v = 3 * np.sin(np.linspace(0, 12, 500)) + np.linspace(0, 1, 500)
    r = np.array(R_EX)
    ident = lambda u: u  # noqa: E731
    np.testing.assert_allclose(generalized_play(v, r, ident, ident), play(v, r), atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-10, 10), min_size=2, max_size=60), st.floats(0, 3))
def test_play_is_lipschitz_one(values: list[float], r: float) -> None:
    v = np.array(values)
    f = play(v, np.array([r]))[:, 0]
    g = play(v + 0.37, np.array([r]), w0=0.37)[:, 0]
    np.testing.assert_allclose(g - f, 0.37, atol=1e-9)  # shift equivariance
    assert np.all(np.abs(np.diff(f)) <= np.abs(np.diff(v)) + 1e-12)


def test_creep_step_response_closed_form() -> None:
    t = np.linspace(0, 50, 501)
    v = np.ones_like(t)
    lam = np.array([0.0127, 0.961])
    x = creep_operators(v, t, lam, x0=0.0)
    # x(k) uses v(k-1): after the first interval it follows 1 - exp(-Lambda t)
    np.testing.assert_allclose(x[1:], 1 - np.exp(-np.outer(t[1:], lam)), atol=1e-12)
    # irregular sampling gives the same values at the same times
    ti = np.r_[0.0, np.sort(np.random.default_rng(0).uniform(0, 50, 80)), 50.0]
    xi = creep_operators(np.ones_like(ti), ti, lam, x0=0.0)
    np.testing.assert_allclose(xi[-1], 1 - np.exp(-50 * lam), atol=1e-12)


def test_kinematics_constant_radius_hand_value() -> None:
    # 3-4-5 triangle: L0 = 5, T w = 3 -> L = 4; h = w^2 T / L
    assert length_constant_radius(3.0, 5.0, 1.0) == pytest.approx(4.0)
    assert reduction_ratio(3.0, 5.0, 1.0) == pytest.approx(3.0 / 4.0)
    assert reduction_ratio_linearised(3.0, 5.0, 1.0) == pytest.approx(3.0 / 5.0)
    assert np.isnan(length_constant_radius(6.0, 5.0, 1.0))


def test_reduction_ratio_is_minus_dl_dt_and_linearisation_at_zero() -> None:
    l0, w = 0.175, 0.65e-3
    t = np.linspace(1, 100, 50)
    d = 1e-6
    numeric = -(length_constant_radius(t + d, l0, w) - length_constant_radius(t - d, l0, w)) / (2 * d)
    np.testing.assert_allclose(reduction_ratio(t, l0, w), numeric, rtol=1e-5)
    small = 1e-3
    assert reduction_ratio(small, l0, w) == pytest.approx(reduction_ratio_linearised(small, l0, w), rel=1e-9)


def test_radius_growth_fixed_point_and_recursion() -> None:
    l0, w0 = 0.175, 0.65e-3
    tw = 15 * 2 * math.pi
    length, w = length_fixed_point(tw, l0, w0)
    assert length == pytest.approx(math.sqrt(l0 ** 2 - tw ** 2 * w ** 2), rel=1e-12)
    assert w == pytest.approx(w0 * math.sqrt(l0 / length), rel=1e-12)
    # the cubic L^3 - L0^2 L + T^2 w0^2 L0 = 0 (substituting eq. 4.5 into 4.4)
    assert length ** 3 - l0 ** 2 * length + tw ** 2 * w0 ** 2 * l0 == pytest.approx(0.0, abs=1e-15)
    # the thesis's recursion along a slow ramp approaches the fixed point
    ls, ws = length_with_radius_growth(np.linspace(0, tw, 2000), l0, w0)
    assert ls[-1] == pytest.approx(length, rel=1e-5) and ws[0] == pytest.approx(w0 * math.sqrt(l0 / l0))
    assert length < length_constant_radius(tw, l0, w0)  # growth shortens further


def test_manipulator_bending_range_is_about_60_degrees() -> None:
    g = ManipulatorGeometry(0.175, 16.75e-3, 0.65e-3)
    theta = np.degrees(bending_angle(np.linspace(3.0, 18.0, 1501) * 2 * np.pi, g))  # recursion along the ramp
    assert 57 < theta[-1] - theta[0] < 63
    const = np.degrees(bending_angle(np.array([3.0, 18.0]) * 2 * np.pi, g, radius_growth=False))
    assert const[1] - const[0] < theta[-1] - theta[0]  # radius growth bends further
    assert theta[0] == pytest.approx(np.degrees((0.175 - length_fixed_point(6 * np.pi, 0.175, 0.65e-3)[0]) / 16.75e-3),
                                     abs=0.05)


def test_velocity_models_order_and_savgol_derivative() -> None:
    rate = 53.9
    t = np.arange(0, 6, 1 / rate)
    x = 2.0 * t ** 3
    np.testing.assert_allclose(savgol_derivative(x, rate), 6.0 * t ** 2, rtol=1e-6, atol=1e-6)
    g = ManipulatorGeometry()
    m = velocity_models((3 + 1.9 * t) * 2 * np.pi, g, rate)
    mid = slice(200, -200)
    assert np.all(m["complete"][mid] > m["conventional"][mid]) and np.all(m["conventional"][mid] > m["linearised"][mid])
    np.testing.assert_allclose(m["tdot_rad_per_s"][mid], 1.9 * 2 * np.pi, rtol=1e-9)
    # the complete model is the time derivative of eq. 4.8
    np.testing.assert_allclose(m["complete"][mid], np.gradient(m["theta_rad"], 1 / rate)[mid], rtol=2e-3)


def test_metrics_hand_values() -> None:
    meas = np.array([10.0, 10.0, 10.0, 10.0])
    pred = np.array([11.0, 9.0, 10.0, 12.0])
    assert e_aver(meas, pred) == pytest.approx(1.0)
    assert sigma(meas, pred) == pytest.approx(math.sqrt(((0) ** 2 * 2 + 1 + 1) / 3))
    m = compare(meas, pred, "mm")
    assert m.mean_percent == pytest.approx(10.0) and m.max_percent == pytest.approx(20.0) and m.n == 4


def test_polynomial_recovers_coefficients() -> None:
    q = np.linspace(-3, 5, 200)
    y = 28.54 - 0.010 * q - 0.001 * q ** 2 + 0.0005 * q ** 3
    model = PolynomialModel.fit(q, y)
    np.testing.assert_allclose(model.coefficients, [28.54, -0.010, -0.001, 0.0005], atol=1e-9)


def test_preisach_fits_a_hysteretic_loop_better_than_a_polynomial() -> None:
    t = np.linspace(0, 4, 4000)
    u = 10 * np.abs(np.sin(np.pi * t))
    y = play(u, np.array([0.0, 2.0, 4.0]), w0=0.0) @ np.array([0.2, 0.4, 0.4])
    late = t > 1.0  # after the first full cycle both memories are saturated at u = 0
    pre = PreisachModel.fit(u, np.where(late, y, np.nan), levels=20)
    poly = PolynomialModel.fit(u[late], y[late])
    assert e_aver(y[late], pre.predict(u)[late]) * 5 < e_aver(y[late], poly.predict(u)[late])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-5, 5), min_size=1, max_size=40), st.floats(5.5, 9))
def test_preisach_wiping_out_and_bounds(history: list[float], peak: float) -> None:
    m = 8
    states = relay_states(np.array(history + [peak]), -10, 10, m)
    fresh = relay_states(np.array([peak]), -10, 10, m)
    np.testing.assert_array_equal(states[-1], fresh[-1])  # a new maximum wipes out the memory below it
    w = np.random.default_rng(len(history)).uniform(0, 1, m * (m + 1) // 2)
    model = PreisachModel(m, -10, 10, tuple(w), 0.5, 1.0)
    y = model.predict(np.array(history))
    assert np.all(y >= 0.5 - 1e-12) and np.all(y <= 0.5 + w.sum() + 1e-12)
