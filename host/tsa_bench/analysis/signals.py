"""Signals a residual may follow: the run's inputs and simple functions of them.

Units: each signal's own (turns, s, g, W, mm); bases are dimensionless (scaled).

Contract: :func:`signal_bases` returns, for one run, ``name -> (n, k)`` basis arrays
(columns scaled to about unit range, a low-order polynomial or a few harmonics) for:
``turns`` (twist), ``motor_angle`` (once and twice per turn), ``time``, ``load``,
``heater_power`` (V^2/R lagged by 3 and 30 s), ``direction`` (last twist direction),
``speed`` (commanded twist speed), ``time_since_stop`` (log), ``travel`` (cumulative
twist travel) and ``length`` (the measured length, for sensor-scale errors). A
regression of the residual on a basis tells which input the residual follows.
:data:`DESCRIBE` gives each a phrase for the report.
"""

from __future__ import annotations

import numpy as np

from tsa_bench.analysis.inputs import RunInputs

DESCRIBE = {
    "turns": "the twist", "motor_angle": "the motor angle, once per turn", "time": "time (a drift)",
    "load": "the load", "heater_power": "the heater power", "direction": "the twist direction",
    "speed": "the motor speed", "time_since_stop": "the time since the motor stopped",
    "travel": "the cumulative twist travel (cycles)", "length": "the measured length (a sensor scale error)",
}


def _scale(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, float)
    x = np.where(np.isfinite(x), x, np.nan)
    lo, hi = np.nanmin(x) if np.isfinite(x).any() else 0.0, np.nanmax(x) if np.isfinite(x).any() else 1.0
    return np.nan_to_num((x - lo) / (hi - lo) if hi > lo else np.zeros_like(x))


def _poly(x: np.ndarray, deg: int = 3) -> np.ndarray:
    z = 2.0 * _scale(x) - 1.0
    return np.column_stack([z ** k for k in range(1, deg + 1)])


def _lag(x: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    from scipy.signal import lfilter
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    a = float(np.exp(-dt / tau))
    return lfilter([1.0 - a], [1.0, -a], x)


def signal_bases(r: RunInputs, r0_ohm: float = 5.0) -> dict[str, np.ndarray]:
    n = len(r)
    ang = 2.0 * np.pi * r.turns
    d = np.diff(np.abs(r.turns), prepend=np.abs(r.turns[0]))
    step = np.sign(d)
    idx = np.where(step != 0, np.arange(n), 0)
    np.maximum.accumulate(idx, out=idx)
    last_dir = step[idx]
    dt = np.diff(r.t, prepend=r.t[0])
    speed = np.where(dt > 0, np.abs(np.diff(r.turns, prepend=r.turns[0])) / np.where(dt > 0, dt, 1.0), 0.0)
    mv = r.moving
    stops = np.where(np.r_[False, mv[:-1] & ~mv[1:]], np.arange(n), -1)
    np.maximum.accumulate(stops, out=stops)
    since = np.where(stops >= 0, r.t - r.t[np.maximum(stops, 0)], 1e4)
    since = np.where(mv, 0.0, since)
    power = r.volts ** 2 / max(r0_ohm, 1e-6)
    travel = np.cumsum(np.abs(np.diff(r.turns, prepend=r.turns[0])))
    length = np.where(np.isfinite(r.length), r.length, np.nanmean(r.length) if np.isfinite(r.length).any() else 0)
    return {
        "turns": _poly(r.turns),
        "motor_angle": np.column_stack([np.sin(ang), np.cos(ang), np.sin(2 * ang), np.cos(2 * ang)]),
        "time": _poly(r.t),
        "load": _poly(r.load_g, 2),
        "heater_power": np.column_stack([_scale(_lag(power, r.t, 3.0)), _scale(_lag(power, r.t, 30.0))]),
        "direction": last_dir[:, None].astype(float),
        "speed": _poly(speed, 2),
        "time_since_stop": np.column_stack([_scale(np.log1p(np.minimum(since, 600.0))), mv.astype(float)]),
        "travel": _poly(travel, 2),
        "length": _poly(length, 2),
    }
