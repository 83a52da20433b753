"""Calibrate the simulated-bench presets to the thesis's records by fitting.

Units: parameters in their own units (the suffix of their names); residuals are
dimensionless (1 = at the edge of the record's tolerance).

Contract:

* the distance of a simulated value from a record is
  :func:`tsa_bench.reproduce.table.residual` (1 = at the edge of its tolerance).
* :func:`run_fit` fits one :class:`~tsa_bench.reproduce.plan.Fit`: its parameters,
  mapped to [0, 1] within their bounds (logarithmically when the bounds span more than
  a factor 10 and are positive), are adjusted to minimise the soft-L1 sum of the
  residuals of the fit's records: scipy's bounded trust-region least squares (finite-
  difference Jacobian), then a short bounded Nelder-Mead polish with what is left of
  the budget. Each evaluation simulates the records' experiments on fresh copies of the
  presets (fixed seeds: the same noise every evaluation).
  A fit is evaluated on several noise seeds at once (the residuals of every seed
  stacked) when any of its parameters sets a noise level (:data:`NOISE_EFFECTS`): a
  noise level fitted to one draw is fitted to that draw.
* :func:`calibration_records` are the only records a calibration reads: the fits'
  records. :func:`calibrate` refuses records the plan declares held out
  (:class:`HeldOutError`), runs the plan's fits in order, each starting from the results
  of the earlier ones, and returns the new preset mappings and manipulator settings. A
  plant extension is kept or dropped by leave-one-out cross-validation within the fit's
  own records (:func:`cross_validate_extension`), never by held-out records.
* :func:`write_calibration` writes fitted values into the bench files (and
  configs/manipulator/thesis.yaml), keeping every other line and comment.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.optimize import least_squares, minimize

from tsa_bench.reproduce.experiments import BENCH_DIR, PRESETS, Lab, preset_plant
from tsa_bench.reproduce.manipulator import CONFIG as MANIPULATOR_FILE
from tsa_bench.reproduce.measures import measure_unit
from tsa_bench.reproduce.quantities import compute
from tsa_bench.reproduce.plan import MANIPULATOR, CalibrationPlan, Fit
from tsa_bench.reproduce.records import Record
from tsa_bench.reproduce.table import residual
from tsa_bench.units import convert


def get_path(cfg: dict[str, Any], path: str) -> float:
    """Value at a dotted path; an effect parameter absent from the mapping is its documented default."""
    from tsa_bench.sim.effects import EFFECTS

    node: Any = cfg
    parts = path.split(".")
    for p in parts:
        node = node.get(p) if isinstance(node, dict) else None
        if node is None:
            break
    if node is None and len(parts) == 3 and parts[0] == "effects" and parts[1] in EFFECTS:
        node = {f.name: f.default for f in dataclasses.fields(EFFECTS[parts[1]].Params)}[parts[2]]
    if node is None:
        raise KeyError(path)
    return float(node)


def set_path(cfg: dict[str, Any], path: str, value: float) -> None:
    """Set a dotted path, creating mappings (an effect given as ``true``/``null`` becomes a mapping)."""
    node = cfg
    parts = path.split(".")
    for p in parts[:-1]:
        child = node.get(p)
        if isinstance(child, bool):
            child = {"enabled": child}
        elif not isinstance(child, dict):
            child = {}
        node[p] = child
        node = child
    node[parts[-1]] = value


@dataclass
class Settings:
    """Everything a fit can change: preset plants and the manipulator settings."""

    plants: dict[str, dict[str, Any]]
    manipulator: dict[str, Any]

    def copy(self) -> Settings:
        return Settings(copy.deepcopy(self.plants), copy.deepcopy(self.manipulator))

    def get(self, preset: str | tuple[str, ...], path: str) -> float:
        """A parameter's value (of the first preset, when several share it)."""
        preset = preset[0] if isinstance(preset, tuple) else preset
        return get_path(self.manipulator if preset == MANIPULATOR else self.plants[preset], path)

    def set(self, preset: str | tuple[str, ...], path: str, value: float) -> None:
        """Set a parameter in one preset or several; fitting an effect's parameter switches that effect on."""
        for name in (preset if isinstance(preset, tuple) else (preset,)):
            cfg = self.manipulator if name == MANIPULATOR else self.plants[name]
            set_path(cfg, path, value)
            parts = path.split(".")
            if name != MANIPULATOR and len(parts) == 3 and parts[0] == "effects":
                cfg["effects"][parts[1]].setdefault("enabled", True)

    def lab(self, seed: int = 0, quick: bool = False) -> Lab:
        return Lab(copy.deepcopy(self.plants), seed=seed, quick=quick, manipulator=copy.deepcopy(self.manipulator))


def load_settings(bench_dir: Path = BENCH_DIR, manipulator_file: Path = MANIPULATOR_FILE) -> Settings:
    return Settings({p: preset_plant(p, bench_dir) for p in PRESETS},
                    yaml.safe_load(manipulator_file.read_text(encoding="utf-8")))


#: effects whose parameters are noise levels: a fit of one of them runs on several seeds
NOISE_EFFECTS = ("sensor_noise", "length_settling", "resistance_settling")


class HeldOutError(ValueError):
    """A calibration was handed a record the plan declares held out."""


def calibration_records(records: list[Record], plan: CalibrationPlan) -> list[Record]:
    """The records the calibration may read: those some fit names, in record order (module contract)."""
    fitted = set(plan.fitted_ids())
    return [r for r in records if r.id in fitted]


def is_noise_fit(fit: Fit) -> bool:
    """Does a parameter of ``fit`` set a noise level (:data:`NOISE_EFFECTS`)?"""
    return any(path.split(".")[:2][-1] in NOISE_EFFECTS for _, path in fit.parameters)


def simulated_values(records: list[Record], lab: Lab) -> dict[str, float]:
    """Record id -> simulated value in the record's unit (NaN where it cannot be computed)."""
    out = {}
    for rec in records:
        try:
            raw = compute(lab, rec.measure, rec.conditions)
            out[rec.id] = convert(raw, measure_unit(rec.measure, rec.conditions), rec.unit) if math.isfinite(raw) \
                else raw
        except (ValueError, KeyError, IndexError, ZeroDivisionError):
            out[rec.id] = float("nan")
    return out


class _Space:
    """[0, 1] coordinates of a fit's parameters (log scale for wide positive bounds)."""

    def __init__(self, params: dict[tuple[tuple[str, ...], str], tuple[float, float]]) -> None:
        self.keys = list(params)
        self.bounds = [params[k] for k in self.keys]
        self.log = [lo > 0 and hi / lo > 10 for lo, hi in self.bounds]

    def value(self, i: int, u: float) -> float:
        lo, hi = self.bounds[i]
        u = min(1.0, max(0.0, u))
        return math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo))) if self.log[i] else lo + u * (hi - lo)

    def coord(self, i: int, v: float) -> float:
        lo, hi = self.bounds[i]
        v = min(hi, max(lo, v))
        return (math.log(v) - math.log(lo)) / (math.log(hi) - math.log(lo)) if self.log[i] else (v - lo) / (hi - lo)


@dataclass
class FitResult:
    fit: Fit
    start: dict[tuple[tuple[str, ...], str], float]
    values: dict[tuple[tuple[str, ...], str], float]
    cost_start: float
    cost: float
    evaluations: int
    residuals: dict[str, float]


def run_fit(fit: Fit, records: list[Record], settings: Settings, seed: int = 0, maxfev: int = 200,
            log: Callable[[str], None] | None = None, seeds: tuple[int, ...] | None = None
            ) -> tuple[Settings, FitResult]:
    """Fit ``fit``'s parameters to its records, starting from ``settings`` (module contract).

    ``seeds``: the noise seeds every evaluation simulates (default: ``seed`` alone); the
    residuals of all seeds are stacked, and :attr:`FitResult.residuals` are their means.
    """
    by_id = {r.id: r for r in records}
    recs = [by_id[i] for i in fit.records]
    seeds = tuple(seeds) if seeds else (seed,)
    space = _Space(fit.parameters)
    start = {k: settings.get(*k) for k in space.keys}
    cache: dict[tuple[float, ...], tuple[float, dict[str, float]]] = {}

    def apply(u: np.ndarray) -> Settings:
        s = settings.copy()
        for i, k in enumerate(space.keys):
            s.set(k[0], k[1], space.value(i, float(u[i])))
        return s

    def cost(u: np.ndarray) -> float:
        key = tuple(np.round(u, 6))
        if key not in cache:
            s = apply(u)
            stacked = []
            for sd in seeds:
                sims = simulated_values(recs, s.lab(seed=sd))
                stacked.append({r.id: residual(r, sims[r.id]) for r in recs})
            c = float(sum(2.0 * (math.sqrt(1.0 + min(x * x, 1e6)) - 1.0) for res in stacked for x in res.values()))
            cache[key] = (c, stacked)
            if log is not None and len(cache) % 25 == 0:
                log(f"  {fit.name}: {len(cache)} evaluations, cost {min(v[0] for v in cache.values()):.3f}")
        return cache[key][0]

    def residuals(u: np.ndarray) -> np.ndarray:
        cost(u)
        stacked = cache[tuple(np.round(u, 6))][1]
        return np.array([max(-1e3, min(1e3, res[r.id])) for res in stacked for r in recs])

    u0 = np.array([space.coord(i, start[k]) for i, k in enumerate(space.keys)])
    c0 = cost(u0)
    n = len(u0)
    try:  # trust-region least squares on the residual vector, soft-L1 loss, finite-difference Jacobian
        ls = least_squares(residuals, u0, bounds=(np.zeros(n), np.ones(n)), loss="soft_l1", diff_step=0.004,
                           x_scale=np.full(n, 0.3), max_nfev=max(3, maxfev // (n + 1)), xtol=1e-4, ftol=1e-4)
        best = ls.x
    except ValueError:
        best = u0
    if cost(best) > c0:
        best = u0
    # a short simplex polish from there (helps where the residuals are not smooth)
    simplex = [best] + [np.clip(best + np.eye(n)[i] * (0.05 if best[i] < 0.95 else -0.05), 0, 1) for i in range(n)]
    left = max(0, maxfev - len(cache))
    if left > n + 2:
        nm = minimize(cost, best, method="Nelder-Mead", bounds=[(0.0, 1.0)] * n,
                      options={"maxfev": left, "initial_simplex": np.array(simplex), "xatol": 1e-3, "fatol": 1e-3})
        if nm.fun < cost(best):
            best = nm.x
    cost(best)
    c_best, stacked = cache[tuple(np.round(best, 6))]
    resid = {r.id: float(np.mean([res[r.id] for res in stacked])) for r in recs}
    out = apply(best)
    values = {k: space.value(i, float(best[i])) for i, k in enumerate(space.keys)}
    return out, FitResult(fit, start, values, c0, c_best, len(cache), resid)


@dataclass
class ExtensionReport:
    """A plant extension judged by leave-one-out cross-validation within the fit's records:
    each record left out in turn, the fit run without and with the extension on the
    others, the left-out record's residual (mean over the fit's seeds) compared."""

    fit: str
    effect: str
    records: list[str]
    agree_without: int
    agree_with: int
    residual_without: float
    residual_with: float
    kept: bool


def cross_validate_extension(fit: Fit, records: list[Record], settings: Settings, seeds: tuple[int, ...],
                             maxfev: int, log: Callable[[str], None] | None = None) -> ExtensionReport:
    """Leave-one-out cross-validation of ``fit``'s extension on ``fit``'s own records (module contract).

    ``settings`` has the extension's parameters at 0. For each record of the fit, the
    parameters are fitted without the extension, then with it (from the result without),
    on the other records, and the left-out record's residual is computed both ways. The
    extension is kept when more left-out records agree with it (|residual| <= 1; ties:
    smaller summed |residual|, each capped at 10).
    """
    effect, keys = fit.extension
    by_id = {r.id: r for r in records}
    a0 = a1 = 0
    c0 = c1 = 0.0
    for rid in fit.records:
        rest = [x for x in fit.records if x != rid]
        base = Fit(f"{fit.name} (without {effect}, {rid} left out)",
                   {k: v for k, v in fit.parameters.items() if k not in keys}, rest)
        s0, _ = run_fit(base, records, settings, maxfev=maxfev, seeds=seeds, log=log)
        s1, _ = run_fit(Fit(f"{fit.name} ({rid} left out)", fit.parameters, rest), records, s0, maxfev=maxfev,
                        seeds=seeds, log=log)
        r0 = float(np.mean([residual(by_id[rid], simulated_values([by_id[rid]], s0.lab(seed=sd))[rid])
                            for sd in seeds]))
        r1 = float(np.mean([residual(by_id[rid], simulated_values([by_id[rid]], s1.lab(seed=sd))[rid])
                            for sd in seeds]))
        a0 += abs(r0) <= 1
        a1 += abs(r1) <= 1
        c0 += min(abs(r0), 10.0)
        c1 += min(abs(r1), 10.0)
        if log is not None:
            log(f"  cross-validation {effect}, {rid} left out: residual {r0:+.2f} without, {r1:+.2f} with")
    kept = a1 > a0 or (a1 == a0 and c1 < c0)
    return ExtensionReport(fit.name, effect, list(fit.records), a0, a1, c0, c1, kept)


def describe(result: FitResult) -> list[str]:
    """Lines saying what a fit did: cost, parameters start -> fitted, residual of each fitted record."""
    lines = [f"- {result.fit.name}: cost {result.cost_start:.2f} -> {result.cost:.2f} in {result.evaluations} simulations"]
    for (presets, path), v in result.values.items():
        lines.append(f"    {','.join(presets)}: {path}: {result.start[(presets, path)]:.5g} -> {v:.5g}")
    for rid, r in result.residuals.items():
        lines.append(f"    fitted record {rid}: residual {r:+.2f} ({'agrees' if abs(r) <= 1 else 'outside tolerance'})")
    return lines


def calibrate(plan: CalibrationPlan, records: list[Record], settings: Settings, seed: int = 0, maxfev: int = 200,
              only: list[str] | None = None, passes: int = 2, log: Callable[[str], None] | None = None,
              noise_seeds: int = 5) -> tuple[Settings, list[FitResult], list[ExtensionReport]]:
    """Run the plan's fits in order, ``passes`` times (``only``: just the fits with these names).

    ``records`` are the fits' records (:func:`calibration_records`); a record the plan
    declares held out raises :class:`HeldOutError` before anything runs. A fit runs on
    seed ``seed``, a noise fit (:func:`is_noise_fit`) on ``noise_seeds`` seeds from it.
    The fits share parameters through the records they touch (a twist play changes the
    strains the geometry was fitted to), so the sequence is repeated; later passes start
    from the earlier results and get half the evaluations. In the first pass a fit with an
    ``extension`` is judged by :func:`cross_validate_extension` (within its own records,
    half the budget per fold), then fitted on all its records without the extension and,
    when kept, with it; a rejected extension stays out of the later passes.
    """
    held = sorted(r.id for r in records if plan.held_out is not None and r.id in plan.held_out)
    if held:
        shown = ", ".join(held[:5]) + (f" and {len(held) - 5} more" if len(held) > 5 else "")
        raise HeldOutError(f"the calibration was given {len(held)} held-out record(s) ({shown}); "
                           f"it reads only the fits' records ({plan.held_out_path})")
    results, extensions = [], []
    rejected: set[tuple[tuple[str, ...], str]] = set()

    def say(lines: list[str]) -> None:
        if log is not None:
            log("\n".join(lines))

    for n in range(passes):
        for fit in plan.fits:
            if only and fit.name not in only:
                continue
            budget = fit.maxfev or maxfev
            budget = budget if n == 0 else max(10, budget // 2)
            name = fit.name if n == 0 else f"{fit.name} (pass {n + 1})"
            seeds = tuple(range(seed, seed + max(1, noise_seeds))) if is_noise_fit(fit) else (seed,)
            say([f"fit '{name}': {len(fit.parameters)} parameters on {len(fit.records)} records, "
                 f"{len(seeds)} seed{'s' if len(seeds) > 1 else ''}"])
            if fit.extension is None or n > 0:
                f = Fit(name, {k: v for k, v in fit.parameters.items() if k not in rejected}, fit.records)
                if not f.parameters:
                    continue
                settings, result = run_fit(f, records, settings, maxfev=budget, log=log, seeds=seeds)
                results.append(result)
                say(describe(result))
                continue
            effect, keys = fit.extension
            settings = settings.copy()
            for k in keys:  # the extension's parameters are 0 (no effect) for the fit without it
                settings.set(*k, 0.0)
            report = cross_validate_extension(fit, records, settings, seeds, max(5, budget // 2), log=log)
            extensions.append(report)
            say([f"  extension {effect}: left-out records agreeing {report.agree_without} -> {report.agree_with} "
                 f"of {len(report.records)}, summed |residual| {report.residual_without:.1f} -> "
                 f"{report.residual_with:.1f}: {'kept' if report.kept else 'rejected'}"])
            base = Fit(f"{fit.name} (without {effect})", {k: v for k, v in fit.parameters.items() if k not in keys},
                       fit.records)
            settings, r_without = run_fit(base, records, settings, maxfev=budget, log=log, seeds=seeds)
            results.append(r_without)
            say(describe(r_without))
            if report.kept:
                settings, r_with = run_fit(Fit(name, fit.parameters, fit.records), records, settings,
                                           maxfev=budget, log=log, seeds=seeds)
                results.append(r_with)
                say(describe(r_with))
            else:
                rejected.update(keys)
    return settings, results, extensions


# -- writing the fitted values back into the files ----------------------------------
def _units_comment(path: str) -> str:
    from tsa_bench.sim.effects import EFFECTS

    parts = path.split(".")
    unit = ""
    if len(parts) == 3 and parts[0] == "effects" and parts[1] in EFFECTS:
        meta = {f.name: f.metadata for f in dataclasses.fields(EFFECTS[parts[1]].Params)}
        unit = meta.get(parts[2], {}).get("units", "")
    else:
        unit = {"mm": "mm", "ohm": "ohm", "C": "degC", "g": "g"}.get(parts[-1].rsplit("_", 1)[-1], "")
    return f"# {unit + ', ' if unit else ''}fitted (configs/thesis/calibration.yaml)"


def _fmt(v: float) -> str:
    return f"{v:.6g}"


def _block_end(lines: list[str], i: int, indent: int) -> int:
    """Index after the block opened at line ``i`` (lines indented deeper than ``indent``; comments belong)."""
    j = i + 1
    while j < len(lines):
        ln = lines[j]
        if ln.strip() and not ln.lstrip().startswith("#") and len(ln) - len(ln.lstrip()) <= indent:
            break
        j += 1
    return j


def write_plant_value(text: str, path: str, value: float) -> str:
    """The bench-file text with ``plant.<path>`` set to ``value`` (block-style YAML, comments kept)."""
    lines = text.splitlines()
    plant = next((i for i, ln in enumerate(lines) if re.match(r"^plant:\s*(#.*)?$", ln)), None)
    if plant is None:
        raise ValueError("no 'plant:' block")
    parts = path.split(".")
    lo, hi = plant + 1, _block_end(lines, plant, 0)
    for depth, key in enumerate(parts):
        pad = "  " * (depth + 1)
        found = next((i for i in range(lo, hi) if re.match(rf"^{pad}{re.escape(key)}:(\s|$)", lines[i])), None)
        if depth == len(parts) - 1:
            new = f"{pad}{key}: {_fmt(value)}"
            new += " " * max(1, 30 - len(new)) + _units_comment(path)
            if found is None:
                lines.insert(lo, new)
            else:
                lines[found] = new
            return "\n".join(lines) + "\n"
        if found is None:
            lines.insert(lo, f"{pad}{key}:")
            found, hi = lo, hi + 1
        elif "{" in lines[found].split("#", 1)[0]:
            raise ValueError(f"plant.{'.'.join(parts[:depth + 1])} is a flow mapping; write it in block style")
        lo, hi = found + 1, _block_end(lines, found, len(pad))
    raise AssertionError("unreachable")


def write_flow_value(text: str, path: str, value: float) -> str:
    """Set ``section.key`` in a file whose ``section:`` is a one-line or wrapped flow mapping."""
    section, key = path.split(".", 1)
    m = re.search(rf"^{re.escape(section)}:\s*\{{", text, flags=re.M)
    if m is None:
        raise ValueError(f"no flow mapping '{section}:' to write {key} into")
    close = text.index("}", m.end())
    body = text[m.end():close]
    new_body, n = re.subn(rf"(\b{re.escape(key)}:\s*)([-+0-9.eE]+)", lambda g: g.group(1) + _fmt(value), body)
    if n != 1:
        raise ValueError(f"'{key}' not found once in '{section}'")
    return text[:m.end()] + new_body + text[close:]


def write_calibration(settings: Settings, plan: CalibrationPlan, bench_dir: Path = BENCH_DIR,
                      manipulator_file: Path = MANIPULATOR_FILE) -> list[Path]:
    """Write every fitted parameter of ``plan`` from ``settings`` into its file; return the files changed."""
    changed = []
    for preset, paths in plan.fitted_parameters().items():
        f = manipulator_file if preset == MANIPULATOR else bench_dir / f"{preset}.yaml"
        text = f.read_text(encoding="utf-8")
        for path in dict.fromkeys(paths):
            v = settings.get(preset, path)
            text = write_flow_value(text, path, v) if preset == MANIPULATOR else write_plant_value(text, path, v)
        f.write_text(text, encoding="utf-8")
        changed.append(f)
    return changed
