"""Chapter 4's soft manipulator in the reproduction: the thesis's own model, driven as in 4.2.3-4.2.4.

Units: angles in degrees, time in s, motor speed in rev/s, voltage in V.

Contract: the manipulator's settings are ``configs/manipulator/thesis.yaml`` (geometry
L0, r, w0 as measured in 4.2.3; the P controller of 4.2.4; the motor speed per volt),
or ``lab.manipulator`` when the calibration supplies one. :func:`manipulator_quantity`
computes:

* ``L0``, ``r``, ``w0``: the geometry the model is built from (m);
* ``angle_range``: eq. 4.8 from 3 to 18 motor rotations (the characterisation range);
* ``rise_time``: 10-90 % rise time of the closed loop for a step to ``setpoint_deg``
  from rest at 3 rotations (Kp = 5, 2.4-12 V, the motor speed proportional to voltage);
* ``sse_mean`` / ``sse_max``: steady-state errors (eq. 4.25) over set-points uniform in
  [0, 60] deg (the file's seed and count);
* ``speed_at_3V6``: the motor speed the settings give at 3.6 V;
* ``velocity_span``: bending angle swept in 14 s at 3.6 V from 3 rotations (4.2.3).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import yaml

from tsa_bench.models.manipulator import ManipulatorGeometry, bending_angle, simulate_p_control
from tsa_bench.models.tsa_kinematics import TWO_PI

CONFIG = Path(__file__).resolve().parents[3] / "configs" / "manipulator" / "thesis.yaml"


def manipulator_config(lab: Any = None) -> dict[str, Any]:
    cfg = getattr(lab, "manipulator", None)
    return cfg if cfg else yaml.safe_load(CONFIG.read_text(encoding="utf-8"))


def manipulator_quantity(lab: Any, quantity: str, args: dict[str, Any]) -> float:
    cfg = manipulator_config(lab)
    geom = ManipulatorGeometry(**{k: float(v) for k, v in cfg["geometry"].items()})
    ctl = cfg.get("control", {})
    speed_per_v = float(ctl.get("motor_rev_per_s_per_V", 1.90 / 3.6))
    if quantity in ("L0", "r", "w0"):
        return {"L0": geom.l0_m, "r": geom.r_m, "w0": geom.w0_m}[quantity]
    if quantity == "angle_range":
        th = np.degrees(bending_angle(np.array([3.0, 18.0]) * TWO_PI, geom))
        return float(th[1] - th[0])
    if quantity == "speed_at_3V6":
        return speed_per_v * 3.6
    if quantity == "velocity_span":
        turns = 3.0 + speed_per_v * 3.6 * 14.0
        th = np.degrees(bending_angle(np.array([3.0, turns]) * TWO_PI, geom))
        return float(th[1] - th[0]) if np.isfinite(th).all() else float("inf")
    kw = dict(kp_V_per_deg=float(ctl.get("kp", 5.0)), v_min=float(ctl.get("v_min", 2.4)),
              v_max=float(ctl.get("v_max", 12.0)), speed_rev_per_s_per_V=speed_per_v,
              deadband_deg=float(ctl.get("deadband_deg", 0.5)), rate_hz=53.9)
    if quantity == "rise_time":
        res, _ = simulate_p_control(np.array([float(args.get("setpoint_deg", 32.0))]), geom,
                                    step_s=max(30.0, float(ctl.get("step_s", 20.0))), **kw)
        return res[0].rise_time_s
    rng = np.random.default_rng(int(ctl.get("seed", 0)))
    setpoints = rng.uniform(0.0, 60.0, int(ctl.get("random_setpoints", 5)))
    res, _ = simulate_p_control(setpoints, geom, step_s=float(ctl.get("step_s", 20.0)), **kw)
    errs = [r.steady_state_error_deg for r in res]
    return float(np.mean(errs) if quantity == "sse_mean" else np.max(errs))
