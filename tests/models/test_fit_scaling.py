"""The long-run forms of the fits give what the direct forms give.

``quasi_static_mask`` groups samples by segment in one pass, and the Preisach fit builds
its relay states block by block and solves one weighted row per distinct state; both
are checked against the straightforward forms (a loop over segments; the whole design
matrix in one non-negative least squares)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import nnls

from tsa_bench.models.fit_samples import quasi_static_mask
from tsa_bench.models.preisach import PreisachModel, relay_state_blocks, relay_states
from tsa_bench.rundata import RunData


def loop_mask(t: np.ndarray, seg: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Motor stopped and in the last third of its segment, one segment at a time."""
    mask = np.zeros(len(t), bool)
    for s in np.unique(seg):
        idx = np.flatnonzero((seg == s) & ~moving)
        if len(idx):
            t0, t1 = t[idx[0]], t[idx[-1]]
            mask[idx[t[idx] >= t0 + 2.0 * (t1 - t0) / 3.0]] = True
    return mask


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 400), st.integers(1, 8), st.booleans(), st.integers(0, 2**31))
def test_quasi_static_mask_equals_the_loop_over_segments(n, n_seg, with_nan, seed):
    rng = np.random.default_rng(seed)
    seg = rng.integers(0, n_seg, n)
    if with_nan:     # an imported file's float segment column may hold NaN
        seg = seg.astype(float)
        seg[rng.random(n) < 0.1] = np.nan
    moving = rng.random(n) < 0.3
    t = np.sort(rng.random(n)) * 100
    samples = {"t": t, "segment": seg, "motor_moving": moving.astype(np.uint8), "turns": rng.random(n)}
    run = RunData("x.h5", {}, samples, dict.fromkeys(samples, ""), segments=np.zeros(1))
    expected = loop_mask(t, seg, moving) if (seg >= 0).any() else np.ones(n, bool)  # no segments: used whole
    assert np.array_equal(quasi_static_mask(run, "turns"), expected)


def test_relay_states_in_blocks_equal_the_whole_history():
    rng = np.random.default_rng(1)
    u = np.cumsum(rng.normal(0, 0.5, 3000))
    whole = relay_states(u, u.min(), u.max(), 12)
    for block in (1, 7, 1000, 5000):
        assert np.array_equal(np.vstack([b for _, b in relay_state_blocks(u, u.min(), u.max(), 12, block)]), whole)


def test_preisach_fit_equals_the_dense_least_squares():
    rng = np.random.default_rng(2)
    n = 4000
    u = 15 + 10 * np.sin(np.linspace(0, 25, n)) + 0.05 * rng.normal(size=n)
    truth = PreisachModel(10, u.min() - 1e-6, u.max() + 1e-6, tuple(rng.random(55)), 3.0, -1.0)
    y = np.concatenate([truth.predict(u[:2500]), truth.predict(u[2500:])]) + 0.01 * rng.normal(size=n)
    y[rng.random(n) < 0.2] = np.nan
    model = PreisachModel.fit([u[:2500], u[2500:]], [y[:2500], y[2500:]], levels=10)
    # the direct form: every sample a row of [sign * states, +1, -1]
    states = np.vstack([relay_states(a, model.u_min, model.u_max, 10) for a in (u[:2500], u[2500:])])
    ok = np.isfinite(y)
    design = np.hstack([states[ok] * model.sign, np.ones((ok.sum(), 1)), -np.ones((ok.sum(), 1))])
    coef, _ = nnls(design, y[ok], maxiter=50 * design.shape[1])
    direct = design @ coef
    ours = model.offset + model.sign * states[ok] @ np.asarray(model.weights)
    assert np.abs(ours - direct).max() < 1e-9
    assert np.sqrt(np.mean((ours - y[ok]) ** 2)) < 0.011   # the noise, not the model, is left


@pytest.mark.parametrize("dense_max", [10**9, 0])   # the direct form, and levels taken out first
def test_the_transient_decay_fit_equals_the_full_problem_with_one_level_per_curve(monkeypatch, dense_max):
    """Curve levels taken out first give the same b1, b2 and levels as the dense formulation
    (one column per curve), which grows as samples x curves and stalled a day-long run."""
    from scipy.optimize import lsq_linear

    from tsa_bench.models import transient
    from tsa_bench.models.transient import EPS_S, fit_decay

    monkeypatch.setattr(transient, "DENSE_MAX_ENTRIES", dense_max)

    rng = np.random.default_rng(5)
    curves = []
    for i in range(25):
        dt = np.sort(rng.uniform(0.0, 150.0, int(rng.integers(0, 40))))
        y = 5.0 + rng.normal(0, 0.1) - 2e-3 * np.log(dt + EPS_S) ** 2 - 4e-3 * np.log(dt + EPS_S) \
            + rng.normal(0, 1e-3, len(dt))
        if len(dt) > 3:
            y[1] = np.nan
        curves.append((dt, y))
    b1, b2, levels = fit_decay(curves)
    blocks, rhs = [], []
    for i, (dt, y) in enumerate(curves):
        ok = np.isfinite(y)
        lg = np.log(dt[ok] + EPS_S)
        block = np.zeros((ok.sum(), len(curves) + 2))
        block[:, 0], block[:, 1], block[:, 2 + i] = lg * lg, lg, 1.0
        blocks.append(block)
        rhs.append(y[ok])
    hi = np.r_[0.0, 0.0, np.full(len(curves), np.inf)]
    full = lsq_linear(np.vstack(blocks), np.concatenate(rhs), bounds=(-np.inf, hi), method="bvls").x
    assert b1 == pytest.approx(full[0], abs=1e-9) and b2 == pytest.approx(full[1], abs=1e-9) and b1 < 0
    has = np.array([np.isfinite(y).any() for _, y in curves])
    np.testing.assert_allclose(levels[has], full[2:][has], atol=1e-8)
    assert np.isnan(levels[~has]).all() and (~has).any()
