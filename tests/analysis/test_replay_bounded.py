"""Diagnose's replays stay bounded on long runs: the replay cache, the turning points
replayed for the plant state only, and the signal bases built one at a time.

Small histories (a few thousand samples); the 10x lifetime figures are printed by
scripts/bench/speed_limits.py --long and scripts/bench/diagnose_speed.py, not asserted."""

from __future__ import annotations

import numpy as np

from tests.analysis import hidden
from tsa_bench.analysis import load_model
from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.modelspec import switch
from tsa_bench.analysis.replay import STATE_ONLY, ReplayCache, replay, replay_samples, subsample
from tsa_bench.analysis.signals import RunBases, signal_bases


def _inputs(cycles: int, seed: int = 0) -> RunInputs:
    steps = [("load", 550), ("move", 15, 3.33), ("hold", 20)]
    for _ in range(cycles):
        for x in (17, 19, 21, 23, 25, 23, 21, 19, 17, 15):
            steps += [("move", x, 3.33, "cycle"), ("hold", 1.0, "cycle")]
    steps += [("move", 0, 3.33), ("hold", 10)]
    h = hidden.history(steps, 550)
    n = len(h["t"])
    rng = np.random.default_rng(seed)
    return RunInputs(h["t"], h["turns"], h["heater_voltage"], h["load_g"], h["motor_moving"].astype(bool),
                     250 + rng.normal(0, 0.01, n), 6 + rng.normal(0, 0.001, n), np.zeros(n, int),
                     heldout=np.zeros(n, bool), scored=np.ones(n, bool))


def _turning_points(turns: np.ndarray) -> np.ndarray:
    d = np.diff(turns)
    nz = np.flatnonzero(d != 0)
    sd = np.sign(d[nz])
    return nz[1:][sd[1:] != sd[:-1]]


def test_cache_returns_the_same_replay_read_only_and_evicts_by_size():
    inp = _inputs(3)
    cfg = load_model(None)
    cache = ReplayCache()
    idx = subsample(inp, len(inp), 200)
    first = replay(cfg, inp, idx, cache)
    again = replay(cfg, inp, idx, cache)
    plain = replay(cfg, inp, idx)
    assert cache.hits == 1 and cache.misses == 1
    assert all(np.array_equal(a, b) for a, b in zip(again, plain))
    assert not again[0].flags.writeable and plain[0].flags.writeable
    other = replay(switch(cfg, "resistance_creep", True), inp, idx, cache)
    assert cache.misses == 2 and not np.array_equal(other[1], first[1])
    full = replay(cfg, inp, None, cache)
    assert len(full[0]) == len(inp)
    small = ReplayCache(max_bytes=3 * first[0].nbytes)          # room for one subsample replay (two arrays)
    for k in range(4):
        replay(set_radius(cfg, 0.5 + 0.001 * k), inp, idx, small)
    assert small._bytes <= small.max_bytes and len(small._items) == 1
    replay(set_radius(cfg, 0.503), inp, idx, small)
    assert small.hits == 1
    replay(cfg, inp, None, small)                                  # larger than the whole cache: not kept
    assert len(small._items) == 1


def set_radius(cfg: dict, r: float) -> dict:
    from tsa_bench.analysis.modelspec import set_values
    return set_values(cfg, {"geometry.radius_mm": r})


def test_short_run_keeps_every_turning_point_in_the_compared_samples():
    inp = _inputs(5)
    idx, state = replay_samples(inp, len(inp), 400)
    assert len(_turning_points(inp.turns)) <= STATE_ONLY * 400
    assert len(state) == 0 and np.array_equal(idx, subsample(inp, len(inp), 400))


def test_long_run_compares_a_bounded_subsample_and_replays_turning_points_for_the_state():
    target = 25
    sizes = []
    for cycles in (40, 120):
        inp = _inputs(cycles)
        idx, state = replay_samples(inp, len(inp), target)
        tp = _turning_points(inp.turns)
        assert len(tp) > STATE_ONLY * target
        assert len(state) > 0 and np.intersect1d(idx, state).size == 0
        assert np.array_equal(np.union1d(idx, state)[np.isin(np.union1d(idx, state), tp)], tp)   # all replayed
        assert len(idx) < len(subsample(inp, len(inp), target))
        sizes.append(len(idx))
    # three times the cycles: the compared samples grow far less than the run
    assert sizes[1] < 1.5 * sizes[0]


def test_replaying_the_turning_points_keeps_wear_and_hysteresis_state():
    inp = _inputs(60)
    cfg = switch(switch(load_model(None), "resistance_creep", True, {"ohm_per_turn": 2e-4}), "twist_hysteresis", True)
    idx, state = replay_samples(inp, len(inp), 25)
    assert len(state) > 0
    full_l, full_r = replay(cfg, inp)
    l_state, r_state = replay(cfg, inp, idx, state=state)
    _, r_none = replay(cfg, inp, idx)
    err_state = np.max(np.abs(r_state - full_r[idx]))
    err_none = np.max(np.abs(r_none - full_r[idx]))
    # without the turning points the cumulative travel (wear) is lost between compared samples
    assert err_none > 20 * max(err_state, 1e-6), (err_state, err_none)
    assert err_state < 1e-3
    assert np.max(np.abs(l_state - full_l[idx])) < 0.05


def test_bases_one_at_a_time_equal_the_whole_set():
    a, b = _inputs(2, seed=1), _inputs(3, seed=2)
    lazy = RunBases([a, b], 5.5)
    whole = [signal_bases(a, 5.5), signal_bases(b, 5.5)]
    assert list(lazy) == list(whole[0]) and len(lazy) == len(whole[0])
    for name in lazy:
        assert np.array_equal(lazy[name], np.concatenate([w[name] for w in whole]))


def test_chunked_replay_equals_one_pass(monkeypatch):
    import tsa_bench.analysis.replay as rp
    from tsa_bench.sim.history import simulate
    inp = _inputs(8)
    cfg = switch(switch(load_model(None), "resistance_creep", True), "twist_hysteresis", True)
    one = simulate(rp.deterministic(cfg), inp.t, inp.turns, inp.volts, inp.load_g, inp.moving, seed=0)
    monkeypatch.setattr(rp, "CHUNK", 397)
    assert len(inp) > 3 * 397
    length, res = replay(cfg, inp)
    assert np.array_equal(length, one["length_mm"]) and np.array_equal(res, one["resistance_ohm"])
