"""The measure functions of :mod:`tsa_bench.reproduce.measures`, one per measure name.

Units: as :func:`tsa_bench.reproduce.measures.measure_unit` says for each (mm, ohm, %,
s, N, deg, h).

Contract: every function is ``f(lab, args, conditions) -> float`` and computes the
quantity on the Lab's simulated experiments (cached there); the case fits (Preisach,
polynomial, strain-resistance, self-sensing) are cached on the Lab too, so a table of
many records costs one simulation and one fit per case. :func:`compute` gives a record's
measure (by its name) on a Lab.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from tsa_bench.models.fit_samples import quasi_static_mask
from tsa_bench.models.fitting import fit
from tsa_bench.models.polynomial import PolynomialModel
from tsa_bench.models.preisach import PreisachModel
from tsa_bench.reproduce.experiments import (DURATIONS_S, LIFETIME_CYCLES, LOADS, SCHEME_LOADS, TRAINING_S, Lab,
                                             SimRun, lifetime_steps, plateaus, preset_for)
from tsa_bench.reproduce.runs import history
from tsa_bench.reproduce.measures import UNIT_OF_INPUT, MeasureError

LEVELS = 20
ORDER = 3


def _list(v: Any) -> list:
    return list(v) if isinstance(v, (list, tuple)) else [v]


def _cases(cond: dict[str, Any], experiment: str) -> list[tuple[int, float]]:
    """(ply or scheme, load) pairs named by the conditions (all loads of each when none)."""
    if experiment == "scheme":
        keys = [int(s) for s in _list(cond.get("scheme", [1, 2]))]
        table = SCHEME_LOADS
    else:
        keys = [int(p) for p in _list(cond.get("ply", [3, 4]))]
        table = LOADS
    loads = cond.get("load_g")
    out = []
    for k in keys:
        for load in (_list(loads) if loads is not None and len(keys) == 1 else table[k]):
            out.append((k, float(load)))
    return out


def _run(lab: Lab, experiment: str, key: int, load: float) -> SimRun:
    return {"sweep": lab.sweep, "heat": lab.heat, "scheme": lab.scheme}[experiment](key, load)


class CaseFit:
    """Preisach and polynomial fitted to one case: quasi-static input u, output y, errors."""

    def __init__(self, u_hist: np.ndarray, y_hist: np.ndarray, mask: np.ndarray) -> None:
        y_fit = np.where(mask, y_hist, np.nan)
        self.preisach = PreisachModel.fit(u_hist, y_fit, levels=LEVELS)
        ok = mask & np.isfinite(y_hist) & np.isfinite(u_hist)
        self.poly = PolynomialModel.fit(u_hist[ok], y_hist[ok], order=ORDER)
        self.errors = {"preisach": np.abs(self.preisach.predict(u_hist)[ok] - y_hist[ok]),
                       "polynomial": np.abs(self.poly.predict(u_hist[ok]) - y_hist[ok])}
        self.y = y_hist[ok]
        self.u_min, self.u_max = float(np.min(u_hist[ok])), float(np.max(u_hist[ok]))


def case_fit(lab: Lab, experiment: str, key: int, load: float) -> CaseFit:
    def make() -> CaseFit:
        sim = _run(lab, experiment, key, load)
        col = {"sweep": "turns", "heat": "heater_voltage", "scheme": "resistance"}[experiment]
        run = sim.run
        u = np.asarray(run.samples[col], float)
        mask = quasi_static_mask(run, col) & (np.asarray(run.samples["motor_moving"]) == 0)
        if experiment == "scheme":  # the sensing range, 20-55 turns (2.5.1), not the rest before it
            mask &= np.asarray(run.samples["turns"], float) >= 20.0 - 1e-9
            u = np.where(np.isfinite(u), u, np.nanmedian(u))
        return CaseFit(u, np.asarray(run.samples["length"], float), mask)
    return lab.cached(("casefit", experiment, key, load), make)


def _pooled(errors: list[np.ndarray], stat: str) -> float:
    e = np.concatenate(errors)
    if stat == "e_aver":
        return float(e.mean())
    return float(np.sqrt(np.sum((e - e.mean()) ** 2) / max(len(e) - 1, 1)))


# -- 3.1 / 3.2.1: polynomial and Preisach models -----------------------------------
def poly_coefficient(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    i = int(a["index"])
    vals = [case_fit(lab, a["experiment"], k, load).poly.coefficients[i] for k, load in _cases(c, a["experiment"])]
    if a.get("stat") == "max_abs":
        return float(np.max(np.abs(vals)))
    if len(vals) != 1:
        raise MeasureError("poly_coefficient of several cases needs stat: max_abs")
    return float(vals[0])


def poly_curve_gap(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    """Largest excess (mm) of |p_sim(q) - p_thesis(q)| over the band the printed coefficients
    allow, ``sum_i rounding_i |q|^i``, over the simulated case's quasi-static input range (0: inside)."""
    from tsa_bench.units import parse_unit

    (case,) = _cases(c, a["experiment"])
    f = case_fit(lab, a["experiment"], *case)
    to_mm = parse_unit(a["unit"]).factor / parse_unit(f"mm/{UNIT_OF_INPUT[a['experiment']]}").factor
    q = np.linspace(f.u_min, f.u_max, 101)
    thesis = np.polynomial.polynomial.polyval(q, np.asarray(a["coefficients"], float)) * to_mm
    band = np.polynomial.polynomial.polyval(np.abs(q), np.asarray(a["rounding"], float)) * to_mm
    return float(max(0.0, np.max(np.abs(f.poly.predict(q) - thesis) - band)))


def model_error(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    fits = [case_fit(lab, a["experiment"], k, load) for k, load in _cases(c, a["experiment"])]
    if a["stat"] == "worst_case":
        return float(max(f.errors[a["model"]].mean() for f in fits))
    return _pooled([f.errors[a["model"]] for f in fits], a["stat"])


def error_ratio(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    if a["experiment"] == "heat_vs_sweep":
        heat = [case_fit(lab, "heat", k, ld).errors["polynomial"] for k, ld in _cases(c, "heat")]
        sweep = [case_fit(lab, "sweep", k, ld).errors["polynomial"] for k, ld in _cases(c, "sweep")]
        return _pooled(heat, "e_aver") / _pooled(sweep, "e_aver")
    fits = [case_fit(lab, a["experiment"], k, ld) for k, ld in _cases(c, a["experiment"])]
    return _pooled([f.errors["polynomial"] for f in fits], "e_aver") / max(
        _pooled([f.errors["preisach"] for f in fits], "e_aver"), 1e-12)


def load_error_ratio(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    cases = sorted(_cases(c, a["experiment"]), key=lambda kl: kl[1])
    lo, hi = case_fit(lab, a["experiment"], *cases[0]), case_fit(lab, a["experiment"], *cases[-1])
    return float(lo.errors[a["model"]].mean() / max(hi.errors[a["model"]].mean(), 1e-12))


def scheme_error_ratio(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    e = {s: _pooled([case_fit(lab, "scheme", s, ld).errors[a["model"]] for ld in SCHEME_LOADS[s]], "e_aver")
         for s in (1, 2)}
    return e[1] / max(e[2], 1e-12)


def length_change(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    changes = []
    for k, load in _cases(c, a["experiment"]):
        f = case_fit(lab, a["experiment"], k, load)
        y = f.y
        changes.append(float(np.max(y) - np.min(y)))
    if a["stat"] == "mean":
        return float(np.mean(changes))
    return float(np.std(changes, ddof=1)) if len(changes) > 1 else 0.0


def p0_load_trend(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    rises = []
    for ply in (3, 4):
        p0 = [case_fit(lab, "sweep", ply, load).poly.coefficients[0] for load in LOADS[ply]]
        rises += list(np.diff(p0))
    return float(min(rises))


# -- 2.4: strains ---------------------------------------------------------------------
def _strain_parts(lab: Lab, ply: int, load: float) -> tuple[float, float, float]:
    """(x_l loaded untwisted, x twisted cold, x heated at the maximum voltage) in mm."""
    sim = lab.heat(ply, load)
    h, x = sim.hist, sim.length
    pl = plateaus(h, x)
    first = pl[0][1]
    seg_v = {int(s): float(h["heater_voltage"][h["segment"] == s][0]) for s, _ in pl}
    seg_t = {int(s): float(h["turns"][h["segment"] == s][0]) for s, _ in pl}
    full = max(seg_t.values())
    cold = [v for s, v in pl if seg_t[s] == full and seg_v[s] == 0.0]
    vmax = max(seg_v.values())
    hot = [v for s, v in pl if seg_v[s] == vmax]
    return first, cold[0], min(hot)


def _passive(lab: Lab, ply: int, load: float) -> float:
    """Eq. 2.2 at full twist from the twist sweep (twisting only, 2.4.2)."""
    sim = lab.sweep(ply, load)
    h = sim.hist
    pl = plateaus(h, sim.length)
    turns = [float(h["turns"][h["segment"] == s][0]) for s, _ in pl]
    xl = pl[0][1]
    xt = pl[int(np.argmax(turns))][1]
    return (xl - xt) / xt


def strain(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    """Passive strain from the twist sweep; active and thermal from the heating run (2.4.3);
    the mean over the cases (every load of each ply named when the conditions name several)."""
    vals = []
    for ply, load in _cases(c, "heat"):
        if a["kind"] == "passive":
            vals.append(_passive(lab, ply, float(load)) * 100.0)
            continue
        xl, xt, xh = _strain_parts(lab, ply, float(load))
        passive, active, thermal = (xl - xt) / xt, (xl - xh) / xh, (xt - xh) / xh
        vals.append({"active": active, "thermal": thermal, "increase": active - passive}[a["kind"]] * 100.0)
    return float(np.mean(vals))


def thermal_time(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    sim = lab.thermal(int(c["ply"]), float(_list(c.get("load_g", 250))[0]))
    h, x = sim.hist, sim.length
    t, v = h["t"], h["heater_voltage"]
    on = np.flatnonzero(v > 0)
    t_on, t_off = t[on[0]], t[on[-1]] + (t[1] - t[0])
    before = x[on[0] - 1]
    hot = x[on[-1]]
    span = before - hot
    if span <= 0:
        raise MeasureError("heating does not shorten the TSA in this preset")
    if a["phase"] == "heating":
        reached = np.flatnonzero((t >= t_on) & (t < t_off) & (before - x >= 0.9 * span))
        return float(t[reached[0]] - t_on) if len(reached) else float("inf")
    after = np.flatnonzero((t >= t_off) & (x - hot >= 0.95 * (x[-1] - hot)))
    return float(t[after[0]] - t_off) if len(after) else float("inf")


# -- 2.5.1: Scheme 1 and 2 ----------------------------------------------------------------
def _scheme_levels(lab: Lab, scheme: int, load: float) -> list[tuple[float, float, float]]:
    """(turns, steady length, steady resistance) of each hold at 20 turns or more, in order."""
    sim = lab.scheme(scheme, load)
    h = sim.hist
    res = dict(plateaus(h, sim.resistance))
    out = []
    for s, length in plateaus(h, sim.length):
        tw = float(h["turns"][h["segment"] == s][0])
        if tw >= 20.0 - 1e-9:
            out.append((tw, length, res[s]))
    return out


def scheme_length(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    vals = []
    for load in _list(c.get("load_g", SCHEME_LOADS[int(c["scheme"])])):
        lv = _scheme_levels(lab, int(c["scheme"]), float(load))
        vals.append(next(L for tw, L, _ in lv if abs(tw - float(a["turns"])) < 1e-6))
    return float(np.mean(vals))


def scheme_contraction(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    lf = scheme_length(lab, {"turns": a["from_turns"]}, c)
    lt = scheme_length(lab, {"turns": a["to_turns"]}, c)
    return (lf - lt) / lt * 100.0


def load_effect(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    scheme = int(c["scheme"])
    lo, hi = sorted(float(x) for x in _list(c.get("load_g", SCHEME_LOADS[scheme])))[:2]
    col = 1 if a["column"] == "length" else 2
    a_lo, a_hi = _scheme_levels(lab, scheme, lo), _scheme_levels(lab, scheme, hi)
    return float(min(h[col] - l[col] for l, h in zip(a_lo, a_hi)))


def length_resistance_correlation(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    scheme = int(c["scheme"])
    rs = []
    for load in _list(c.get("load_g", SCHEME_LOADS[scheme])):
        lv = np.array([(L, R) for _, L, R in _scheme_levels(lab, scheme, float(load))])
        rs.append(np.corrcoef(lv[:, 0], lv[:, 1])[0, 1])
    return float(min(rs))


def _loop_width(lab: Lab, scheme: int, load: float) -> float:
    lv = _scheme_levels(lab, scheme, load)
    up, down = {}, {}
    peak = int(np.argmax([tw for tw, _, _ in lv]))
    for i, (tw, _, r) in enumerate(lv):
        (up if i <= peak else down)[round(tw, 6)] = r
    widths = [abs(up[k] - down[k]) for k in down if k in up]
    span = max(r for _, _, r in lv) - min(r for _, _, r in lv)
    return max(widths) / span if span > 0 else float("nan")


def loop_width_ratio(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    return _loop_width(lab, 2, SCHEME_LOADS[2][0]) / _loop_width(lab, 1, SCHEME_LOADS[1][0])


# -- 2.3 stiffness -----------------------------------------------------------------------
def _stiffness_fit(lab: Lab, ply: int) -> tuple[float, np.ndarray]:
    sim = lab.stiffness(ply)
    h = sim.hist
    pl = plateaus(h, sim.length)
    loads_n = np.array([float(h["load_g"][h["segment"] == s][0]) for s, _ in pl]) * 9.80665e-3
    lengths = np.array([v for _, v in pl])
    slope, l0 = np.polyfit(loads_n, lengths, 1)
    return l0 / slope, np.abs(lengths - (l0 + slope * loads_n))


def stiffness(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    return _stiffness_fit(lab, int(c["ply"]))[0]


def stiffness_fit_error(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    return float(_stiffness_fit(lab, int(c["ply"]))[1].mean())


# -- settings ---------------------------------------------------------------------------
def plant_setting(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    from tsa_bench.sim.effects import EFFECTS
    import dataclasses

    preset = a.get("preset") or preset_for({**c, **a.get("preset_for", {})})
    cfg: Any = lab.plants[preset]
    parts = str(a["path"]).split(".")
    node = cfg
    for p in parts:
        node = node.get(p) if isinstance(node, dict) else None
        if node is None:
            break
    if node is None and parts[0] == "effects":  # the effect's documented default
        default = {f.name: f.default for f in dataclasses.fields(EFFECTS[parts[1]].Params)}
        node = default[parts[2]]
    if node is None:
        raise MeasureError(f"{preset}: no plant setting {a['path']}")
    return float(node) * float(a.get("scale", 1.0))


def bench_setting(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    from tsa_bench.bench import load_bench
    from tsa_bench.reproduce.experiments import BENCH_DIR

    bench = load_bench(BENCH_DIR / f"{a.get('preset', 'sim')}.yaml")
    return float(bench.resistance.sense_current_A)


# -- 2.5.2 and 3.2.2: transient ------------------------------------------------------------
def decay_settle_time(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    sim = lab.transient_quiet()
    h, r = sim.hist, sim.resistance
    seg = h["segment"]
    last = int(seg.max())
    idx = np.flatnonzero(seg == last)
    dev = np.abs(r[idx] - r[idx[-1]])
    amp = dev[0]
    if amp <= 0:
        return 0.0
    above = np.flatnonzero(dev > 0.05 * amp)
    return float(h["t"][idx[above[-1]]] - h["t"][idx[0]]) if len(above) else 0.0


def hold_length_drift(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    sim = lab.transient_quiet()
    seg = sim.hist["segment"]
    idx = np.flatnonzero(seg == int(seg.max()))
    return float(abs(sim.length[idx[-1]] - sim.length[idx[min(10, len(idx) - 1)]]))


class _InverseFit:
    """The self-sensing model identified on the strain-resistance model already fitted
    (``tsa-bench fit self-sensing`` identifies that forward model again, the same way on
    the same runs): its ``parameters`` (rho0-3, phi0-3) and per-run ``metrics``, as a saved
    model has them."""

    def __init__(self, forward: Any, train: list, others: list) -> None:
        from tsa_bench.models.fitting import series
        from tsa_bench.models.metrics import compare
        from tsa_bench.models.self_sensing import SelfSensingModel

        model = SelfSensingModel.identify(forward, [series(r) for r in train])
        self.parameters = {f"{k}{i}": {"value": float(v)} for k, vals in (("rho", model.rho), ("phi", model.phi))
                           for i, v in enumerate(vals)}
        self.metrics: dict[str, dict[str, Any]] = {"identification": {}, "validation": {}}
        for group, runs in (("identification", train), ("validation", others)):
            for r in runs:
                pred = model.predict(series(r))
                ok = np.isfinite(pred)
                self.metrics[group][r.path] = compare(np.asarray(r.samples["length"], float)[ok], pred[ok],
                                                      r.units.get("length", "mm")).as_dict()


def _transient_fits(lab: Lab) -> dict[str, Any]:
    def make() -> dict[str, Any]:
        from tsa_bench.models.fitting import from_saved

        runs = {d: lab.steps(d) for d in DURATIONS_S}
        train = [runs[d].run for d in TRAINING_S]
        others = [runs[d].run for d in DURATIONS_S if d not in TRAINING_S]
        forward = fit("strain-resistance", train, validate=others)
        return {"runs": runs, "strain-resistance": forward,
                "self-sensing": _InverseFit(from_saved(forward), train, others)}
    return lab.cached(("transient-fits",), make)


def transient_error(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    fits = _transient_fits(lab)
    saved = fits[a["model"]]
    metrics = {**saved.metrics["identification"], **saved.metrics["validation"]}
    vals = [metrics[fits["runs"][float(d)].run.path][a["stat"]] for d in _list(a["step_s"])]
    return float(max(vals) if a["stat"].startswith("max") else np.mean(vals))


def model_parameter(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    saved = _transient_fits(lab)[a["model"]]
    v = saved.parameters[a["parameter"]]["value"]
    return float(v[int(a.get("index", 0))] if isinstance(v, list) else v)


def run_level(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    vals = []
    for d in DURATIONS_S:
        sim = lab.steps(d)
        stopped = sim.hist["motor_moving"] == 0
        col = sim.length if a["column"] == "length" else sim.resistance
        vals.append(np.nanmean(col[stopped]))
    return float(np.mean(vals))


def lifetime(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    if a["quantity"] == "duration":  # the full protocol's duration, even for a quick Lab
        t = history(lifetime_steps(LIFETIME_CYCLES), dt_s=0.2, load_g=550.0)["t"]
        return float((t[-1] - t[0]) / 3600.0)
    sim = lab.lifetime()
    h = sim.hist
    t = h["t"]
    seg, turns, moving = h["segment"], h["turns"], h["motor_moving"].astype(bool)
    ends = np.flatnonzero((np.diff(seg, append=seg[-1] + 1) != 0) & ~moving & (np.abs(turns - 15.0) < 1e-9))
    t15 = t[ends]
    col = sim.length if a["quantity"] == "length_creep_fraction" else sim.resistance
    v15 = col[ends]

    def window(t0: float, t1: float) -> float:
        sel = (t15 >= t0) & (t15 < t1)
        return float(np.median(v15[sel]))
    start, end = float(t15[0]), float(t15[-1])
    if a["quantity"] == "resistance_creep":
        return window(end - 600, end + 1) - window(start, start + 600)
    first = window(start + 540, start + 660) - window(start, start + 60)
    later = window(end - 120, end + 1) - window(start + 540, start + 660)
    return abs(later) / max(abs(first), 1e-12)


# -- chapter 4: soft manipulator ------------------------------------------------------------
def manipulator(lab: Lab, a: dict[str, Any], c: dict[str, Any]) -> float:
    from tsa_bench.reproduce.manipulator import manipulator_quantity

    return manipulator_quantity(lab, a["quantity"], a)


def compute(lab: Any, measure: dict[str, Any], conditions: dict[str, Any]) -> float:
    """Value of a record's measure on ``lab`` (a :class:`~tsa_bench.reproduce.experiments.Lab`)."""
    fn = getattr(sys.modules[__name__], measure["name"])
    args = {k: v for k, v in measure.items() if k != "name"}
    return float(fn(lab, args, conditions))
