"""The TSA-driven soft manipulator of thesis section 4.2: bending angle, velocity models, P control.

Units: SI: lengths in m, angles in rad internally (reports also give degrees), twist
T in rad, time in s, motor voltage in V.

Contract:

* :func:`bending_angle` is eq. 4.8, ``theta = (L0 - L) / r`` with L from eq. 4.4 and the
  radius-growth recursion of eqs. 4.6-4.7 (or a constant radius).
* :func:`velocity_models` returns the complete (eq. 4.9, with ``wdot`` from the
  Savitzky-Golay derivative of w as in the thesis), conventional (eq. 4.12, ``wdot = 0``)
  and linearised (eq. 4.23) bending velocities for a twist history.
* :func:`savgol_derivative` is a third-order, 151-sample Savitzky-Golay derivative
  (scipy.signal.savgol_filter) at the sampling rate (53.9 Hz in the thesis).
* :func:`simulate_p_control` runs the closed-loop proportional controller of section
  4.2.4: ``V = sign(e) clip(Kp |e|, V_min, V_max)`` with e in degrees, the motor turning
  at ``speed_per_V * V`` (1.90 rev/s at 3.6 V in the thesis), switched off within
  ``deadband_deg`` of the set-point; the bending angle follows eq. 4.8. It reports
  the 10-90 % rise time and the steady-state error of each step set-point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import savgol_filter

from tsa_bench.models.tsa_kinematics import (TWO_PI, length_constant_radius, length_with_radius_growth,
                                             reduction_ratio, reduction_ratio_linearised)


@dataclass(frozen=True)
class ManipulatorGeometry:
    """``l0_m`` arc length (= untwisted TSA length), ``r_m`` centre-to-string distance, ``w0_m`` string radius."""

    l0_m: float = 0.175
    r_m: float = 16.75e-3
    w0_m: float = 0.65e-3

    def __post_init__(self) -> None:
        for name in ("l0_m", "r_m", "w0_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")


def bending_angle(twist_rad: np.ndarray, geom: ManipulatorGeometry, radius_growth: bool = True) -> np.ndarray:
    """Eq. 4.8: theta (rad) along the twist history ``twist_rad``."""
    t = np.atleast_1d(np.asarray(twist_rad, dtype=float))
    if radius_growth:
        length, _ = length_with_radius_growth(t, geom.l0_m, geom.w0_m)
    else:
        length = length_constant_radius(t, geom.l0_m, geom.w0_m)
    return (geom.l0_m - length) / geom.r_m


def savgol_derivative(x: np.ndarray, rate_hz: float = 53.9, window: int = 151, order: int = 3) -> np.ndarray:
    """d/dt of ``x`` sampled at ``rate_hz`` by a Savitzky-Golay filter (units of x per s)."""
    x = np.asarray(x, dtype=float)
    if len(x) < window:
        raise ValueError(f"the Savitzky-Golay window ({window} samples) is longer than the data ({len(x)})")
    return savgol_filter(x, window, order, deriv=1, delta=1.0 / rate_hz)


def velocity_models(twist_rad: np.ndarray, geom: ManipulatorGeometry, rate_hz: float = 53.9,
                    window: int = 151, order: int = 3) -> dict[str, np.ndarray]:
    """theta, Tdot and the three model velocities (rad/s) for a twist history sampled at ``rate_hz``."""
    t = np.asarray(twist_rad, dtype=float)
    length, w = length_with_radius_growth(t, geom.l0_m, geom.w0_m)
    tdot = savgol_derivative(t, rate_hz, window, order)
    wdot = savgol_derivative(w, rate_hz, window, order)
    l0, r = geom.l0_m, geom.r_m
    complete = (tdot * w + t * wdot) * t * w / (r * np.sqrt(l0 * l0 - t * t * w * w))       # eq. 4.9
    conventional = reduction_ratio(t, l0, w) / r * tdot                                       # eq. 4.12
    linearised = reduction_ratio_linearised(t, l0, w) / r * tdot                              # eq. 4.23
    return {"theta_rad": (l0 - length) / r, "tdot_rad_per_s": tdot, "w_m": w, "wdot_m_per_s": wdot,
            "complete": complete, "conventional": conventional, "linearised": linearised}


@dataclass(frozen=True)
class StepResult:
    """One set-point of the closed-loop simulation (angles in degrees, times in s)."""

    setpoint_deg: float
    start_deg: float
    rise_time_s: float
    steady_state_error_deg: float


def simulate_p_control(setpoints_deg: np.ndarray, geom: ManipulatorGeometry, kp_V_per_deg: float = 5.0,
                       v_min: float = 2.4, v_max: float = 12.0, speed_rev_per_s_per_V: float = 1.90 / 3.6,
                       deadband_deg: float = 0.5, initial_turns: float = 3.0, step_s: float = 20.0,
                       rate_hz: float = 53.9) -> tuple[list[StepResult], dict[str, np.ndarray]]:
    """Closed loop over successive step set-points, each held ``step_s``; returns per-step results and traces."""
    if not 0 < v_min < v_max:
        raise ValueError(f"need 0 < v_min < v_max, got {v_min}, {v_max}")
    dt = 1.0 / rate_hz
    n_step = int(round(step_s * rate_hz))
    twist = initial_turns * TWO_PI
    theta0 = float(bending_angle(np.array([initial_turns * TWO_PI]), geom, radius_growth=False)[0])
    w_prev = geom.w0_m
    results, t_tr, th_tr, sp_tr, v_tr = [], [], [], [], []
    now = 0.0
    theta = theta0
    for sp in np.asarray(setpoints_deg, dtype=float):
        start = np.degrees(theta - theta0)
        trace = np.empty(n_step)
        for i in range(n_step):
            ang = np.degrees(theta - theta0)
            e = sp - ang
            volts = 0.0 if abs(e) < deadband_deg else float(np.sign(e) * np.clip(kp_V_per_deg * abs(e), v_min, v_max))
            twist = max(twist + volts * speed_rev_per_s_per_V * TWO_PI * dt, 0.0)
            arg = geom.l0_m ** 2 - twist * twist * w_prev * w_prev
            length = np.sqrt(max(arg, 1e-12))
            w_prev = geom.w0_m * np.sqrt(geom.l0_m / length)
            theta = (geom.l0_m - length) / geom.r_m
            trace[i] = np.degrees(theta - theta0)
            t_tr.append(now); th_tr.append(trace[i]); sp_tr.append(sp); v_tr.append(volts)
            now += dt
        results.append(StepResult(float(sp), float(start), _rise_time(trace, start, sp, dt),
                                  float(abs(trace[-1] - sp))))
    return results, {"t_s": np.array(t_tr), "theta_deg": np.array(th_tr), "setpoint_deg": np.array(sp_tr),
                     "motor_V": np.array(v_tr)}


def _rise_time(trace: np.ndarray, start: float, target: float, dt: float) -> float:
    """Time from 10 % to 90 % of the change ``start -> target`` (NaN if not reached)."""
    span = target - start
    if abs(span) < 1e-9:
        return 0.0
    frac = (trace - start) / span
    i10 = np.flatnonzero(frac >= 0.1)
    i90 = np.flatnonzero(frac >= 0.9)
    if len(i10) == 0 or len(i90) == 0:
        return float("nan")
    return float((i90[0] - i10[0]) * dt)
