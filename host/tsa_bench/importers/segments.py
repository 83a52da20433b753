"""Segments for imported runs: from a column, or inferred from the data like a recorded run's.

Contract of :func:`infer` (columns in their contract units, thresholds as :data:`DEFAULTS`
completed by :func:`settings`):

* the motor moves where ``turns`` changes between rows: a Schmitt trigger on the change per
  row (moving from above ``turns`` + ``turns_hyst``, still again at or below ``turns`` -
  ``turns_hyst``; :func:`moving_from_turns`), and still spells shorter than ``min_s``
  between two moving rows are part of the move (a twist logged slower than the samples,
  sample-held, changes only every few rows); at the run's start and end the motor stays still;
* ``heater_voltage`` and the declared ``load`` change level with hysteresis: the level held (the
  median of the segment's first ``min_s``) moves only where the value departs from it by more
  than the threshold less its hysteresis (``heater_V`` - ``heater_hyst_V``, ``load_N`` -
  ``load_hyst_N``), so a step of exactly the threshold counts whatever its rounding and values
  wandering around a level never toggle it; a new level must hold ``min_s`` and differ from the
  level before it by as much, else it is no segment of its own (a short excursion and its
  return are merged into the segment before);
* a new segment starts where the motor starts or stops and where a level changes; kinds
  ``move`` (motor moving), ``heater`` (still, heater level changed at its start), ``hold``
  (otherwise); params say it was inferred and give the levels;
* a run in which nothing changes gets no segments (every sample -1): a single hold would
  make ``fit`` take only its last third.

:func:`from_column` makes one segment per run of equal values of a source column.
Both return (segment index per sample, [SegmentRecord]).
"""

from __future__ import annotations

import numpy as np

from tsa_bench.rundocs import SegmentRecord

#: thresholds (turn, V, N), their hysteresis (None: a fifth of the threshold) and the minimum duration (s)
DEFAULTS: dict[str, float | None] = {"turns": 0.0, "heater_V": 0.05, "load_N": 0.05, "turns_hyst": None,
                                     "heater_hyst_V": None, "load_hyst_N": None, "min_s": 0.25}
_HYST = {"turns": "turns_hyst", "heater_V": "heater_hyst_V", "load_N": "load_hyst_N"}


def settings(overrides: dict[str, float]) -> dict[str, float]:
    """:data:`DEFAULTS` with ``overrides``, hysteresis filled (a fifth of its threshold); ValueError when
    a value is negative or a hysteresis is not below its threshold (a threshold of 0 takes none)."""
    s = {**DEFAULTS, **overrides}
    for thr, hyst in _HYST.items():
        if s[hyst] is None:
            s[hyst] = 0.2 * float(s[thr])
    bad = [f"{k}={v:g}" for k, v in s.items() if not (float(v) >= 0.0 and np.isfinite(float(v)))]
    bad += [f"{h}={s[h]:g} (must be below {t}={s[t]:g})" for t, h in _HYST.items() if s[h] and s[h] >= s[t]]
    if bad:
        raise ValueError(", ".join(bad))
    return {k: float(v) for k, v in s.items()}


def describe(s: dict[str, float]) -> str:
    """The settings as printed in the summary."""
    return (f"turns {s['turns']:g} turn (hysteresis {s['turns_hyst']:g}), heater {s['heater_V']:g} V "
            f"(hysteresis {s['heater_hyst_V']:g}), load {s['load_N']:g} N (hysteresis {s['load_hyst_N']:g}), "
            f"minimum duration {s['min_s']:g} s")


def _rows(t: np.ndarray, seconds: float) -> int:
    """How many rows ``seconds`` spans at the run's median interval (at least 1)."""
    if len(t) < 2:
        return 1
    dt = float(np.median(np.diff(t)))
    return max(1, int(np.ceil(seconds / dt))) if dt > 0 else 1


def moving_from_turns(turns: np.ndarray, t: np.ndarray, s: dict[str, float]) -> np.ndarray:
    """1 where the motor moves (module contract: Schmitt trigger on the change per row, short still spells closed)."""
    n = len(turns)
    m = np.zeros(n, "u1")
    if n < 2:
        return m
    d = np.abs(np.diff(turns))
    lo, hi = s["turns"] - s["turns_hyst"], s["turns"] + s["turns_hyst"]
    mv = np.zeros(n, bool)
    mv[1:] = d > hi   # NaN compares False: still
    if hi > lo:
        state = np.full(n, -1, np.int8)   # -1: in the band, keeps the state before
        state[0] = 0
        state[1:][mv[1:]] = 1
        state[1:][~np.isfinite(d) | (d <= lo)] = 0
        idx = np.where(state >= 0, np.arange(n), 0)
        np.maximum.accumulate(idx, out=idx)
        mv = state[idx] == 1
    # still spells shorter than min_s between two moving rows are part of the move (at the run's ends the
    # data say the motor stood still: those stay still)
    d = np.diff(np.r_[0, (~mv).astype(np.int8), 0])
    a, b = np.flatnonzero(d == 1), np.flatnonzero(d == -1)    # still rows [a, b)
    inner = (a > 0) & (b < n)
    a, b = a[inner], b[inner]
    short = t[b] - t[a] < s["min_s"]
    if short.any():
        fill = np.zeros(n + 1, np.int64)
        np.add.at(fill, a[short], 1)
        np.add.at(fill, b[short], -1)
        mv |= np.cumsum(fill[:n]) > 0
    m[mv] = 1
    return m


def _departure(x: np.ndarray, start: int, level: float, edge: float) -> int | None:
    """First row >= ``start`` whose value is more than ``edge`` from ``level`` (NaN never), or None."""
    block, n = 1024, len(x)
    while start < n:
        hit = np.flatnonzero(np.abs(x[start:start + block] - level) > edge)
        if len(hit):
            return start + int(hit[0])
        start += block
        block = min(block * 2, 1 << 20)
    return None


def level_starts(x: np.ndarray, thr: float, hyst: float, rows: int) -> list[int]:
    """Rows where ``x`` departs from the level held by more than ``thr`` - ``hyst`` (module contract);
    ``rows`` is the minimum duration in rows, over which a new level's median is taken."""
    n, starts, k = len(x), [], 0
    while k < n:
        level = _level(x[k:k + rows])
        if not np.isfinite(level):
            nxt = np.flatnonzero(np.isfinite(x[k + 1:]))
            if not len(nxt):
                break
            k = k + 1 + int(nxt[0])
            continue
        j = _departure(x, k + 1, level, thr - hyst)
        if j is None:
            break
        starts.append(j)
        k = j
    return starts


def _records(t: np.ndarray, starts: np.ndarray, kinds: list[str], params: list[dict]) -> tuple[np.ndarray, list]:
    seg = np.zeros(len(t), "i4")
    ends = np.r_[starts[1:], len(t)]
    recs = []
    for k, (a, b) in enumerate(zip(starts, ends)):
        seg[a:b] = k
        t_end = float(t[b]) if b < len(t) else float(t[-1])
        recs.append(SegmentRecord(k, kinds[k], float(t[a]), t_end, params[k], "inferred", None, True))
    return seg, recs


def _level(v: np.ndarray) -> float:
    """The median of the finite values (NaN when there are none)."""
    v = v[np.isfinite(v)]
    return float(np.median(v)) if len(v) else np.nan


def _kept_levels(x: np.ndarray, t: np.ndarray, starts: list[int], edge: float, min_s: float) -> np.ndarray:
    """Mask of the level starts kept: a level held at least ``min_s`` (until the next level starts) and not back
    within ``edge`` of the level kept before it (a short excursion and its return are no levels)."""
    n = len(x)
    keep = np.zeros(n, bool)
    if not starts:
        return keep
    before = _level(x[:starts[0]])
    ends = starts[1:] + [n]
    for a, b in zip(starts, ends):
        t_end = t[b] if b < n else t[-1] + (t[-1] - t[0]) / max(n - 1, 1)
        if t_end - t[a] < min_s:
            continue
        here = _level(x[a:b])
        if np.isfinite(before) and np.isfinite(here) and abs(here - before) <= edge:
            continue
        keep[a] = True
        before = here
    return keep


def infer(s: dict[str, np.ndarray], moving: np.ndarray, settings_: dict[str, float]) -> tuple[np.ndarray, list]:
    """(segment per sample, records) inferred from the samples (module contract)."""
    t = s["t"]
    n = len(t)
    heater, load = s.get("heater_voltage"), s.get("load")
    mv = moving.astype(bool)
    change = np.zeros(n, bool)
    change[0] = True
    hstep, lstep = np.zeros(n, bool), np.zeros(n, bool)  # a new level from row k
    rows = _rows(t, settings_["min_s"])
    if n > 1:
        change[1:] |= mv[1:] != mv[:-1]
        if heater is not None:
            thr, hyst = settings_["heater_V"], settings_["heater_hyst_V"]
            hstep = _kept_levels(heater, t, level_starts(heater, thr, hyst, rows), thr - hyst, settings_["min_s"])
        if load is not None:
            thr, hyst = settings_["load_N"], settings_["load_hyst_N"]
            lstep = _kept_levels(load, t, level_starts(load, thr, hyst, rows), thr - hyst, settings_["min_s"])
        change |= hstep | lstep
    starts = np.flatnonzero(change)
    if len(starts) < 2:
        return np.full(n, -1, "i4"), []
    kinds, params = [], []
    for k, a in enumerate(starts):
        b = starts[k + 1] if k + 1 < len(starts) else n
        p: dict = {"inferred": True}
        if heater is not None and np.isfinite(heater[a]):
            p["heater_voltage_V"] = float(heater[a])
        if load is not None and np.isfinite(load[a]):
            p["load_N"] = float(load[a])
        if "turns" in s:
            p["turns_start"], p["turns_end"] = float(s["turns"][a]), float(s["turns"][b - 1])
        if lstep[a]:
            p["load_change"] = True
        kinds.append("move" if mv[a] else "heater" if hstep[a] else "hold")
        params.append(p)
    return _records(t, starts, kinds, params)


def from_column(t: np.ndarray, values: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, list]:
    """One segment per run of equal values of ``values`` (NaN or < 0: outside any segment)."""
    n = len(t)
    v = np.where(np.isfinite(values), values, -1)
    change = np.r_[True, v[1:] != v[:-1]] if n else np.zeros(0, bool)
    starts = np.flatnonzero(change)
    seg = np.full(n, -1, "i4")
    recs = []
    k = 0
    for j, a in enumerate(starts):
        b = starts[j + 1] if j + 1 < len(starts) else n
        if v[a] < 0:
            continue
        seg[a:b] = k
        kind = "move" if moving[a:b].mean() > 0.5 else "hold"
        t_end = float(t[b]) if b < n else float(t[-1])
        recs.append(SegmentRecord(k, kind, float(t[a]), t_end, {"source_value": float(v[a])}, "column", None, True))
        k += 1
    return seg, recs
