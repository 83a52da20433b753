"""Figures of a length-tracking run: steady-state error on the true length, rise time, overshoot,
recovery after a load change.

Units: length in mm, time in s, load in g.

Contract: :func:`target_figures` cuts a run written with ``track_length`` segments into
its targets (the samples of one segment with one ``length_target``) and gives, per
target: the time from its start to its first ``on_target`` sample (``rise_s``, None
if never), the steady-state error of the TRUE length (the position sensor's ``length``
column, which the controller never uses) and of the estimate over the last half of the
time after the target was reached (motor stopped), and the overshoot (the furthest the
true length went beyond the target, in the step's direction, mm). :func:`load_recoveries`
finds each load change (a ``prompt`` segment that changed the declared load) followed
by a ``track_length`` and gives how long after the change the true length (1 s moving
mean) was back within ``band_mm`` of the target for good, with the largest deviation.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from tsa_bench.control.controller import ON_TARGET
from tsa_bench.units import G_N_PER_G
from tsa_bench.rundata import RunData


@dataclass(frozen=True)
class TargetFigures:
    segment: int
    target_mm: float
    start_mm: float          # true length when the target began
    rise_s: float | None
    steady_error_mm: float   # mean true length - target over the steady window (NaN: never reached)
    estimate_error_mm: float  # mean estimate - target over the same samples
    overshoot_mm: float

    def as_dict(self) -> dict[str, Any]:
        return self.__dict__.copy()


@dataclass(frozen=True)
class LoadRecovery:
    t_change_s: float
    load_from_g: float
    load_to_g: float
    target_mm: float
    max_deviation_mm: float
    recovery_s: float | None   # None: not back within the band by the segment's end


def _text(v: Any) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _track_segments(run: RunData) -> list[tuple[int, float, float]]:
    if run.segments is None:
        return []
    return [(int(s["index"]), float(s["t_start"]), float(s["t_end"])) for s in run.segments
            if _text(s["kind"]) == "track_length"]


def target_figures(run: RunData) -> list[TargetFigures]:
    """Per-target figures of every track_length segment (module contract)."""
    s = run.samples
    if "length_target" not in s:
        raise ValueError(f"{run.path}: no length_target column (not a track_length run)")
    t, seg, tgt = run.t_s, np.asarray(s["segment"]), np.asarray(s["length_target"], float)
    true, est = np.asarray(s["length"], float), np.asarray(s["length_estimate"], float)
    state, moving = np.asarray(s["controller_state"]), np.asarray(s["motor_moving"]).astype(bool)
    out = []
    for idx, _, _ in _track_segments(run):
        rows = np.flatnonzero((seg == idx) & np.isfinite(tgt))
        if len(rows) == 0:
            continue
        cuts = np.flatnonzero(np.diff(tgt[rows]) != 0) + 1
        for part in np.split(rows, cuts):
            target = float(tgt[part[0]])
            start = float(np.nanmean(true[max(part[0] - 5, 0):part[0] + 1]))
            reached = part[state[part] == ON_TARGET]
            if len(reached) == 0:
                out.append(TargetFigures(idx, target, start, None, float("nan"), float("nan"), float("nan")))
                continue
            t_reach, t_end = t[reached[0]], t[part[-1]]
            steady = part[(t[part] >= t_reach + 0.5 * (t_end - t_reach)) & ~moving[part]]
            direction = np.sign(target - start) or 1.0
            over = float(np.nanmax(direction * (true[part] - target)))
            out.append(TargetFigures(idx, target, start, float(t_reach - t[part[0]]),
                                     float(np.nanmean(true[steady]) - target) if len(steady) else float("nan"),
                                     float(np.nanmean(est[steady]) - target) if len(steady) else float("nan"),
                                     max(over, 0.0)))
    return out


def load_recoveries(run: RunData, band_mm: float = 0.5) -> list[LoadRecovery]:
    """Recovery after each load change followed by a track_length (module contract)."""
    if run.segments is None:
        return []
    s = run.samples
    t, seg = run.t_s, np.asarray(s["segment"])
    true, tgt = np.asarray(s["length"], float), np.asarray(s["length_target"], float)
    load_g = np.asarray(s["load"], float) / G_N_PER_G
    segs = list(run.segments)
    out = []
    for i, row in enumerate(segs[:-1]):
        if _text(row["kind"]) != "prompt" or _text(segs[i + 1]["kind"]) != "track_length":
            continue
        new = json.loads(_text(row["params"])).get("load_g")
        t_change = float(row["t_end"])
        before = load_g[t < t_change]
        old = float(before[np.isfinite(before)][-1]) if np.isfinite(before).any() else float("nan")
        if new is None or not abs(new - old) > 0.5:
            continue
        nxt = int(segs[i + 1]["index"])
        rows = np.flatnonzero(seg == nxt)
        if len(rows) == 0:
            continue
        target = float(np.nanmedian(tgt[rows]))
        # 1 s centred moving mean of the true length (10 samples at 10 Hz)
        k = max(1, int(round(1.0 / max(float(np.median(np.diff(t[rows]))), 1e-3))))
        if len(rows) <= k:
            continue
        smooth = np.convolve(true[rows], np.ones(k) / k, mode="valid")   # smooth[j]: rows j .. j+k-1
        dev = np.abs(smooth - target)
        outside = np.flatnonzero(dev > band_mm)
        recovery = None
        if not len(outside):
            recovery = float(t[rows[0]] - t_change)
        elif outside[-1] < len(dev) - 1:
            recovery = float(t[rows[outside[-1] + k]] - t_change)
        out.append(LoadRecovery(t_change, old, float(new), target, float(np.nanmax(dev)), recovery))
    return out
