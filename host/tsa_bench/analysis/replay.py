"""Deterministic replay of recorded inputs through a plant config, on all or some samples.

Units: as :mod:`tsa_bench.analysis.inputs`.

Contract: :func:`replay` runs the plant with ``sensor_noise`` and ``quantisation``
off on the run's samples ``idx`` (sorted; default all), from a fresh plant at the
run's start. On a subsample ``motor_moving`` is the OR over the skipped samples, so
no motor stop is lost. :func:`subsample` picks a few thousand indices keeping every
heater and load change (and motor start/stop when affordable).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.modelspec import set_values
from tsa_bench.sim.history import simulate


def deterministic(plant_cfg: Mapping[str, Any]) -> dict:
    cfg = set_values(plant_cfg, {})
    for name in ("sensor_noise", "quantisation"):
        cfg["effects"].setdefault(name, {})["enabled"] = False
    return cfg


def replay(plant_cfg: Mapping[str, Any], inp: RunInputs, idx: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(length_mm, resistance_ohm) of the noise-free plant at samples ``idx``."""
    cfg = deterministic(plant_cfg)
    if idx is None:
        out = simulate(cfg, inp.t, inp.turns, inp.volts, inp.load_g, inp.moving, seed=0)
        return out["length_mm"], out["resistance_ohm"]
    idx = np.asarray(idx)
    c = np.cumsum(inp.moving.astype(np.int64))
    prev = np.r_[-1, idx[:-1]]
    moving = (c[idx] - np.where(prev >= 0, c[np.maximum(prev, 0)], 0)) > 0
    out = simulate(cfg, inp.t[idx], inp.turns[idx], inp.volts[idx], inp.load_g[idx], moving, seed=0)
    return out["length_mm"], out["resistance_ohm"]


def subsample(inp: RunInputs, stop: int, target: int) -> np.ndarray:
    """Sorted indices in [0, stop): every heater/load change and twist turning point, motor
    starts/stops if they fit, ~``target`` in all."""
    if stop <= 0:
        return np.zeros(0, int)
    if stop <= target:
        return np.arange(stop)
    keep = [np.array([0, stop - 1])]
    for x in (inp.volts[:stop], inp.load_g[:stop]):
        ch = np.flatnonzero(np.diff(x) != 0)
        keep += [ch, ch + 1]
    mv = np.flatnonzero(np.diff(inp.moving[:stop].astype(np.int8)) != 0)
    if 2 * len(mv) <= 2 * target:
        keep += [mv, mv + 1]
    # every turning point of the twist: between kept samples the twist is then monotone,
    # so play operators (hysteresis) and cumulative travel (wear creep) replay exactly
    d = np.diff(inp.turns[:stop])
    nz = np.flatnonzero(d != 0)
    if len(nz) > 1:
        sd = np.sign(d[nz])
        keep.append(nz[1:][sd[1:] != sd[:-1]])
    n_uniform = max(target - sum(len(k) for k in keep), target // 3)
    keep.append(np.linspace(0, stop - 1, n_uniform).astype(int))
    idx = np.unique(np.concatenate(keep))
    return idx[(idx >= 0) & (idx < stop)]


def noise_level(x: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Sensor noise std from first differences (trimmed, robust to steps and quantisation)."""
    d = np.diff(x)
    ok = np.isfinite(d)
    if mask is not None:
        ok &= mask[1:] & mask[:-1]
    d = d[ok]
    if len(d) < 10:
        return float("nan")
    d2 = np.sort(d * d)
    d2 = d2[: max(1, int(0.95 * len(d2)))]
    return float(np.sqrt(0.5 * np.mean(d2) / 0.79))  # 0.79: second moment kept by a 95 % trim of a Gaussian
