"""Diagnose's cheaper replays give the numbers of the plain ones: a memoryless plant simulated
once per distinct input row, a plant remembering only the last motor stop replayed without
the turning points and, for scores alone, on the held-out samples and their pauses; the
structure tests' normal-equation path for long residuals; and a diagnosis through that path.

Small synthetic histories; the 10x lifetime figures are printed by scripts/bench/diagnose_speed.py."""

from __future__ import annotations

import numpy as np
import pytest

from tests.analysis import hidden
from tests.analysis.test_replay_bounded import _inputs
from tsa_bench.analysis import diagnose, load_model
from tsa_bench.analysis import structure
from tsa_bench.analysis.holdout import split
from tsa_bench.analysis.modelspec import switch
from tsa_bench.analysis.replay import ReplayCache, deterministic, memory, replay, replay_samples, scoring_samples
from tsa_bench.analysis.scoring import all_units, unit_scores
from tsa_bench.analysis.signals import RunBases
from tsa_bench.sim.history import simulate
from tsa_bench.store import read_run

STOP_FORMS = ("resistance_transient_decay", "resistance_transient_stretched", "resistance_transient_two_exp")


def _plain(cfg: dict, inp) -> tuple[np.ndarray, np.ndarray]:
    """The reference: the deterministic plant sampled on every sample, in order."""
    out = simulate(deterministic(cfg), inp.t, inp.turns, inp.volts, inp.load_g, inp.moving, seed=0)
    return out["length_mm"], out["resistance_ohm"]


def _with_load_steps(cycles: int):
    inp = _inputs(cycles)
    inp.load_g = np.where(np.arange(len(inp)) > len(inp) // 2, 450.0, inp.load_g)   # a second load
    return inp


def test_memory_kinds_of_the_baseline_and_its_candidates():
    m = load_model(None)
    assert memory(deterministic(m)) == "none"
    for form in STOP_FORMS:
        assert memory(deterministic(switch(m, form, True))) == "stop"
    for form in ("twist_hysteresis", "thermal_dynamics", "resistance_creep", "length_creep", "load_dependence",
                 "missed_steps", "resistance_hysteresis"):
        assert memory(deterministic(switch(m, form, True))) == "path", form


def test_a_memoryless_plant_replayed_once_per_distinct_row_gives_the_same_numbers():
    inp = _with_load_steps(6)
    cfg = load_model(None)
    ref_l, ref_r = _plain(cfg, inp)
    cache = ReplayCache()
    for idx in (None, replay_samples(inp, len(inp), 150)[0]):
        for _ in range(2):                   # the second time from the cached row grouping
            length, res = replay(cfg, inp, idx, cache)
            sel = slice(None) if idx is None else idx
            assert np.array_equal(length, ref_l[sel]) and np.array_equal(res, ref_r[sel])
            cache._items.clear()
    assert len(cache.rows) == 2
    assert len(np.unique(np.c_[inp.turns, inp.load_g], axis=0)) < len(inp) / 2     # the grouping does save work


@pytest.mark.parametrize("form", STOP_FORMS)
def test_a_plant_remembering_the_last_stop_needs_no_turning_points(form):
    inp = _inputs(60)
    cfg = switch(load_model(None), form, True)
    idx, state = replay_samples(inp, len(inp), 25)
    assert len(state) > 0
    _, ref_r = _plain(cfg, inp)
    _, r_state = replay(cfg, inp, idx, state=state)
    assert np.allclose(r_state, ref_r[idx], rtol=0, atol=1e-12)


@pytest.mark.parametrize("form", (None, *STOP_FORMS, "twist_hysteresis"))
def test_scores_alone_from_the_held_out_samples_equal_the_full_replay_scores(form):
    inp = _with_load_steps(8)
    inp.segment = np.cumsum(np.r_[0, np.diff(inp.turns) != 0]) // 7      # segments to cut units at
    split([inp], "fraction:0.3")
    units = all_units([inp])
    cfg = load_model(None) if form is None else switch(load_model(None), form, True)
    sigma = {"length": 0.05, "resistance": 0.001}
    full = unit_scores(cfg, [inp], units, sigma, ("length", "resistance"))
    alone = unit_scores(cfg, [inp], units, sigma, ("length", "resistance"), keep_sims=False)
    assert alone.sims == [] and len(full.sims) == 1
    assert np.array_equal(full.sse, alone.sse) and np.array_equal(full.count, alone.count)
    held = np.flatnonzero(inp.heldout)
    at = scoring_samples(inp, held)
    assert len(at) < 0.6 * len(inp) and np.isin(held, at).all()


def test_scoring_samples_keep_the_whole_pause_before_a_still_start():
    inp = _inputs(2)
    mv = inp.moving
    still = np.flatnonzero(~mv[1:-1] & ~mv[:-2] & ~mv[2:]) + 1    # a sample inside a pause
    start = int(still[len(still) // 2])
    at = scoring_samples(inp, np.arange(start, start + 3))
    stop = int(np.flatnonzero(mv[:start])[-1])                  # the last moving sample before it
    assert np.array_equal(at, np.arange(stop, start + 3))


def test_long_residuals_regressed_through_the_normal_equations_agree(monkeypatch):
    inp = _inputs(10)
    rng = np.random.default_rng(3)
    res = 0.002 * np.sin(inp.t / 7.0) + 0.01 * inp.moving + rng.normal(0, 0.01, len(inp))
    res[::97] = np.nan
    exact = structure._signal_fits(res, RunBases([inp]))
    exact_lb = structure.ljung_box(res)
    monkeypatch.setattr(structure, "LEAN_N", 100)
    lean = structure._signal_fits(res, RunBases([inp]))
    assert [f["signal"] for f in lean] == [f["signal"] for f in exact]
    for a, b in zip(exact, lean):
        assert a["r2"] == pytest.approx(b["r2"], rel=1e-8, abs=1e-14)
        assert a["p"] == pytest.approx(b["p"], rel=1e-6, abs=1e-300)
    assert structure.ljung_box(res) == pytest.approx(exact_lb, rel=1e-8)


def test_diagnosis_through_the_long_residual_path_names_the_hidden_decay(tmp_path, monkeypatch):
    monkeypatch.setattr(structure, "LEAN_N", 1000)
    info = hidden.generate(tmp_path / "run.h5", ("resistance_transient_decay",), seed=1, short=True)
    assert info["n"] > 1000
    result = diagnose([read_run(info["path"])], load_model(None), max_causes=1)
    assert result.verdict == "named" and result.causes == ["resistance_transient_decay"], result.summary
    assert result.named[0].variant == "resistance_transient_decay"
