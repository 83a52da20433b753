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

from collections.abc import Iterator, Mapping

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
    out = np.empty((len(z), deg))
    for k in range(1, deg + 1):
        out[:, k - 1] = z ** k
    return out


def _lag(x: np.ndarray, t: np.ndarray, tau: float) -> np.ndarray:
    from scipy.signal import lfilter
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    a = float(np.exp(-dt / tau))
    return lfilter([1.0 - a], [1.0, -a], x)


def last_direction(r: RunInputs) -> np.ndarray:
    """(n, 1): the sign of the last change of |twist| (+1 twisting up, -1 down, 0 before any)."""
    n = len(r)
    d = np.diff(np.abs(r.turns), prepend=np.abs(r.turns[0]))
    step = np.sign(d)
    idx = np.where(step != 0, np.arange(n), 0)
    np.maximum.accumulate(idx, out=idx)
    return step[idx][:, None].astype(float)


def _speed(r: RunInputs) -> np.ndarray:
    dt = np.diff(r.t, prepend=r.t[0])
    speed = np.where(dt > 0, np.abs(np.diff(r.turns, prepend=r.turns[0])) / np.where(dt > 0, dt, 1.0), 0.0)
    return _poly(speed, 2)


def _time_since_stop(r: RunInputs) -> np.ndarray:
    n = len(r)
    mv = r.moving
    stops = np.where(np.r_[False, mv[:-1] & ~mv[1:]], np.arange(n), -1)
    np.maximum.accumulate(stops, out=stops)
    since = np.where(stops >= 0, r.t - r.t[np.maximum(stops, 0)], 1e4)
    since = np.where(mv, 0.0, since)
    return np.column_stack([_scale(np.log1p(np.minimum(since, 600.0))), mv.astype(float)])


def _heater(r: RunInputs, r0_ohm: float) -> np.ndarray:
    power = r.volts ** 2 / max(r0_ohm, 1e-6)
    return np.column_stack([_scale(_lag(power, r.t, 3.0)), _scale(_lag(power, r.t, 30.0))])


def _motor_angle(r: RunInputs) -> np.ndarray:
    ang = 2.0 * np.pi * r.turns
    out = np.empty((len(ang), 4))
    out[:, 0], out[:, 1] = np.sin(ang), np.cos(ang)
    ang *= 2
    out[:, 2], out[:, 3] = np.sin(ang), np.cos(ang)
    return out


def _measured_length(r: RunInputs) -> np.ndarray:
    length = np.where(np.isfinite(r.length), r.length, np.nanmean(r.length) if np.isfinite(r.length).any() else 0)
    return _poly(length, 2)


#: name -> builder (run, r0_ohm) -> (n, k) basis, in the order the regressions are reported
BUILDERS = {
    "turns": lambda r, r0: _poly(r.turns),
    "motor_angle": lambda r, r0: _motor_angle(r),
    "time": lambda r, r0: _poly(r.t),
    "load": lambda r, r0: _poly(r.load_g, 2),
    "heater_power": _heater,
    "direction": lambda r, r0: last_direction(r),
    "speed": lambda r, r0: _speed(r),
    "time_since_stop": lambda r, r0: _time_since_stop(r),
    "travel": lambda r, r0: _poly(np.cumsum(np.abs(np.diff(r.turns, prepend=r.turns[0]))), 2),
    "length": lambda r, r0: _measured_length(r),
}


def signal_bases(r: RunInputs, r0_ohm: float = 5.0) -> dict[str, np.ndarray]:
    """Every basis of one run at once (see :class:`RunBases` for one at a time)."""
    return {name: build(r, r0_ohm) for name, build in BUILDERS.items()}


class RunBases(Mapping):
    """The bases of several runs (concatenated in run order), each built when asked for and
    not kept: a regression on one basis at a time holds one (n, k) array, not all of them
    (about 23 columns of float64 per sample otherwise)."""

    #: every array it returns is built for that call: a caller may change it in place
    fresh = True

    def __init__(self, runs: list[RunInputs], r0_ohm: float = 5.0) -> None:
        self.runs, self.r0_ohm = runs, r0_ohm

    def __getitem__(self, name: str) -> np.ndarray:
        build = BUILDERS[name]
        parts = [build(r, self.r0_ohm) for r in self.runs]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def __iter__(self) -> Iterator[str]:
        return iter(BUILDERS)

    def __len__(self) -> int:
        return len(BUILDERS)
