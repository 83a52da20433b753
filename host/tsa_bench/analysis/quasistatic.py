"""Staged start of the calibration: geometry first from the holds, then the resistance line.

Units: lengths mm, twist turns, load g (N inside), resistance ohm.

Contract: :func:`hold_points` averages the settled second half of every quiet training
stretch (motor still, heater off, load constant) into quasi-static points (twist, load,
length, resistance); runs without such holds use a thinned set of training samples.
:func:`staged_start` fits the untwisted length, radius and stiffness of the judged
model's static TSA (the plant's own kinematics, :func:`tsa_bench.sim.kinematics.
contracted_length_mm`, radius growth as the model has it) to those points from several
starts (a few radii and stiffnesses, the untwisted length from the least-twisted
point), keeps the best, then solves the resistance line ``R0 + dR/dX (X - L0) - c|n|``
by linear least squares. It returns start values for :func:`~tsa_bench.analysis.
calibrate.calibrate`, never final ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.modelspec import BASE_SPECS, enabled_effects, get_value
from tsa_bench.analysis.noise import quiet_mask
from tsa_bench.sim.kinematics import NEWTON_PER_GRAM, contracted_length_mm

_contract = np.frompyfunc(contracted_length_mm, 2, 1)


def hold_points(runs: list[RunInputs], max_points: int = 400) -> dict[str, np.ndarray]:
    cols: dict[str, list] = {k: [] for k in ("turns", "load_g", "length", "resistance", "weight")}
    for r in runs:
        q = quiet_mask(r) & (r.volts == 0) & ~r.heldout & r.scored
        d = np.diff(np.r_[0, q.astype(np.int8), 0])
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            if b - a < 2:
                continue
            m = (a + b) // 2
            seg = slice(m, b)
            cols["turns"].append(float(np.mean(r.turns[seg])))
            cols["load_g"].append(float(np.mean(r.load_g[seg])))
            for o in ("length", "resistance"):
                x = r.output(o)[seg]
                cols[o].append(float(np.nanmean(x)) if np.isfinite(x).any() else np.nan)
            cols["weight"].append(float(b - m))
    out = {k: np.asarray(v, float) for k, v in cols.items()}
    if len(out["turns"]) < 8:   # continuous motion: thinned training samples instead
        parts = {k: [] for k in cols}
        for r in runs:
            idx = np.flatnonzero(~r.heldout & r.scored & (r.volts == 0))
            idx = idx[:: max(1, len(idx) // 300)]
            parts["turns"].append(r.turns[idx])
            parts["load_g"].append(r.load_g[idx])
            parts["length"].append(r.length[idx])
            parts["resistance"].append(r.resistance[idx])
            parts["weight"].append(np.ones(len(idx)))
        out = {k: np.concatenate(v) if v else np.zeros(0) for k, v in parts.items()}
    if len(out["turns"]) > max_points:
        keep = np.linspace(0, len(out["turns"]) - 1, max_points).astype(int)
        out = {k: v[keep] for k, v in out.items()}
    return out


def static_length(l0: float, r0: float, k: float, turns: np.ndarray, load_g: np.ndarray, compliant: bool,
                  growth: bool) -> np.ndarray:
    big_l = l0 * (1.0 + load_g * NEWTON_PER_GRAM / k) if compliant else np.full(len(turns), l0)
    theta_r = 2.0 * math.pi * turns * r0
    if growth:
        return _contract(big_l, theta_r * theta_r * l0).astype(float)
    x2 = big_l * big_l - theta_r * theta_r
    return np.maximum(np.sqrt(np.maximum(x2, 0.0)), big_l / math.sqrt(3.0))


def staged_start(cfg: Mapping[str, Any], pts: dict[str, np.ndarray], sigma_length: float) -> dict[str, float]:
    """Start values (geometry, stiffness, resistance line) from quasi-static points."""
    on = set(enabled_effects(cfg))
    compliant, growth = "string_compliance" in on, "radius_growth" in on
    ok = np.isfinite(pts["length"])
    if ok.sum() < 3:
        return {}
    tw, ld, x = pts["turns"][ok], pts["load_g"][ok], pts["length"][ok]
    w = np.sqrt(pts["weight"][ok])
    s = max(sigma_length, 1e-3)
    nominal = {k: get_value(cfg, k) for k in ("geometry.untwisted_length_mm", "geometry.radius_mm",
                                                  "string_compliance.stiffness_N")}
    specs = [BASE_SPECS["geometry.untwisted_length_mm"], BASE_SPECS["geometry.radius_mm"],
             BASE_SPECS["string_compliance.stiffness_N"]]
    fit_k = compliant and np.ptp(ld) > 1.0

    def unpack(v):
        return math.exp(v[0]), math.exp(v[1]), (math.exp(v[2]) if fit_k else nominal["string_compliance.stiffness_N"])

    def resid(v):
        l0, r0, k = unpack(v)
        sim = static_length(l0, r0, k, tw, ld, compliant, growth)
        pri = [spec.prior_residual(val, nominal[spec.key]) for spec, val in zip(specs, (l0, r0, k))]
        return np.r_[w * (sim - x) / s, pri[: 3 if fit_k else 2]]

    i0 = int(np.argmin(np.abs(tw)))
    best = None
    k_starts = (nominal["string_compliance.stiffness_N"], 30.0, 3000.0) if fit_k else (
        nominal["string_compliance.stiffness_N"],)
    for k0 in k_starts:
        stretch = 1.0 + ld[i0] * NEWTON_PER_GRAM / k0 if compliant else 1.0
        l0 = max(x[i0], 1.0) / stretch
        for r0 in (0.15, 0.4, 0.8, 1.6):
            v0 = np.log([l0, r0, k0])[: 3 if fit_k else 2]
            lo = [math.log(sp.lo) for sp in specs][: len(v0)]
            hi = [math.log(sp.hi) for sp in specs][: len(v0)]
            v0 = np.clip(v0, np.array(lo) + 1e-9, np.array(hi) - 1e-9)
            try:
                sol = least_squares(resid, v0, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=200)
            except ValueError:
                continue
            if best is None or sol.cost < best.cost:
                best = sol
    if best is None:
        return {}
    l0, r0, k = unpack(best.x)
    out = {"geometry.untwisted_length_mm": l0, "geometry.radius_mm": r0}
    if fit_k:
        out["string_compliance.stiffness_N"] = k
    if "resistance_length" in on:
        okr = np.isfinite(pts["resistance"])
        if okr.sum() >= 3:
            xs = static_length(l0, r0, k, pts["turns"][okr], pts["load_g"][okr], compliant, growth)
            a = np.column_stack([np.ones(okr.sum()), xs - l0, -np.abs(pts["turns"][okr])])
            coef, *_ = np.linalg.lstsq(a, pts["resistance"][okr], rcond=None)
            out["geometry.resistance_ohm"] = float(max(coef[0], 1e-3))
            out["resistance_length.ohm_per_mm"] = float(coef[1])
            out["resistance_length.contact_ohm_per_turn"] = float(coef[2])
    return out
