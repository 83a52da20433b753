"""Fit the thesis's models to run files and evaluate them: what `tsa-bench fit` and `predict` do.

Units: run-file columns in their contract units (turn, V, ohm, mm, s); parameters
stored with units (:mod:`tsa_bench.models.saved`).

Contract:

* preisach / polynomial map any numeric sample column to any other (by default turns
  -> length; e.g. heater_voltage or resistance -> length, or an extra channel such as
  temperature -> strain). They are fitted and scored on the quasi-static samples
  (:func:`quasi_static_mask`: motor stopped, last third of each segment; for
  heater_voltage input only at the twist where the heater was used); a run without
  segments (an import) has no holds to pick from, so its whole run is used
  (:func:`uses_whole_run`). Optionally only samples at one declared load
  (:func:`load_mask`); the Preisach relays are driven by the whole input history of each run.
* :func:`fit_notes` says what a user should know about a fit: an output near zero (percent
  errors not meaningful), runs used whole for lack
  of segments, several loads mixed in one model, a measured force (the ``force`` channel)
  that is not a declared load (:func:`measured_force_note`), more parameters than a tenth of the
  samples they were fitted on.
* strain-resistance maps length -> resistance, self-sensing resistance (+ the
  motor-moving flag) -> length; both are fitted and scored on the hold samples
  (motor stopped after a move). Self-sensing first identifies the strain-resistance
  model on the same runs, then the envelopes.
* :func:`fit` returns a :class:`~tsa_bench.models.saved.SavedModel` with the
  identification metrics of each training run and the validation metrics of each
  ``validate`` run; :func:`evaluate` predicts one run with a saved model.
* twist-heat-additive / twist-heat-coupled map twist and heater voltage together to
  length (:mod:`tsa_bench.models.twist_heat`, its own quasi-static samples and fit). A run that
  lacks a needed column (or has no usable samples) raises :class:`FitError` naming
  the file.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tsa_bench.models import twist_heat
from tsa_bench.models.fit_samples import FitError, _column, quasi_static_mask, uses_whole_run
from tsa_bench.models.metrics import compare
from tsa_bench.models.polynomial import PolynomialModel
from tsa_bench.models.preisach import PreisachModel
from tsa_bench.models.saved import MODEL_NAMES, SavedModel, param
from tsa_bench.models.self_sensing import SelfSensingModel
from tsa_bench.models.steps import RunSeries, series_from_arrays
from tsa_bench.models.strain_resistance import StrainResistanceModel
from tsa_bench.rundata import RunData

#: the usual inputs and outputs of the thesis (any numeric column is accepted)
INPUTS = ("turns", "heater_voltage", "resistance")
OUTPUTS = ("length", "resistance")
FIXED_IO = {"strain-resistance": ("length", "resistance"), "self-sensing": ("resistance", "length")}


G_N_PER_G = 9.80665e-3


def load_mask(run: RunData, load_g: float | None) -> np.ndarray:
    """Samples taken at the declared load ``load_g`` (within 0.5 g); all when None."""
    if load_g is None:
        return np.ones(len(run), bool)
    if "load" not in run.samples or not np.isfinite(np.asarray(run.samples["load"], float)).any():
        if "force" in run.samples:
            raise FitError(f"{run.path}: this run declares no load to select {load_g:g} g by; its measured force "
                           "(the 'force' column) is not a declared load: model it with --input/--output force")
        raise FitError(f"{run.path}: this run declares no load to select {load_g:g} g by (its load column is "
                       "empty); declare it at import (tsa-bench import --load-g G) or fit without --load-g")
    mask = np.abs(np.asarray(run.samples["load"], float) / G_N_PER_G - load_g) < 0.5
    if not mask.any():
        raise FitError(f"{run.path}: no samples at a load of {load_g:g} g (loads: {_listed(loads_g(run), 'g')})")
    return mask


def _listed(values: list[float], unit: str, each: bool = True, most: int = 8) -> str:
    """``100 g, 110 g, ... 390 g (30 in all)`` (or with ``each`` False ``100, 110, ... 390 g (30 in all)``):
    a list short enough for one line."""
    shown = [f"{v:g}" + (f" {unit}" if each else "") for v in values]
    if len(values) > most:
        shown = shown[:most - 1] + [f"... {shown[-1]}"]
    text = ", ".join(shown) + ("" if each else f" {unit}")
    return text + (f" ({len(values):,} in all)" if len(values) > most else "")


def measured_force_note(run: RunData) -> str | None:
    """A sentence when ``run`` has a measured force (``force``) and no declared load: which one was used."""
    if "force" not in run.samples or loads_g(run):
        return None
    f = np.asarray(run.samples["force"], float)
    f = f[np.isfinite(f)]
    if not len(f):
        return None
    return (f"{run.path} has no declared load; its measured force (force, {f.min():.4g}..{f.max():.4g} N) is a "
            "channel, not a load: no loads were counted or selected")


def loads_g(run: RunData, mask: np.ndarray | None = None) -> list[float]:
    """The distinct declared loads (g, rounded to 0.1 g) among the (masked) samples."""
    if "load" not in run.samples:
        return []
    load = np.asarray(run.samples["load"], float)
    if mask is not None:
        load = load[mask]
    return sorted({round(float(v) / G_N_PER_G, 1) for v in load[np.isfinite(load)]})


def series(run: RunData) -> RunSeries:
    return series_from_arrays(run.path, _column(run, "t"), _column(run, "length"), _column(run, "resistance"),
                              np.asarray(run.samples["motor_moving"]))


def _check_io(model: str, input_col: str | None, output_col: str | None) -> tuple[str, str]:
    if model not in MODEL_NAMES:
        raise FitError(f"unknown model '{model}' (known: {', '.join(MODEL_NAMES)})")
    if model in FIXED_IO:
        fixed = FIXED_IO[model]
        if (input_col or fixed[0]) != fixed[0] or (output_col or fixed[1]) != fixed[1]:
            raise FitError(f"model '{model}' maps {fixed[0]} -> {fixed[1]}; --input/--output cannot change that")
        return fixed
    i, o = input_col or "turns", output_col or "length"
    if i == o:
        raise FitError(f"input and output are both '{i}'")
    return i, o


# -- model objects <-> saved parameters ------------------------------------
def _to_saved(model: str, obj: Any, io: tuple[str, str], units: tuple[str, str]) -> SavedModel:
    ui, uo = units
    if isinstance(obj, PreisachModel):
        p = {"levels": param(obj.levels, "1"), "u_min": param(obj.u_min, ui), "u_max": param(obj.u_max, ui),
             "weights": param(list(obj.weights), uo), "offset": param(obj.offset, uo), "sign": param(obj.sign, "1")}
    elif isinstance(obj, PolynomialModel):
        p = {f"p{i}": param(c, f"{uo}/{ui}^{i}" if i else uo) for i, c in enumerate(obj.coefficients)}
    else:
        sr = obj.forward if isinstance(obj, SelfSensingModel) else obj
        p = {"b1": param(sr.b1_ohm, "ohm"), "b2": param(sr.b2_ohm, "ohm"), "eps": param(sr.eps_s, "s"),
             "alpha": param(sr.alpha_mm, "mm"), "beta": param(sr.beta, "1"),
             "lambda": param(sr.lam, "(s/mm)^epsilon"), "epsilon": param(sr.epsilon, "1"),
             "Lambda": param(list(sr.creep_rates_per_s), "1/s"),
             "c": param(list(sr.creep_densities_ohm_per_mm), "ohm/mm"),
             "a": param(sr.a_ohm_per_mm, "ohm/mm"),
             "pi_weights": param(list(sr.weights_ohm_per_mm), "ohm/mm"), "sign": param(sr.sign, "1"),
             "offset": param(sr.offset_ohm, "ohm")}
        if isinstance(obj, SelfSensingModel):
            units_env = ("ohm", "1/ohm", "1", "ohm")
            for prefix, vals in (("rho", obj.rho), ("phi", obj.phi)):
                for i, (v, u) in enumerate(zip(vals, units_env)):
                    p[f"{prefix}{i}"] = param(v, u)
    return SavedModel(model, {"column": io[0], "unit": ui}, {"column": io[1], "unit": uo}, p)


def from_saved(saved: SavedModel) -> Any:
    """The model object of a saved model (raises ModelFileError on a missing parameter)."""
    v = saved.value
    if saved.model in twist_heat.NAMES:
        return twist_heat.to_model(saved)
    if saved.model == "preisach":
        return PreisachModel(int(v("levels")), float(v("u_min")), float(v("u_max")),
                             tuple(map(float, v("weights"))), float(v("offset")), float(v("sign")))
    if saved.model == "polynomial":
        n = len([k for k in saved.parameters if k.startswith("p")])
        return PolynomialModel(tuple(float(v(f"p{i}")) for i in range(n)))
    sr = StrainResistanceModel(float(v("b1")), float(v("b2")), float(v("alpha")), float(v("beta")),
                               float(v("lambda")), float(v("epsilon")), tuple(map(float, v("Lambda"))),
                               tuple(map(float, v("c"))), tuple(map(float, v("pi_weights"))), float(v("sign")),
                               float(v("offset")), float(v("eps")))
    if saved.model == "strain-resistance":
        return sr
    return SelfSensingModel(sr, tuple(float(v(f"rho{i}")) for i in range(4)),
                            tuple(float(v(f"phi{i}")) for i in range(4)))


# -- fit and evaluate ------------------------------------------------------
def _predict(obj: Any, run: RunData, io: tuple[str, str], load_g: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(prediction at every sample, mask of the samples it is scored on)."""
    if isinstance(obj, (StrainResistanceModel, SelfSensingModel)):
        s = series(run)
        try:
            pred = obj.predict(s)
        except ValueError as exc:
            raise FitError(f"{run.path}: {exc}") from None
        return pred, np.isfinite(pred)
    u = _column(run, io[0])
    ok = np.isfinite(u)
    pred = np.full(len(u), np.nan)
    if isinstance(obj, PreisachModel):
        pred[ok] = obj.predict(u[ok])
    else:
        pred[ok] = obj.predict(u[ok])
    return pred, quasi_static_mask(run, io[0]) & ok & load_mask(run, load_g)


def evaluate(saved: SavedModel, run: RunData, obj: Any | None = None) -> tuple[np.ndarray, dict[str, Any]]:
    """Prediction of ``run`` and its metrics (:class:`~tsa_bench.models.metrics.Metrics` as a dict),
    scored at the model's training load when it was fitted at one (``options['load_g']``)."""
    model = from_saved(saved) if obj is None else obj
    if saved.model in twist_heat.NAMES:
        return twist_heat.score(model, run)
    io = (saved.input["column"], saved.output["column"])
    pred, mask = _predict(model, run, io, saved.options.get("load_g"))
    y = _column(run, io[1])
    if not (mask & np.isfinite(y)).any():
        raise FitError(f"{run.path}: no samples to score the {saved.model} model on")
    return pred, compare(y[mask], pred[mask], saved.output["unit"]).as_dict()


def fit(model: str, runs: list[RunData], input_col: str | None = None, output_col: str | None = None,
        validate: list[RunData] | None = None, levels: int = 20, order: int = 3,
        load_g: float | None = None) -> SavedModel:
    """Identify ``model`` on ``runs``; score it on them and on ``validate`` (module docstring).

    ``load_g`` (preisach, polynomial) fits and scores only the samples at that declared
    load: the thesis fits one model per load, a run of several loads otherwise mixes curves.
    """
    if model in twist_heat.NAMES:
        if input_col is not None or output_col is not None or load_g is not None:
            raise FitError(f"model '{model}' maps turns and heater_voltage -> length; --input, --output and "
                           "--load-g do not apply")
        if not runs:
            raise FitError("no training runs given")
        return twist_heat.fit_saved(model, runs, validate)
    io = _check_io(model, input_col, output_col)
    if not runs:
        raise FitError("no training runs given")
    if load_g is not None and model in FIXED_IO:
        raise FitError(f"--load-g applies to preisach and polynomial; {model} is fitted on whole hold curves")
    units = (runs[0].units.get(io[0], ""), runs[0].units.get(io[1], ""))
    if model in FIXED_IO:
        ss = [series(r) for r in runs]
        try:
            obj: Any = StrainResistanceModel.identify(ss)
            if model == "self-sensing":
                obj = SelfSensingModel.identify(obj, ss)
        except ValueError as exc:
            raise FitError(f"{', '.join(r.path for r in runs)}: {exc}") from None
    else:
        us, ys = [], []
        for r in runs:
            u, y = _column(r, io[0]), _column(r, io[1]).copy()
            mask = quasi_static_mask(r, io[0]) & load_mask(r, load_g)
            if not (mask & np.isfinite(y)).any():
                raise FitError(f"{r.path}: no quasi-static samples of '{io[1]}' to fit")
            y[~mask] = np.nan
            ok = np.isfinite(u)
            us.append(u[ok]); ys.append(y[ok])
        try:
            if model == "preisach":
                obj = PreisachModel.fit(us, ys, levels=levels)
            else:
                uu, yy = np.concatenate(us), np.concatenate(ys)
                obj = PolynomialModel.fit(uu, yy, order=order)
        except ValueError as exc:
            raise FitError(f"{', '.join(r.path for r in runs)}: {exc}") from None
    saved = _to_saved(model, obj, io, units)
    saved.options = {"levels": levels} if model == "preisach" else {"order": order} if model == "polynomial" else {}
    if load_g is not None:
        saved.options["load_g"] = load_g
    if model in FIXED_IO:
        saved.options.update(validity(runs))
    saved.training_files = [r.path for r in runs]
    for r in runs:
        saved.metrics["identification"][r.path] = evaluate(saved, r, obj)[1]
    for r in validate or []:
        saved.metrics["validation"][r.path] = evaluate(saved, r, obj)[1]
    return saved


def validity(runs: list[RunData]) -> dict[str, Any]:
    """Where a strain-resistance or self-sensing model was identified: the range of the
    training holds' mean lengths (mm) and resistances (ohm), and the bench name the
    training runs were recorded on (when they all name one)."""
    lengths, resistances, benches = [], [], set()
    for r in runs:
        s = series(r)
        moving = s.motor_moving
        stopped = ~moving
        lengths.append(s.length_mm[stopped & np.isfinite(s.length_mm)])
        resistances.append(s.resistance_ohm[stopped & np.isfinite(s.resistance_ohm)])
        benches.add(_bench_name(r.bench_text))
    ll, rr = np.concatenate(lengths), np.concatenate(resistances)
    out: dict[str, Any] = {}
    if len(ll):
        out["length_range_mm"] = [round(float(ll.min()), 4), round(float(ll.max()), 4)]
    if len(rr):
        out["resistance_range_ohm"] = [round(float(rr.min()), 6), round(float(rr.max()), 6)]
    if len(benches) == 1 and None not in benches:
        out["bench"] = benches.pop()
    return out


def _bench_name(bench_text: str) -> str | None:
    import yaml

    try:
        doc = yaml.safe_load(bench_text) if bench_text else None
    except yaml.YAMLError:
        return None
    name = doc.get("name") if isinstance(doc, dict) else None
    return name if isinstance(name, str) else None


def parameter_count(saved: SavedModel) -> int:
    """Number of identified numbers in a saved model (list parameters count each element)."""
    n = 0
    for name, entry in saved.parameters.items():
        if name in ("levels", "u_min", "u_max", "sign", "eps"):  # structure, not identified
            continue
        v = entry["value"]
        n += len(v) if isinstance(v, list) else 1
    return n


def _percent_note(run: RunData, col: str, mask: np.ndarray) -> str | None:
    """A caution when the output comes near zero: percent errors (eq. 3.21) divide by it and mean nothing."""
    y = np.asarray(run.samples[col], float)[mask]
    y = y[np.isfinite(y)]
    if len(y) < 2:
        return None
    near = np.min(np.abs(y)) < 0.01 * np.max(np.abs(y)) or (y.min() < 0 < y.max())
    if not near:
        return None
    return (f"{run.path}: {col} comes near zero ({y.min():.4g} to {y.max():.4g}): the percent errors (3.21) divide "
            "by it and are not meaningful here; read E_aver and sigma"
            + (" (a displacement is not a length: tsa-bench import --offset length=L0)" if col == "length" else ""))


def fit_notes(saved: SavedModel, runs: list[RunData]) -> list[str]:
    """What the user should know about a fit (module contract), one sentence each."""
    notes = []
    io_in = saved.input["column"]
    load_g = saved.options.get("load_g")
    n_fit = 0
    for r in runs:
        if saved.model in twist_heat.NAMES:
            n_fit += int(saved.metrics["identification"].get(r.path, {}).get("n", 0))
            continue
        if saved.model in FIXED_IO:
            n_fit += int(saved.metrics["identification"].get(r.path, {}).get("n", 0))
            continue
        mask = quasi_static_mask(r, io_in) & load_mask(r, load_g)
        n_fit += int((mask & np.isfinite(_column(r, saved.output["column"]))).sum())
        if uses_whole_run(r):
            notes.append(f"{r.path} has no segments (no holds to take quasi-static samples from): "
                         f"the whole run, {len(r)} samples, was used")
        force_note = measured_force_note(r)
        if force_note and io_in != "force" and saved.output["column"] != "force":
            notes.append(force_note)
        elif load_g is None and not uses_whole_run(r):
            loads = loads_g(r, quasi_static_mask(r, io_in))
            if len(loads) > 1:
                notes.append(f"{r.path} holds samples at {len(loads):,} loads ({_listed(loads, 'g', each=False)}); "
                             "one model was fitted across them. The thesis fits one per load: --load-g")
        note = _percent_note(r, saved.output["column"], mask)
        if note:
            notes.append(note)
    k = parameter_count(saved)
    if n_fit and k > n_fit / 10:
        notes.append(f"the {saved.model} model has {k} parameters for {n_fit} fitted samples (more than a tenth "
                     "of them): it can follow noise; judge it on --validate runs, or use fewer levels")
    return notes
