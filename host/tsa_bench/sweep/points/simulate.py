"""The simulate runner: run a protocol shape on the plant; summary figures and a drift test.

Figures: ``duration_s``, ``samples``, ``length_mean_mm``, ``length_span_mm``,
``resistance_mean_ohm``; the resistance drift at a fixed twist (the twist held longest in
all, e.g. the lifetime test's 15 turns, reached at the end of every cycle; its
first hold, the rest, is left out): ``drift_ohm_per_h`` (least-squares slope of the
hold means against time), ``drift_z`` (slope over its standard error, from the scatter
of the hold means), ``drift_detected`` (``drift_z > detect.z_threshold``: a one-sided
test, creep raises the resistance) and ``drift_holds`` (hold means used).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tsa_bench.sweep.points.common import simulate_point


def drift(hist: dict[str, np.ndarray], resistance: np.ndarray) -> tuple[float, float, int]:
    """(slope in ohm/h, z, holds) of the resistance at the rest twist (module docstring)."""
    still = hist["motor_moving"] == 0
    held = hist["turns"][still] if still.any() else hist["turns"]
    values, counts = np.unique(np.round(held, 6), return_counts=True)
    rest = float(values[np.argmax(counts)])            # the twist held longest in all
    at = still & np.isclose(hist["turns"], rest) & np.isfinite(resistance)
    seg = hist["segment"][at]
    t, r = hist["t"][at], resistance[at]
    ids = np.unique(seg)[1:]     # not the first hold: the rest, where the moves' transients still decay
    tm = np.array([t[seg == i].mean() for i in ids])
    rm = np.array([r[seg == i].mean() for i in ids])
    if len(ids) < 3:
        return float("nan"), float("nan"), int(len(ids))
    a = np.vstack([tm - tm.mean(), np.ones_like(tm)]).T
    coef, *_ = np.linalg.lstsq(a, rm, rcond=None)
    resid = rm - a @ coef
    se = float(np.sqrt(resid @ resid / (len(rm) - 2) / ((tm - tm.mean()) @ (tm - tm.mean()))))
    slope = float(coef[0])
    z = slope / se if se > 0 else float("inf") * np.sign(slope)
    return slope * 3600.0, float(z), int(len(ids))


def run(config: dict[str, Any], plant: dict[str, Any]) -> dict[str, Any]:
    hist, out = simulate_point(config["protocol"], plant, int(config["bench"]["seed"]),
                               float(config["bench"]["settle_s"]))
    length, res = out["length_mm"], out["resistance_ohm"]
    slope, z, holds = drift(hist, res)
    return {"duration_s": float(hist["t"][-1] - hist["t"][0]), "samples": int(len(hist["t"])),
            "length_mean_mm": float(np.nanmean(length)), "length_span_mm": float(np.nanmax(length) - np.nanmin(length)),
            "resistance_mean_ohm": float(np.nanmean(res)), "drift_ohm_per_h": slope, "drift_z": z,
            "drift_detected": bool(z > float(config["detect"]["z_threshold"])), "drift_holds": holds}
