"""Deterministic replay of recorded inputs through a plant config, on all or some samples.

Units: as :mod:`tsa_bench.analysis.inputs`.

Contract: :func:`replay` runs the plant with its random parts (sensor noise, quantisation,
settling offsets: :data:`RANDOM_PARTS`) off on the run's samples ``idx`` (sorted; default all), from a fresh plant at the
run's start. On a subsample ``motor_moving`` is the OR over the skipped samples, so
no motor stop is lost, and a few samples before each kept sample whose twist or load
changed are simulated too (not returned), so state lagging one sample replays at the
true spacing. Where the config's plant has no memory beyond the present sample
(:func:`memory` "none": every effect in :data:`MEMORYLESS`) each distinct (twist, load,
heater, motor) row is simulated once and the result spread to its samples (the same
numbers, sample for sample); where it remembers only the last motor stop ("stop"), the
``state`` samples (twist turning points) and the context samples are not simulated, the
stops themselves being among ``idx``. A :class:`ReplayCache` (one per diagnosis) keeps
recent replays keyed by the config, the run and the subsample, so a config replayed again
(the optimiser's start, the final fit, a score asked for twice) costs nothing; the arrays it
returns are read-only.
:func:`subsample` picks a few thousand indices keeping every heater and
load change (and motor start/stop when affordable, else short windows after evenly
spread stops), and for every kept still sample the stop that began its pause.
"""

from __future__ import annotations

import hashlib
import json
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

import numpy as np

from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.modelspec import set_values
from tsa_bench.sim.history import simulate
from tsa_bench.sim.plant import plant_from_config

#: samples simulated before a kept sample whose twist or load changed (see :func:`_with_context`)
CONTEXT = 3
#: samples per call of the plant's history loop: one plant runs through the chunks (the same
#: replay), and the loop's per-sample Python lists stay small on a long run
CHUNK = 1 << 16
#: turning points per target sample beyond which they are replayed for the state only (:func:`replay_samples`)
STATE_ONLY = 2
#: effects that only draw random numbers (their mean is 0): a deterministic replay leaves them out
RANDOM_PARTS = ("sensor_noise", "quantisation", "length_settling", "resistance_settling")
#: effects whose outputs are a function of the present sample's twist and load alone while
#: thermal_dynamics is off (the strings then stay at ambient): no state flows between samples
MEMORYLESS = frozenset({"string_compliance", "radius_growth", "thermal_contraction", "resistance_length",
                        "resistance_temperature"})
#: effects that remember only the time since the motor last stopped (``t_since_stop_s``)
STOP_MEMORY = frozenset({"resistance_transient_decay", "resistance_transient_stretched",
                         "resistance_transient_two_exp"})


#: the plant's effect names by the effects' switches (an effect is built when its ``enabled``,
#: or its default when absent, is true), so :func:`memory` builds a plant once per set of switches
_EFFECT_SETS: dict[tuple, frozenset] = {}


def memory(cfg: Mapping[str, Any]) -> str:
    """What a replay of ``cfg`` (a :func:`deterministic` config) must carry between samples:
    "none" (every effect in :data:`MEMORYLESS`), "stop" (also :data:`STOP_MEMORY`: the time
    since the last motor stop) or "path" (anything else: twist path, time, temperature)."""
    fx = cfg.get("effects") or {}
    key = tuple(sorted((k, v.get("enabled", "default") if isinstance(v, Mapping) else v) for k, v in fx.items()))
    names = _EFFECT_SETS.get(key)
    if names is None:
        names = _EFFECT_SETS[key] = frozenset(e.name for e in plant_from_config(cfg, seed=0).effects)
        if len(_EFFECT_SETS) > 256:
            _EFFECT_SETS.pop(next(iter(_EFFECT_SETS)))
    if names <= MEMORYLESS:
        return "none"
    if names <= MEMORYLESS | STOP_MEMORY:
        return "stop"
    return "path"


def deterministic(plant_cfg: Mapping[str, Any]) -> dict:
    cfg = set_values(plant_cfg, {})
    for name in RANDOM_PARTS:
        cfg["effects"].setdefault(name, {})["enabled"] = False
    return cfg


class ReplayCache:
    """Least-recently-used replays, at most ``max_bytes`` of output arrays in all and none
    larger than ``max_item_bytes`` (a day of full-resolution replays, rarely asked for twice,
    is not kept).

    A replay is deterministic (noise off, fixed seed), so its result is a function of the
    config, the run and the samples asked for: the key is the config's canonical JSON, the
    run's identity (the cache lives no longer than the runs it was made for) and a digest of
    ``idx``.
    """

    def __init__(self, max_bytes: int = 48 * 2 ** 20, max_item_bytes: int = 4 * 2 ** 20) -> None:
        self.max_bytes = int(max_bytes)
        self.max_item_bytes = int(max_item_bytes)
        self._items: OrderedDict[tuple, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self._bytes = 0
        self.hits = 0
        self.misses = 0
        #: distinct input rows of recent sample sets (:func:`_row_groups`), a config-free
        #: grouping every memoryless replay on the same samples shares
        self.rows: OrderedDict[tuple, tuple[list[np.ndarray], np.ndarray]] = OrderedDict()

    @staticmethod
    def key(cfg: Mapping[str, Any], inp: RunInputs, idx: np.ndarray | None, state: np.ndarray | None = None
            ) -> tuple:
        subs = tuple(None if a is None else (len(a), hashlib.blake2b(np.ascontiguousarray(a, np.int64).tobytes(),
                                                                     digest_size=16).digest()) for a in (idx, state))
        return json.dumps(cfg, sort_keys=True, default=str), id(inp), subs

    def get(self, key: tuple) -> tuple[np.ndarray, np.ndarray] | None:
        out = self._items.get(key)
        if out is None:
            self.misses += 1
            return None
        self._items.move_to_end(key)
        self.hits += 1
        return out

    def put(self, key: tuple, value: tuple[np.ndarray, np.ndarray]) -> None:
        size = sum(a.nbytes for a in value)
        if size > min(self.max_bytes, self.max_item_bytes):
            return
        for a in value:
            a.setflags(write=False)
        old = self._items.pop(key, None)
        if old is not None:
            self._bytes -= sum(a.nbytes for a in old)
        self._items[key] = value
        self._bytes += size
        while self._bytes > self.max_bytes:
            _, dropped = self._items.popitem(last=False)
            self._bytes -= sum(a.nbytes for a in dropped)


def replay(plant_cfg: Mapping[str, Any], inp: RunInputs, idx: np.ndarray | None = None,
           cache: ReplayCache | None = None, state: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(length_mm, resistance_ohm) of the noise-free plant at samples ``idx`` (read-only
    arrays when ``cache`` is given); samples ``state`` (with ``idx`` only) are simulated too,
    without context, and not returned."""
    cfg = deterministic(plant_cfg)
    if cache is None:
        return _replay(cfg, inp, idx, state)
    key = cache.key(cfg, inp, idx, state)
    out = cache.get(key)
    if out is None:
        out = _replay(cfg, inp, idx, state, cache, key[1:])
        cache.put(key, out)
    return out


def _replay(cfg: dict, inp: RunInputs, idx: np.ndarray | None, state: np.ndarray | None = None,
            cache: ReplayCache | None = None, rows_key: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    mem = memory(cfg)
    if mem == "none":
        groups = None
        if cache is not None and rows_key is not None:
            groups = cache.rows.get(rows_key)
            if groups is None:
                groups = cache.rows[rows_key] = _row_groups(inp, idx)
                while len(cache.rows) > 4:
                    cache.rows.popitem(last=False)
            else:
                cache.rows.move_to_end(rows_key)
        return _memoryless(cfg, groups if groups is not None else _row_groups(inp, idx))
    if mem == "stop":
        state = None
    if idx is None:
        return _simulate(cfg, inp.t, inp.turns, inp.volts, inp.load_g, inp.moving)
    idx = np.asarray(idx)
    if mem == "stop":      # nothing lags a sample: no context (the stops are among idx)
        run_idx, pos = idx, np.arange(len(idx))
    else:
        warm = None
        if (cfg["effects"].get("load_dependence") or {}).get("enabled", True) is not False and np.any(inp.volts > 0):
            warm = _warm(inp)
        run_idx, pos = _with_context(inp, idx, warm=warm)
    if state is not None and len(state):
        run_idx = np.union1d(run_idx, state)
        pos = np.searchsorted(run_idx, idx)
    c = np.cumsum(inp.moving.astype(np.int64))
    prev = np.r_[-1, run_idx[:-1]]
    moving = (c[run_idx] - np.where(prev >= 0, c[np.maximum(prev, 0)], 0)) > 0
    length, res = _simulate(cfg, inp.t[run_idx], inp.turns[run_idx], inp.volts[run_idx], inp.load_g[run_idx], moving)
    return length[pos], res[pos]


def _simulate(cfg: dict, t: np.ndarray, turns: np.ndarray, volts: np.ndarray, load_g: np.ndarray,
              moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(length_mm, resistance_ohm) of a fresh plant (seed 0) sampled on the history, :data:`CHUNK` samples a call."""
    n = len(t)
    if n <= CHUNK:
        out = simulate(cfg, t, turns, volts, load_g, moving, seed=0)
        return out["length_mm"], out["resistance_ohm"]
    plant = plant_from_config(cfg, seed=0)
    length, res = np.empty(n), np.empty(n)
    for a in range(0, n, CHUNK):
        b = min(n, a + CHUNK)
        out = simulate(plant, t[a:b], turns[a:b], volts[a:b], load_g[a:b], moving[a:b])
        length[a:b], res[a:b] = out["length_mm"], out["resistance_ohm"]
    return length, res


def _row_groups(inp: RunInputs, idx: np.ndarray | None) -> tuple[list[np.ndarray], np.ndarray]:
    """(distinct rows of (twist, load, heater, motor flag) among the samples ``idx`` (all when
    None), in sorted order; for each sample, which of them it is)."""
    sel = slice(None) if idx is None else np.asarray(idx)
    rows = [inp.turns[sel], inp.load_g[sel], inp.volts[sel], inp.moving[sel].astype(float)]
    n = len(rows[0])
    if n == 0:
        return [r[:0] for r in rows], np.zeros(0, np.int32)
    order = np.lexsort(rows[::-1])
    new = np.ones(n, bool)
    new[1:] = np.any([np.diff(r[order]) != 0 for r in rows], axis=0)
    inverse = np.empty(n, np.int32 if n < 2 ** 31 else np.int64)
    inverse[order] = np.cumsum(new) - 1
    first = order[new]
    return [r[first] for r in rows], inverse


def _memoryless(cfg: dict, groups: tuple[list[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A plant without memory on grouped samples (:func:`_row_groups`): each distinct row is
    simulated once, in sorted order, and spread back to its samples."""
    u, inverse = groups
    if len(inverse) == 0:
        return np.zeros(0), np.zeros(0)
    length, res = _simulate(cfg, np.arange(len(u[0]), dtype=float), u[0], u[2], u[1], u[3] > 0)
    return length[inverse], res[inverse]


def scoring_samples(inp: RunInputs, idx: np.ndarray) -> np.ndarray:
    """``idx`` (sorted) with, for each block of consecutive samples in it that begins with
    the motor still, the whole pause before it from the last moving sample on: a plant that
    remembers only the last motor stop (:func:`memory` "stop") replays on these exactly as
    on the whole run (the same time steps since the stop, the same motor flags)."""
    idx = np.asarray(idx, np.int64)
    if len(idx) == 0:
        return idx
    mv = inp.moving
    n = len(inp)
    st = np.where(np.r_[False, mv[:-1] & ~mv[1:]], np.arange(n), -1)
    np.maximum.accumulate(st, out=st)
    first = idx[np.r_[True, np.diff(idx) > 1]]
    first = first[~mv[first] & (st[first] > 0)]
    parts = [np.arange(st[b] - 1, b) for b in first]
    return np.unique(np.concatenate([idx, *parts])) if parts else idx


def _warm(inp: RunInputs, after_s: float = 300.0) -> np.ndarray:
    """Samples while the heater is on or within ``after_s`` of it (the strings' temperature moves)."""
    on = np.where(inp.volts > 0, np.arange(len(inp)), -1)
    np.maximum.accumulate(on, out=on)
    return (on >= 0) & (inp.t - inp.t[np.maximum(on, 0)] <= after_s)


def _with_context(inp: RunInputs, idx: np.ndarray, n_context: int = CONTEXT, warm: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Samples to simulate for outputs at ``idx`` (sorted), and where ``idx`` sits in them.

    Some plant state lags one sample (load_dependence's stiffness uses the previous
    sample's contraction), so where the twist or load changed since the previous kept
    sample, or (``warm``) the temperature may have, the ``n_context`` samples before are
    simulated too (not returned): that lag then acts at the true sample spacing and its
    error decays before the kept sample.
    """
    if len(idx) < 2 or n_context <= 0:
        return idx, np.arange(len(idx))
    tw, ld = inp.turns[idx], inp.load_g[idx]
    changed = (tw[1:] != tw[:-1]) | (ld[1:] != ld[:-1])
    if warm is not None:
        changed |= warm[idx[1:]]
    jump = np.flatnonzero(changed) + 1
    if len(jump) == 0:
        return idx, np.arange(len(idx))
    lo = np.maximum(idx[jump - 1] + 1, idx[jump] - n_context)
    extra = np.concatenate([np.arange(a, b) for a, b in zip(lo, idx[jump]) if a < b] or [np.zeros(0, int)])
    run_idx = np.unique(np.concatenate([idx, extra]))
    return run_idx, np.searchsorted(run_idx, idx)


def subsample(inp: RunInputs, stop: int, target: int) -> np.ndarray:
    """Sorted indices in [0, stop): every heater/load change and twist turning point, motor
    starts/stops if they fit, ~``target`` in all."""
    return replay_samples(inp, stop, target, split_state=False)[0]


def replay_samples(inp: RunInputs, stop: int, target: int, split_state: bool = True
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(idx, state): :func:`subsample`'s indices, except that on a long run with more than
    :data:`STATE_ONLY` x ``target`` twist turning points those are returned apart as
    ``state``: replayed so the plant state runs through them exactly (play operators,
    cumulative travel), but neither compared with the data nor given context or the stop of
    their pause, so the samples compared stay ~``target`` however long the run is."""
    none = np.zeros(0, int)
    if stop <= 0:
        return none, none
    if stop <= target:
        return np.arange(stop), none
    keep = [np.array([0, stop - 1])]
    for x in (inp.volts[:stop], inp.load_g[:stop]):
        ch = np.flatnonzero(np.diff(x) != 0)
        keep += [ch, ch + 1]
    mv = np.flatnonzero(np.diff(inp.moving[:stop].astype(np.int8)) != 0)
    if 2 * len(mv) <= 2 * target:
        keep += [mv, mv + 1]
    else:
        keep.append(_post_stop_windows(inp, stop, target // 3))
    # every turning point of the twist: between kept samples the twist is then monotone,
    # so play operators (hysteresis) and cumulative travel (wear creep) replay exactly
    d = np.diff(inp.turns[:stop])
    nz = np.flatnonzero(d != 0)
    state = none
    if len(nz) > 1:
        sd = np.sign(d[nz])
        turning = nz[1:][sd[1:] != sd[:-1]]
        if split_state and len(turning) > STATE_ONLY * target:
            state = turning
        else:
            keep.append(turning)
    n_uniform = max(target - sum(len(k) for k in keep), target // 3)
    keep.append(np.linspace(0, stop - 1, n_uniform).astype(int))
    idx = np.unique(np.concatenate(keep))
    idx = idx[(idx >= 0) & (idx < stop)]
    # every kept still sample also keeps the stop that began its pause (and the last moving
    # sample before it), so the replay's time since the stop is exact on the subsample
    mv = inp.moving[:stop]
    st = np.where(np.r_[False, mv[:-1] & ~mv[1:]], np.arange(stop), -1)
    np.maximum.accumulate(st, out=st)
    s0 = st[idx][~mv[idx] & (st[idx] > 0)]
    if len(s0):
        idx = np.unique(np.concatenate([idx, s0, s0 - 1]))
    return idx, np.setdiff1d(state, idx)


def _post_stop_windows(inp: RunInputs, stop: int, budget: int, width: int = 12) -> np.ndarray:
    """Too many motor stops to keep them all: whole short windows after evenly spread stops
    (last moving sample, then up to ``width`` samples of the pause), ~``budget`` samples in
    all, so the replay on the subsample sees those stops at their true time and the
    post-stop structure (e.g. resistance transient decay) is sampled densely."""
    mv = inp.moving[:stop]
    stops = np.flatnonzero(mv[:-1] & ~mv[1:]) + 1          # first still sample after a move
    if len(stops) == 0 or budget <= 0:
        return np.zeros(0, int)
    starts = np.flatnonzero(~mv[:-1] & mv[1:]) + 1
    nxt = np.searchsorted(starts, stops)
    end = np.where(nxt < len(starts), starts[np.minimum(nxt, len(starts) - 1)], stop)
    w = np.minimum(end - stops, width)
    n_win = max(1, min(len(stops), budget // max(1, int(np.median(w)) + 1)))
    pick = np.unique(np.linspace(0, len(stops) - 1, n_win).astype(int))
    parts = [np.arange(stops[i] - 1, stops[i] + w[i]) for i in pick]
    return np.concatenate(parts) if parts else np.zeros(0, int)
