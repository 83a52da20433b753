"""Segments for imported runs: from a column, or inferred from the data like a recorded run's.

Contract of :func:`infer` (columns in their contract units):

* a new segment starts where the motor starts or stops moving (``turns`` changes by more
  than ``turns`` turn between rows), where ``heater_voltage`` steps by more than
  ``heater_V`` or the declared ``load`` by more than ``load_N`` between rows;
* kinds: ``move`` (motor moving), ``heater`` (still, heater level changed at its start),
  ``hold`` (otherwise); params say it was inferred and give the levels;
* a run in which nothing changes gets no segments (every sample -1): a single hold would
  make ``fit`` take only its last third.

:func:`from_column` makes one segment per run of equal values of a source column.
Both return (segment index per sample, [SegmentRecord]).
"""

from __future__ import annotations

import numpy as np

from tsa_bench.rundocs import SegmentRecord

DEFAULTS = {"turns": 0.0, "heater_V": 0.05, "load_N": 0.05}


def _steps(x: np.ndarray | None, thr: float) -> np.ndarray:
    if x is None or len(x) < 2:
        return np.zeros(max(len(x) if x is not None else 0, 1) - 1, bool)
    a = np.where(np.isfinite(x), x, -1e300)
    return np.abs(np.diff(a)) > thr


def moving_from_turns(turns: np.ndarray, thr: float) -> np.ndarray:
    """1 where ``turns`` changed by more than ``thr`` since the previous row."""
    m = np.zeros(len(turns), "u1")
    if len(turns) > 1:
        m[1:] = (np.abs(np.diff(turns)) > thr) & np.isfinite(turns[1:])
    return m


def _records(t: np.ndarray, starts: np.ndarray, kinds: list[str], params: list[dict]) -> tuple[np.ndarray, list]:
    seg = np.zeros(len(t), "i4")
    ends = np.r_[starts[1:], len(t)]
    recs = []
    for k, (a, b) in enumerate(zip(starts, ends)):
        seg[a:b] = k
        t_end = float(t[b]) if b < len(t) else float(t[-1])
        recs.append(SegmentRecord(k, kinds[k], float(t[a]), t_end, params[k], "inferred", None, True))
    return seg, recs


def infer(s: dict[str, np.ndarray], moving: np.ndarray, thresholds: dict[str, float]) -> tuple[np.ndarray, list]:
    """(segment per sample, records) inferred from the samples (module contract)."""
    t = s["t"]
    n = len(t)
    heater, load = s.get("heater_voltage"), s.get("load")
    mv = moving.astype(bool)
    change = np.zeros(n, bool)
    change[0] = True
    hstep, lstep = np.zeros(n, bool), np.zeros(n, bool)  # a step into row k
    if n > 1:
        change[1:] |= mv[1:] != mv[:-1]
        hstep[1:] = _steps(heater, thresholds["heater_V"]) if heater is not None else False
        lstep[1:] = _steps(load, thresholds["load_N"]) if load is not None else False
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
        heater_step, load_step = bool(hstep[a]), bool(lstep[a])
        if load_step:
            p["load_change"] = True
        kinds.append("move" if mv[a] else "heater" if heater_step else "hold")
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
