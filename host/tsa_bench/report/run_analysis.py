"""Quantities the run figures show, computed from a run's samples (no plotting here).

Contract: every function takes a :class:`~tsa_bench.rundata.RunData` (columns in contract
units: s, turn, mm, ohm, V, N) and works from the samples alone, so recorded,
simulated and imported runs (which may lack ``/segments``) are treated alike. NaN
marks a value that was not measured and is skipped, never plotted as zero.

* :func:`plateaus` - contiguous stretches with the motor at rest and turns, heater
  voltage and load constant, with the steady-state length and resistance (median of the
  last ``tail`` fraction of the stretch);
* :func:`motor_stops` - the rest periods that begin when a move ends (for the transient
  decay on a log time axis, thesis Fig. 2.8(a)-(b));
* :func:`cycle_table` - per-cycle statistics of a repeat block (Fig. 2.8(d));
* :func:`stiffness_points` - normalized stiffness K = F L0 / (L - L0) from load steps at
  one twist level (eq. 2.1, Fig. 2.4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tsa_bench.rundata import RunData

#: Two readings of turns / voltage / load closer than these count as the same level.
TOL = {"turns": 1e-6, "heater_voltage": 1e-6, "load": 1e-6}


@dataclass(frozen=True)
class Plateau:
    """Samples ``[start, stop)`` at rest with constant inputs; values in contract units."""

    start: int
    stop: int
    t_start: float          # s
    t_end: float            # s
    turns: float            # turn
    heater_voltage: float   # V
    load: float             # N (NaN where undeclared)
    length: float           # mm, steady state (NaN if never measured)
    resistance: float       # ohm, steady state (NaN if never measured)
    after_move: bool        # the motor moved just before this rest

    @property
    def duration(self) -> float:
        return self.t_end - self.t_start


def finite_any(a: np.ndarray) -> bool:
    return bool(np.isfinite(np.asarray(a, dtype=float)).any())


def span(a: np.ndarray) -> float:
    """max - min over finite values (0 when none)."""
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    return float(a.max() - a.min()) if len(a) else 0.0


def _level_change(a: np.ndarray, tol: float) -> np.ndarray:
    """Boolean per sample boundary i (between i-1 and i): the level changed (NaN-aware)."""
    a = np.asarray(a, dtype=float)
    prev, cur = a[:-1], a[1:]
    both_nan = np.isnan(prev) & np.isnan(cur)
    return ~both_nan & ~(np.abs(cur - prev) <= tol)


def _tail_median(a: np.ndarray, tail: float) -> float:
    n = len(a)
    part = a[n - max(1, int(round(n * tail))):]
    part = np.sort(part[np.isfinite(part)])
    k = len(part)
    if not k:
        return float("nan")
    return float(part[k // 2]) if k % 2 else float(0.5 * (part[k // 2 - 1] + part[k // 2]))


def plateaus(run: RunData, min_samples: int = 3, tail: float = 0.2) -> list[Plateau]:
    """Rest stretches of at least ``min_samples`` samples; see the module contract.

    The result is cached in ``run.extra`` (the figures ask for it several times).
    """
    key = ("plateaus", min_samples, tail)
    if key not in run.extra:
        run.extra[key] = _plateaus(run, min_samples, tail)
    return list(run.extra[key])


def _plateaus(run: RunData, min_samples: int, tail: float) -> list[Plateau]:
    s = run.samples
    n = len(run)
    if n == 0:
        return []
    moving = np.asarray(s["motor_moving"]).astype(bool)
    cut = np.zeros(n + 1, dtype=bool)
    cut[0] = cut[n] = True
    cut[1:n] |= moving[1:] != moving[:-1]
    for name, tol in TOL.items():
        cut[1:n] |= _level_change(s[name], tol)
    edges = np.flatnonzero(cut)
    out: list[Plateau] = []
    t = s["t"]
    for a, b in zip(edges[:-1], edges[1:]):
        if moving[a] or b - a < min_samples:
            continue
        out.append(Plateau(int(a), int(b), float(t[a]), float(t[b - 1]), float(s["turns"][a]),
                           float(s["heater_voltage"][a]), float(s["load"][a]),
                           _tail_median(s["length"][a:b], tail), _tail_median(s["resistance"][a:b], tail),
                           bool(a > 0 and moving[a - 1])))
    return out


def motor_stops(run: RunData, min_duration_s: float = 2.0) -> list[Plateau]:
    """Rests that start right after a move and last at least ``min_duration_s`` s."""
    return [p for p in plateaus(run) if p.after_move and p.duration >= min_duration_s]


def sample_cycles(run: RunData) -> np.ndarray:
    """Cycle number per sample (-1 outside repeat blocks or without /segments)."""
    n = len(run)
    seg = run.segments
    if seg is None or not len(seg) or "cycle" not in (seg.dtype.names or ()):
        return np.full(n, -1, dtype=np.int64)
    index = np.asarray(seg["index"], dtype=np.int64)
    cycle = np.asarray(seg["cycle"], dtype=np.int64)
    lookup = np.full(int(max(index.max(), 0)) + 1, -1, dtype=np.int64)
    lookup[index[index >= 0]] = cycle[index >= 0]
    samp = np.asarray(run.samples["segment"], dtype=np.int64)
    ok = (samp >= 0) & (samp < len(lookup))
    out = np.full(n, -1, dtype=np.int64)
    out[ok] = lookup[samp[ok]]
    return out


@dataclass(frozen=True)
class CycleTable:
    """Per-cycle statistics; arrays indexed like ``cycle``; units mm, ohm, s."""

    cycle: np.ndarray
    t_mid: np.ndarray
    length_mean: np.ndarray
    length_min: np.ndarray
    length_max: np.ndarray
    resistance_mean: np.ndarray
    resistance_min: np.ndarray
    resistance_max: np.ndarray


def cycle_table(run: RunData) -> CycleTable | None:
    """Mean, min and max of length and resistance per repeat cycle; None without cycles."""
    cyc = sample_cycles(run)
    inside = cyc >= 0
    if not inside.any():
        return None
    s = run.samples
    ids = np.unique(cyc[inside])
    cols: dict[str, list[float]] = {k: [] for k in ("t", "Lm", "Ll", "Lh", "Rm", "Rl", "Rh")}

    def stats(a: np.ndarray) -> tuple[float, float, float]:
        a = a[np.isfinite(a)]
        return (float(a.mean()), float(a.min()), float(a.max())) if len(a) else (np.nan,) * 3

    order = np.argsort(cyc, kind="stable")
    sorted_c = cyc[order]
    for c in ids:
        lo, hi = np.searchsorted(sorted_c, [c, c + 1])
        idx = order[lo:hi]
        cols["t"].append(float(np.median(s["t"][idx])))
        for key, name in (("L", "length"), ("R", "resistance")):
            m, mn, mx = stats(np.asarray(s[name][idx], dtype=float))
            cols[key + "m"].append(m)
            cols[key + "l"].append(mn)
            cols[key + "h"].append(mx)
    a = {k: np.asarray(v) for k, v in cols.items()}
    return CycleTable(ids, a["t"], a["Lm"], a["Ll"], a["Lh"], a["Rm"], a["Rl"], a["Rh"])


@dataclass(frozen=True)
class StiffnessPoint:
    """One loaded rest: load F (N), steady length L (mm), unloaded L0 (mm), K (N), rising."""

    load: float
    length: float
    l0: float
    k: float
    rising: bool


def stiffness_points(run: RunData, min_levels: int = 3) -> list[StiffnessPoint]:
    """Load-step points at the twist level that has an unloaded rest and the most loads.

    L0 is the mean steady length of the unloaded (0 N) rests at that twist level. A point
    whose length equals L0 gets K = NaN (division by zero is not a stiffness). Returns []
    when no twist level has an unloaded rest and ``min_levels`` distinct loads.
    """
    rests = [p for p in plateaus(run) if np.isfinite(p.load) and np.isfinite(p.length) and p.heater_voltage == 0]
    best: list[Plateau] = []
    for turns in sorted({round(p.turns, 6) for p in rests}):
        at = [p for p in rests if round(p.turns, 6) == turns]
        levels = {round(p.load, 6) for p in at}
        if 0.0 in levels and len(levels) >= min_levels and len(at) > len(best):
            best = at
    if not best:
        return []
    l0 = float(np.mean([p.length for p in best if p.load == 0]))
    out: list[StiffnessPoint] = []
    prev = 0.0
    for p in best:
        rising = p.load >= prev
        prev = p.load
        if p.load == 0:
            continue
        dl = p.length - l0
        out.append(StiffnessPoint(p.load, p.length, l0, p.load * l0 / dl if dl != 0 else float("nan"), rising))
    return out
