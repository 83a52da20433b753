"""A model's gain over another with a block-bootstrap interval over holds, split on and off the training grid.

Units: lengths and RMSE in mm, twist in turns, heater voltage in V, gains in percent.

Contract: :func:`hold_errors` fits the additive (thesis eq. 3.3) and the coupled twist-and-heat
forms on training runs and returns one :class:`Hold` per hold (segment) of each run scored: its
quasi-static samples' summed squared errors under both forms, its twist and voltage, and
whether that twist/voltage pair was held in the training runs (*on grid*: within
:data:`GRID_TOL_TURNS` and :data:`GRID_TOL_V` of a training hold). The gain of a set of holds
is ``100 (1 - RMSE_coupled / RMSE_additive)`` over their samples pooled;
:func:`gain_with_interval` adds the 95 % percentile interval of that gain when the holds are
resampled with replacement (a block bootstrap: the samples of one hold are correlated, the
holds nearly independent; :data:`N_BOOT` resamples, fixed seed, so the interval is
reproducible) and the share of the gain the three largest holds carry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

GRID_TOL_TURNS = 0.01
GRID_TOL_V = 0.01
N_BOOT = 2000


@dataclass(frozen=True)
class Hold:
    """One hold's quasi-static samples under both forms (squared errors summed, mm^2)."""

    run: str
    segment: int
    turns: float
    voltage_V: float
    n: int
    sse_additive: float
    sse_coupled: float
    length_mm: float
    on_grid: bool = False


@dataclass(frozen=True)
class Gain:
    """A gain (percent) with its bootstrap interval over holds and what carried it."""

    holds: int
    samples: int
    rmse_additive_mm: float
    rmse_coupled_mm: float
    gain_percent: float
    low_percent: float
    high_percent: float
    top3_share: float


def _holds_of(run: Any, models: dict[str, Any]) -> list[Hold]:
    from tsa_bench.models.twist_heat import ADDITIVE, COUPLED, predict_run

    pa, mask = predict_run(models[ADDITIVE], run)
    pc, _ = predict_run(models[COUPLED], run)
    y = np.asarray(run.samples["length"], float)
    seg = np.asarray(run.samples["segment"])
    t = np.asarray(run.samples["turns"], float)
    v = np.asarray(run.samples["heater_voltage"], float)
    out = []
    for s in np.unique(seg[mask]):
        idx = np.flatnonzero(mask & (seg == s))
        out.append(Hold(str(run.path), int(s), float(np.median(t[idx])), float(np.median(v[idx])), len(idx),
                        float(np.sum((pa[idx] - y[idx]) ** 2)), float(np.sum((pc[idx] - y[idx]) ** 2)),
                        float(np.mean(y[idx]))))
    return out


def hold_errors(train: list[Any], scored: list[Any]) -> tuple[list[Hold], list[Hold]]:
    """(training holds, scored holds) under both forms fitted on ``train`` (module contract)."""
    from tsa_bench.models.twist_heat import NAMES, fit_saved, to_model

    models = {name: to_model(fit_saved(name, train)) for name in NAMES}
    tr = [h for r in train for h in _holds_of(r, models)]
    grid = np.array([(h.turns, h.voltage_V) for h in tr])

    def on_grid(h: Hold) -> bool:
        return bool(np.any((np.abs(grid[:, 0] - h.turns) <= GRID_TOL_TURNS)
                           & (np.abs(grid[:, 1] - h.voltage_V) <= GRID_TOL_V)))
    tr = [Hold(**{**h.__dict__, "on_grid": True}) for h in tr]
    return tr, [Hold(**{**h.__dict__, "on_grid": on_grid(h)}) for h in scored_holds(scored, models)]


def scored_holds(runs: list[Any], models: dict[str, Any]) -> list[Hold]:
    """Every hold of ``runs`` under ``models`` (name -> fitted twist-heat model)."""
    return [h for r in runs for h in _holds_of(r, models)]


def _gain(sse_a: np.ndarray, sse_c: np.ndarray) -> np.ndarray:
    return 100.0 * (1.0 - np.sqrt(sse_c / sse_a))


def gain_with_interval(holds: list[Hold], n_boot: int = N_BOOT, seed: int = 0, level: float = 0.95) -> Gain:
    """Pooled gain of ``holds`` with its block-bootstrap interval (module contract)."""
    if not holds:
        raise ValueError("no holds to compute a gain on")
    a = np.array([h.sse_additive for h in holds])
    c = np.array([h.sse_coupled for h in holds])
    n = np.array([h.n for h in holds])
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, len(holds), size=(n_boot, len(holds)))
    boot = _gain(a[pick].sum(axis=1), c[pick].sum(axis=1))
    lo, hi = np.percentile(boot, [50 * (1 - level), 50 * (1 + level)])
    gained = np.sort(a - c)[::-1]
    total = float(np.sum(a - c))
    top3 = float(np.sum(gained[:3]) / total) if total > 0 else float("nan")
    return Gain(len(holds), int(n.sum()), float(np.sqrt(a.sum() / n.sum())), float(np.sqrt(c.sum() / n.sum())),
                float(_gain(np.array(a.sum()), np.array(c.sum()))), float(lo), float(hi), top3)


def heating_effect_mm(holds: list[Hold]) -> float:
    """The largest change of the hold-mean length with the voltage at one twist (mm): how much heating moves it."""
    by_twist: dict[float, list[float]] = {}
    for h in holds:
        by_twist.setdefault(round(h.turns, 2), []).append(h.length_mm)
    return max((max(v) - min(v) for v in by_twist.values()), default=0.0)


__all__ = ["Gain", "Hold", "N_BOOT", "gain_with_interval", "heating_effect_mm", "hold_errors", "scored_holds"]
