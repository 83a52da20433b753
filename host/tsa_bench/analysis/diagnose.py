"""The diagnose engine: calibrate, replay, test, screen, refit, name, check, decide.

Units: length mm, resistance ohm, time s; improvements in noise variances per sample.

Contract: :func:`diagnose` judges a plant config against runs and always ends in a
verdict (:mod:`tsa_bench.analysis.verdict`). Steps:

1. inputs: a run that lacks what the model needs ends at once in ``model_mismatch``;
2. holdout (:mod:`~tsa_bench.analysis.holdout`) and the noise model from the data alone
   (:mod:`~tsa_bench.analysis.noise`);
3. staged calibration: geometry from the holds from several starts, the resistance line
   by least squares, then every parameter on a training subsample (calibrate.py);
4. residual structure of the judged model (structure.py); if no output is structured
   above the noise the verdict is ``explained`` and nothing is screened;
5. up to ``max_causes`` iterations: screen every candidate form the data can test (its
   excitation occurs, :data:`~tsa_bench.analysis.families.NEEDS`) and may blame (the output it
   acts on was structured in the judged model on its own account, so a later cause never
   just repairs what an earlier one did to an output that was fine) (screening.py), refit every form of the leading effect and the best form of the next
   ones that screen at least :data:`CONTENDER` of the leader, together with the model's
   own parameters, and **name** the one with the largest
   held-out improvement among those that pass the gate: the 95 % block-bootstrap
   interval of the pooled held-out improvement over the current model is above 0 and its
   estimate is at least the relevance floor (a quarter of a noise variance per sample: a
   structure of half the noise RMS); switching the form off again in the refitted model
   worsens the training fit by at least the floor (the gain is the form's, not the
   re-calibration's) and, on the held-out units where the form acts, worsens it
   significantly; no output's held-out error grows by more than :data:`HARM_REL` of it in
   :data:`HARM_P` of the resamples; none of the
   form's own parameters ended at a soft bound. A refit whose parameters fit the
   training data better even with the form off shows the current calibration was a
   poorer optimum: the model is re-calibrated from there and the iteration repeated;
6. the final model: each named cause's own part (final model against the final model
   re-calibrated without it; with one cause, the judged model) orders the causes,
   dominant first, and gives its confidence (share of bootstrap replicates above the
   floor; ``form_confidence``: share in which its form beats the family's other forms);
   the residual is tested again and the verdict decided (verdict.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.analysis.calibrate import Fit, Problem, calibrate
from tsa_bench.analysis.families import FAMILIES, FAMILY_OF, FORM_SPECS, NEEDS, OUTPUT_OF, RunScale
from tsa_bench.analysis.holdout import Holdout, split
from tsa_bench.analysis.inputs import OUTPUTS, RunInputs, missing_inputs, run_inputs
from tsa_bench.analysis.modelspec import baseline_specs, enabled_effects, get_value, switch
from tsa_bench.analysis.noise import RELEVANT, Noise, noise_model
from tsa_bench.analysis.provenance import provenance
from tsa_bench.analysis.quasistatic import hold_points, staged_start
from tsa_bench.analysis.replay import subsample
from tsa_bench.analysis.result import Candidate, DiagnoseResult, Gain, NamedCause
from tsa_bench.analysis.scoring import Comparison, Scores, all_units, compare, unit_scores
from tsa_bench.analysis.screening import jacobian, screen, stacked
from tsa_bench.analysis.signals import signal_bases
from tsa_bench.analysis.structure import jumps, ljung_box, structure_test
from tsa_bench.analysis import verdict as vd

#: relevance floor of an improvement: (half a noise RMS)^2, in noise variances per sample
FLOOR = RELEVANT ** 2
N_CAL = 2000          # calibration subsample (all runs)
N_REFIT = 1000        # subsample for candidate refits (the named one is then polished on N_CAL)
REFIT_MAX = 4         # forms refitted per iteration
REFIT_NFEV = 20       # function evaluations per refit
CONTENDER = 0.1       # other effects are refitted when their screen reaches this share of the leader's
#: a form whose companion only acts through it (the resistance's temperature coefficient needs the
#: strings to heat) is also refitted together with it
COMPANIONS = {"thermal_dynamics": ("resistance_temperature",)}
SCREEN_MIN = 0.01     # a form's signature must explain at least this share of the residual
N_BOOT = 1000
#: a candidate that makes an output's held-out error worse by more than HARM_REL of it (and the floor),
#: in HARM_P of the resamples, is rejected: a cure must not damage another output noticeably
HARM_P = 0.5
HARM_REL = 0.1
UNITS = {"length": "mm", "resistance": "ohm"}
Progress = Callable[[str], None]


def _structure(res: np.ndarray, noise: Noise, rate: float, bases: dict[str, np.ndarray], moving: np.ndarray) -> dict:
    t = structure_test(res, noise, rate, bases)
    t["ljung_box_p"] = ljung_box(res)[1]
    t["jumps"] = jumps(res, noise, moving)
    if not t["structured"]:
        t["follows"] = []
    return t


class _Context:
    """Everything fixed once the inputs, holdout and noise are known."""

    def __init__(self, inputs: list[RunInputs], outputs: tuple[str, ...], noise: dict[str, Noise], hold: Holdout,
                 seed: int) -> None:
        self.inputs, self.outputs, self.noise, self.hold, self.seed = inputs, outputs, noise, hold, seed
        self.sigma = {o: noise[o].rms for o in outputs}
        n_total = sum(len(r) for r in inputs)
        idx = [subsample(r, len(r), max(300, N_CAL * len(r) // max(1, n_total))) for r in inputs]
        self.problem = Problem(inputs, idx, [~r.heldout[i] for r, i in zip(inputs, idx)], self.sigma, outputs)
        idx = [subsample(r, len(r), max(200, N_REFIT * len(r) // max(1, n_total))) for r in inputs]
        self.small = Problem(inputs, idx, [~r.heldout[i] for r, i in zip(inputs, idx)], self.sigma, outputs)
        self.units = all_units(inputs)
        self.rate = float(np.median([r.rate_hz for r in inputs]))
        self.moving = np.concatenate([r.moving for r in inputs])
        self.kinds = {k for k, v in hold.kinds.items() if v["train"] + v["heldout"] > 0}
        self.induced: set[str] = set()   # outputs structured only through the joint fit with the other
        self.source: set[str] = set(outputs)   # outputs structured in the judged model (what may be blamed)

    def scores(self, cfg: Mapping[str, Any]) -> Scores:
        return unit_scores(cfg, self.inputs, self.units, self.sigma, self.outputs)

    def compare(self, a: Scores, b: Scores) -> Comparison:
        return compare(a, b, FLOOR, N_BOOT, self.seed)

    def residual_tests(self, sims: list[dict], r0: float) -> dict:
        bases_runs = [signal_bases(r, r0) for r in self.inputs]
        bases = {k: np.concatenate([b[k] for b in bases_runs]) for k in bases_runs[0]}
        out = {}
        for o in self.outputs:
            res = np.concatenate([np.where(r.scored, r.output(o) - s[o], np.nan) for r, s in zip(self.inputs, sims)])
            out[o] = _structure(res, self.noise[o], self.rate, bases, self.moving)
        return out


def _induced(ctx: _Context, fit0: Fit, structured: list[str], centre: dict, say: Progress) -> set[str]:
    """Outputs whose residual is noise when the judged model is calibrated on them alone."""
    out = set()
    for o in structured:
        say(f"calibrating the judged model on the {o} alone")
        p = ctx.small
        alone = Problem(p.runs, p.idx, p.train, p.sigma, (o,))
        fit = calibrate(alone, fit0.cfg, baseline_specs(fit0.cfg), start=dict(fit0.values), centre=centre,
                        max_nfev=REFIT_NFEV)
        sims = ctx.scores(fit.cfg).sims
        test = ctx.residual_tests(sims, get_value(fit.cfg, "geometry.resistance_ohm"))[o]
        if not test["structured"]:
            out.add(o)
    return out if len(out) < len(structured) else set()


def _blamable(ctx: _Context, fam: str, on: set[str]) -> bool:
    """Whether the output ``fam`` acts on (length effects also through dR/dX) was structured in
    the judged model on its own account: a later cause must never just repair what an earlier
    one did to an output that was fine."""
    acts = OUTPUT_OF[fam]
    if acts not in ctx.outputs:
        acts = "resistance" if acts == "length" and "resistance_length" in on else ""
    return acts in ctx.source and acts not in ctx.induced


def _eligible(ctx: _Context, cfg: Mapping[str, Any], named_families: list[str]) -> list[str]:
    on = set(enabled_effects(cfg))
    out = []
    for fam, forms in FAMILIES.items():
        if fam in named_families or any(f in on for f in forms):
            continue
        if not any(k in ctx.kinds for k in NEEDS.get(fam, ())):
            continue
        if not _blamable(ctx, fam, on):
            continue
        out += list(forms)
    return out


def _run_scale(ctx: _Context, cfg: Mapping[str, Any]) -> RunScale:
    from tsa_bench.analysis.quasistatic import static_length
    from tsa_bench.sim.kinematics import NEWTON_PER_GRAM
    tw = np.concatenate([r.turns for r in ctx.inputs])
    ld = np.concatenate([r.load_g for r in ctx.inputs])
    sel = np.linspace(0, len(tw) - 1, min(len(tw), 2000)).astype(int)
    l0, r0 = get_value(cfg, "geometry.untwisted_length_mm"), get_value(cfg, "geometry.radius_mm")
    k = get_value(cfg, "string_compliance.stiffness_N")
    on = set(enabled_effects(cfg))
    x = static_length(l0, r0, k, tw[sel], ld[sel], "string_compliance" in on, "radius_growth" in on)
    r2 = r0 * r0 * (l0 / x if "radius_growth" in on else 1.0)
    torque = ld[sel] * NEWTON_PER_GRAM * 2 * np.pi * np.abs(tw[sel]) * r2 / x * 1e-3
    speed = [np.max(np.abs(np.diff(r.turns)) / np.maximum(np.diff(r.t), 1e-9), initial=0.0) for r in ctx.inputs]
    res_level = get_value(cfg, "geometry.resistance_ohm")
    return RunScale(float(np.max(np.abs(tw))), float(np.max(torque, initial=0.0)), float(max(speed)),
                    float(sum(r.duration_s for r in ctx.inputs)), res_level,
                    ctx.noise["resistance"].rms if "resistance" in ctx.outputs else 1e-3)


def _gate(c: Comparison, own_train: float, own: Comparison | None, form_bounds: list[dict],
          outputs: tuple[str, ...]) -> tuple[bool, str]:
    """The naming gate (module docstring, step 5)."""
    if form_bounds:
        b = form_bounds[0]
        return False, f"{b['key']} ran to the {b['side']} bound of its range ({b['bound']:.4g})"
    if c.ci95["pooled"][0] <= 0:
        return False, "held-out improvement not significant (95 % interval reaches 0)"
    if c.improvement["pooled"] < FLOOR:
        return False, f"held-out improvement {c.improvement['pooled']:.3f} noise variances is below the floor {FLOOR}"
    if own_train < FLOOR:
        return False, "switching the form off again in the refitted model barely changes the fit: the gain is the " \
                      "re-calibration's, not the form's"
    if own is not None and own.ci95["pooled"][0] <= 0:
        return False, "where the form acts on the held-out data, switching it off is not significantly worse"
    for o in outputs:
        if c.p_worse[o] >= HARM_P and -c.improvement[o] >= HARM_REL * c.mse_before[o]:
            return False, (f"makes the {o} held-out error {100 * -c.improvement[o] / c.mse_before[o]:.0f} % worse "
                           f"(in {100 * c.p_worse[o]:.0f} % of the resamples)")
    return True, "passes"


def _refit_specs(cfg: Mapping[str, Any], form: str) -> list:
    """Parameters refitted with ``form``: all of them, or for a resistance-stage form only the
    resistance side (it cannot move the length, so the length's parameters stay)."""
    from tsa_bench.sim.effects import effect_class
    specs = baseline_specs(cfg)
    if effect_class(form).stage != "resistance":
        return specs
    keep = []
    for s in specs:
        head = s.key.split(".")[0]
        if s.key == "geometry.resistance_ohm" or (head != "geometry" and effect_class(head).stage == "resistance"):
            keep.append(s)
    return keep


def _refit(ctx: _Context, current: Fit, cur_scores: Scores, forms: tuple[str, ...], params: dict, centre: dict
           ) -> dict:
    """Refit the current model with ``forms`` switched on (``params``: form -> start values) and gate it
    (the gate's ablation switches all of ``forms`` off). Fitted on the smaller subsample."""
    problem = ctx.small
    cfg_on = dict(current.cfg)
    start = dict(current.values)
    for f in forms:
        cfg_on = switch(cfg_on, f, True, params.get(f, {}))
        start.update({f"{f}.{k}": v for k, v in params.get(f, {}).items()})
    specs = baseline_specs(cfg_on) if len(forms) > 1 else _refit_specs(cfg_on, forms[0])
    fit = calibrate(problem, cfg_on, specs, start=start, centre=centre, max_nfev=REFIT_NFEV)
    s_new = ctx.scores(fit.cfg)
    abl_cfg = fit.cfg
    for f in forms:
        abl_cfg = switch(abl_cfg, f, False)
    v_abl = problem.vector(abl_cfg)
    rss_abl = float(v_abl @ v_abl)
    c = ctx.compare(cur_scores, s_new)
    own, own_train = _own(ctx, fit, s_new, abl_cfg, rss_abl)
    bounds = [b for b in fit.at_bound if b["key"].split(".")[0] in forms]
    ok, why = _gate(c, own_train, own, bounds, ctx.outputs)
    return {"fit": fit, "scores": s_new, "cmp": c, "ok": ok, "why": why, "own_train": own_train, "own": own,
            "abl_cfg": abl_cfg, "rss_abl": rss_abl, "forms": forms}


def _own(ctx: _Context, fit: Fit, s_fit: Scores, abl_cfg: dict, rss_abl: float | None = None
         ) -> tuple[Comparison | None, float]:
    """Held-out comparison of the ablated config against the fit (None where the ablation changes
    nothing held out) and the training-fit loss per sample of the ablation."""
    if rss_abl is None:
        v = ctx.small.vector(abl_cfg)
        rss_abl = float(v @ v)
    s_abl = ctx.scores(abl_cfg)
    # resample only the units where the form acts (changes the error by a tenth of the floor
    # per sample or more): elsewhere the comparison is about 0 by construction
    acting = np.abs(s_abl.sse - s_fit.sse).sum(axis=1) >= 0.1 * FLOOR * s_fit.count.max(axis=1)
    own = ctx.compare(s_abl.subset(acting), s_fit.subset(acting)) if acting.any() else None
    return own, (rss_abl - fit.rss) / max(fit.n, 1)


def _iteration(ctx: _Context, current: Fit, cur_scores: Scores, named_families: list[str], centre: dict,
               it: int, say: Progress) -> tuple[dict, tuple | None, tuple | None]:
    """Screen, refit, gate. Returns (evidence, pick, better_current): ``pick`` = (form, fit, scores,
    comparison, form confidence, selection confidence) or None; ``better_current`` = (fit, scores)
    when a refit showed the judged parameters were a poorer optimum (the caller re-runs)."""
    problem = ctx.problem
    small = ctx.small
    residual = stacked(small.residuals(current.cfg), ctx.outputs)
    scale = _run_scale(ctx, current.cfg)
    forms = _eligible(ctx, current.cfg, named_families)
    say(f"iteration {it}: screening {len(forms)} candidate forms")
    jac = jacobian(small, current.cfg, residual)
    screened = {f: screen(small, current.cfg, f, residual, residual, scale, jac) for f in forms}
    by_family: dict[str, list[str]] = {}
    for f in sorted(forms, key=lambda f: -screened[f]["score"]):
        if screened[f]["score"] >= SCREEN_MIN:
            by_family.setdefault(FAMILY_OF[f], []).append(f)
    fam_rank = sorted(by_family, key=lambda fam: -screened[by_family[fam][0]]["score"])
    # every form of the leading family (the form is decided on held-out data, not by the
    # screen), then the best form of each next family
    to_refit: list[str] = list(by_family[fam_rank[0]]) if fam_rank else []
    top = screened[to_refit[0]]["score"] if to_refit else 0.0
    for fam in fam_rank[1:]:
        if len(to_refit) < REFIT_MAX and screened[by_family[fam][0]]["score"] >= CONTENDER * top:
            to_refit.append(by_family[fam][0])
    evidence: dict = {"iteration": it, "screened": {f: {"family": FAMILY_OF[f], **screened[f]} for f in forms},
                      "refit": {}, "named": None}
    jobs = [(f,) for f in to_refit]
    for f in to_refit:
        comp = [g for g in COMPANIONS.get(f, ()) if g in forms or (g in FAMILIES and
                                                                    _companion_ok(ctx, current.cfg, g))]
        jobs += [(f, *comp)] if comp else []
    results = {}
    for fs in jobs:
        f = "+".join(fs)
        say(f"iteration {it}: refitting {' with '.join(FAMILY_OF[g] for g in fs)} ({FAMILIES[FAMILY_OF[fs[0]]][fs[0]]})")
        params = {g: (screened[g]["params"] if g in screened else {}) for g in fs}
        res = _refit(ctx, current, cur_scores, fs, params, centre)
        results[f] = res
        evidence["refit"][f] = {"family": FAMILY_OF[fs[0]], "form": FAMILIES[FAMILY_OF[fs[0]]][fs[0]],
                                "passed": res["ok"],
                                "reason": res["why"], "heldout": res["cmp"].to_json(),
                                "own_train_noise_var": res["own_train"],
                                "own_heldout": res["own"].to_json() if res["own"] is not None else None,
                                "params": {s.key: res["fit"].values.get(s.key) for g in fs for s in FORM_SPECS[g]},
                                "at_bound": res["fit"].at_bound}
    cur_small = ctx.small.vector(current.cfg)
    rss_cur_small = float(cur_small @ cur_small)
    stuck = [f for f, r in results.items() if r["rss_abl"] < rss_cur_small * (1 - 1e-3)]
    if stuck:
        f = min(stuck, key=lambda f: results[f]["rss_abl"])
        say(f"iteration {it}: a refit found better values of the model's own parameters; re-calibrating")
        cfg = results[f]["abl_cfg"]
        fit = calibrate(problem, cfg, baseline_specs(cfg), start=None, centre=centre, max_nfev=40)
        if fit.rss < current.rss:
            evidence["recalibrated"] = f"the judged parameters were a poorer optimum (found while refitting {f})"
            return evidence, None, (fit, ctx.scores(fit.cfg))
    passing = [f for f, r in results.items() if r["ok"]]
    if not passing:
        return evidence, None, None
    best = max(passing, key=lambda f: results[f]["cmp"].improvement["pooled"])
    draws = {f: r["cmp"].draws for f, r in results.items()}
    rivals = [f for f in passing if f != best]
    select = float(np.mean(np.all([draws[best] > draws[f] for f in rivals], axis=0))) if rivals else 1.0
    lead = results[best]["forms"][0]
    same = [f for f, r in results.items() if r["forms"][0] != lead and FAMILY_OF[r["forms"][0]] == FAMILY_OF[lead]]
    form_conf = float(np.mean(np.all([draws[best] > draws[f] for f in same], axis=0))) if same else 1.0
    r = results[best]
    fit, s_new, c = r["fit"], r["scores"], r["cmp"]
    picked = [lead]
    for g in r["forms"][1:]:   # a companion is named only if its own part passes too
        own, own_train = _own(ctx, fit, s_new, switch(fit.cfg, g, False))
        ok = own_train >= FLOOR and (own is None or own.ci95["pooled"][0] > 0)
        evidence["refit"][best][f"companion_{g}"] = {"passed": ok, "own_train_noise_var": own_train,
                                                     "own_heldout": own.to_json() if own else None}
        if ok:
            picked.append(g)
        else:
            fit = calibrate(ctx.small, switch(fit.cfg, g, False), baseline_specs(switch(fit.cfg, g, False)),
                            start=dict(fit.values), centre=centre, max_nfev=REFIT_NFEV)
            s_new = ctx.scores(fit.cfg)
            c = ctx.compare(cur_scores, s_new)
    evidence["named"] = picked
    # polish every parameter on the full subsample (a resistance-side refit kept the length's
    # parameters, which the judged calibration may have bent to absorb the resistance structure)
    say(f"iteration {it}: polishing every parameter with {' and '.join(FAMILY_OF[g] for g in picked)}")
    polished = calibrate(problem, fit.cfg, baseline_specs(fit.cfg), start=dict(fit.values), centre=centre,
                         max_nfev=REFIT_NFEV)
    fit, s_new = polished, ctx.scores(polished.cfg)     # never worse than its start on the full subsample
    c = ctx.compare(cur_scores, s_new)
    return evidence, (picked, fit, s_new, c, form_conf, select), None


def _companion_ok(ctx: _Context, cfg: Mapping[str, Any], g: str) -> bool:
    fam = FAMILY_OF.get(g)
    on = set(enabled_effects(cfg))
    return fam is not None and not any(f in on for f in FAMILIES[fam]) and \
        any(k in ctx.kinds for k in NEEDS.get(fam, ())) and _blamable(ctx, fam, on)


def _series(ctx: _Context, before: list[dict], after: list[dict]) -> dict[str, np.ndarray]:
    parts: dict[str, list] = {k: [] for k in ("t", "heldout")}
    t_off = 0.0
    for r, b, a in zip(ctx.inputs, before, after):
        parts["t"].append(r.t - r.t[0] + t_off)
        t_off += r.duration_s + 1.0
        parts["heldout"].append(r.heldout)
        for o in OUTPUTS:
            for key, arr in ((f"{o}_measured", r.output(o)), (f"{o}_before", b[o]), (f"{o}_after", a[o])):
                parts.setdefault(key, []).append(arr)
    return {k: np.concatenate(v) for k, v in parts.items()}


def _r2_noise_free(ctx: _Context, sims: list[dict], o: str) -> float | None:
    """1 - (held-out MSE - noise) / (held-out variance - noise), or None without signal."""
    meas = np.concatenate([r.output(o)[r.heldout & r.scored] for r in ctx.inputs])
    sim = np.concatenate([s[o][r.heldout & r.scored] for r, s in zip(ctx.inputs, sims)])
    ok = np.isfinite(meas) & np.isfinite(sim)
    if ok.sum() < 20:
        return None
    nv = ctx.noise[o].rms ** 2
    var = float(np.var(meas[ok])) - nv
    if var < 4 * nv:
        return None
    mse = float(np.mean((sim[ok] - meas[ok]) ** 2)) - nv
    return 1.0 - max(mse, 0.0) / var


def diagnose(runs: list, model_plant_cfg: Mapping[str, Any], holdout: str | None = None, *, max_causes: int = 3,
             seed: int = 0, progress: Progress | None = None, outputs: tuple[str, ...] | None = None,
             model_path: str | Path | None = None) -> DiagnoseResult:
    """Judge ``model_plant_cfg`` against ``runs`` (RunData); see the module docstring.

    Raises :class:`~tsa_bench.analysis.holdout.HoldoutError` for a bad ``holdout`` and
    ValueError for bad ``outputs``; every other problem of the data ends in a verdict.
    """
    t0 = time.perf_counter()
    say = progress or (lambda msg: None)
    outputs = tuple(outputs or OUTPUTS)
    if not outputs or any(o not in OUTPUTS for o in outputs):
        raise ValueError(f"outputs must be among {', '.join(OUTPUTS)}, got {', '.join(outputs) or 'none'}")
    model = dict(model_plant_cfg)
    inputs = [run_inputs(r, float(model.get("initial_load_g", 0.0))) for r in runs]
    notes: list[str] = []
    finish = _Finisher(runs, model, model_path, seed, t0, outputs, notes)
    say("checking the inputs")
    missing = missing_inputs(inputs, outputs)
    hold = split(inputs, holdout) if not missing else Holdout(holdout or "default", "not applied")
    if missing:
        return finish.mismatch_only(missing, hold)
    if not all(r.load_recorded for r in inputs):
        notes.append(f"a run records no load; the model's initial_load_g ({model.get('initial_load_g', 0)} g) is "
                     "assumed")
    if hold.one_sided:
        notes.append("excitation on one side of the holdout only: " + ", ".join(hold.one_sided))
    noise = {o: noise_model(inputs, o) for o in outputs}
    bad = [(f"{o}: too few samples to estimate the sensor noise", "record longer holds") for o in outputs
           if not np.isfinite(noise[o].rms)]
    for o in outputs:
        y = np.concatenate([r.output(o) for r in inputs])
        spread = float(np.nanstd(y)) if np.isfinite(y).any() else 0.0
        if np.isfinite(noise[o].rms) and noise[o].rms ** 2 > 0.5 * spread ** 2:
            other = [p for p in OUTPUTS if p != o]
            bad.append((f"the {o} reading is mostly noise (sample-to-sample scatter {noise[o].rms:.3g} against a "
                        f"spread of {spread:.3g} {UNITS[o]}): nothing to judge the model on",
                        f"check the {o} sensor and column, or judge the other output alone: --outputs {other[0]}"))
    if bad:
        return finish.mismatch_only(bad, hold)
    ctx = _Context(inputs, outputs, noise, hold, seed)

    say("calibrating the judged model: geometry from the holds")
    pts = hold_points(inputs)
    start = staged_start(model, pts, noise["length"].sigma) if "length" in outputs else {}
    specs = baseline_specs(model)
    centre = {s.key: get_value(model, s.key) for s in specs}
    say("calibrating the judged model: all parameters")
    fit0 = calibrate(ctx.problem, model, specs, start=start, centre=centre, max_nfev=60)
    if fit0.rss / max(fit0.n, 1) > 4.0 and start:
        say("calibrating the judged model: second start (the model's own values)")
        alt = calibrate(ctx.problem, model, specs, centre=centre, max_nfev=60)
        if alt.rss < fit0.rss:
            fit0 = alt
    say("testing the judged model's residuals")
    s0 = ctx.scores(fit0.cfg)
    r0 = get_value(fit0.cfg, "geometry.resistance_ohm")
    tests0 = ctx.residual_tests(s0.sims, r0)
    structured = [o for o in outputs if tests0[o]["structured"]]
    ctx.source = set(structured)
    if len(structured) > 1:
        ctx.induced = _induced(ctx, fit0, structured, centre, say)
        for o in sorted(ctx.induced):
            notes.append(f"the {o} residual is structured only when the model must fit both outputs: calibrated on "
                         f"the {o} alone it is noise, so its structure comes from the other output's misfit and "
                         f"effects acting on the {o} alone are not candidates")
    current, cur_scores = fit0, s0
    _s0_first = s0
    chosen: list[dict] = []
    iterations: list[dict] = []
    candidates: dict[str, Candidate] = {}
    if any(t["structured"] for t in tests0.values()):
        it, redone = 1, False
        while it <= max_causes:
            ev, pick, better = _iteration(ctx, current, cur_scores, [FAMILY_OF[c["form"]] for c in chosen], centre,
                                          it, say)
            iterations.append(ev)
            for f, s in ev["screened"].items():
                candidates[f] = Candidate(f, "effect", s["score"], {"family": FAMILY_OF[f],
                                                                    "form": FAMILIES[FAMILY_OF[f]][f],
                                                                    "iteration": it, "screen": s,
                                                                    **({"refit": ev["refit"][f]} if f in ev["refit"]
                                                                       else {})})
            if better is not None and not redone:
                current, cur_scores = better
                if not chosen:
                    fit0, s0 = better
                notes.append(f"iteration {it}: re-calibrated the model's own parameters (a better optimum)")
                redone = True
                continue
            redone = False
            if pick is None:
                notes.append(f"iteration {it}: no candidate passed the naming gate")
                break
            picked, fit, s_new, c, form_conf, select = pick
            for k, form in enumerate(picked):
                chosen.append({"form": form, "gain": c.relative, "form_conf": form_conf if k == 0 else 1.0,
                               "select": select, "before": (current, cur_scores)})
                notes.append(f"iteration {it}: {FAMILY_OF[form]} ({FAMILIES[FAMILY_OF[form]][form]}) passed"
                             + (f", held-out improvement {c.improvement['pooled']:.2f} noise variances" if k == 0
                                else " as its companion"))
            current, cur_scores = fit, s_new
            it += 1
    else:
        notes.append("the judged model's residuals are consistent with the noise model: no candidate screened")
    if chosen and chosen[0]["before"][0] is not fit0:
        fit0, s0 = chosen[0]["before"]
    if s0 is not _s0_first:
        tests0 = ctx.residual_tests(s0.sims, get_value(fit0.cfg, "geometry.resistance_ohm"))
    return finish.complete(ctx, fit0, s0, tests0, current, cur_scores, chosen, iterations, candidates, hold, centre,
                           say)


class _Finisher:
    """Builds the result (final checks, ordering, verdict, provenance)."""

    def __init__(self, runs, model, model_path, seed, t0, outputs, notes) -> None:
        self.runs, self.model, self.model_path, self.seed, self.t0 = runs, model, model_path, seed, t0
        self.outputs, self.notes = outputs, notes

    def _prov(self, hold: Holdout) -> dict:
        import json
        return provenance(self.runs, self.model_path, json.dumps(self.model, sort_keys=True, default=str),
                          hold.to_json(), self.seed, time.perf_counter() - self.t0)

    def mismatch_only(self, missing: list[tuple[str, str]], hold: Holdout) -> DiagnoseResult:
        mism = vd.mismatch_entries(missing, [], {})
        effects = enabled_effects(self.model)
        return DiagnoseResult("model_mismatch", vd.summary_line("model_mismatch", [], [], mism, {}), [], [], [], {},
                              effects, effects, {}, {}, self.notes, mismatch=mism, holdout=hold.to_json(),
                              provenance=self._prov(hold), outputs=self.outputs)

    def complete(self, ctx: _Context, fit0: Fit, s0: Scores, tests0: dict, current: Fit, cur_scores: Scores,
                 chosen: list[dict], iterations: list[dict], candidates: dict, hold: Holdout, centre: dict,
                 say: Progress) -> DiagnoseResult:
        say("testing the final model")
        r0 = get_value(current.cfg, "geometry.resistance_ohm")
        tests1 = ctx.residual_tests(cur_scores.sims, r0) if chosen else tests0
        states = {o: vd.OutputState(tests0[o], tests1[o], _r2_noise_free(ctx, cur_scores.sims, o), UNITS[o])
                  for o in ctx.outputs}
        named, partial = [], []
        for k, ch in enumerate(chosen):
            form = ch["form"]
            fam = FAMILY_OF[form]
            if len(chosen) == 1:
                s_drop = s0            # the judged model, calibrated without it
            else:
                say(f"final model: re-calibrating without {fam} to measure its own part")
                cfg = switch(current.cfg, form, False)
                drop = calibrate(ctx.small, cfg, baseline_specs(cfg), start=dict(current.values), centre=centre,
                                 max_nfev=REFIT_NFEV)
                s_drop = ctx.scores(drop.cfg)
            own = ctx.compare(s_drop, cur_scores)
            main = max(ctx.outputs, key=lambda o: own.improvement[o])
            share = vd.share_removed(states[main])
            cause = NamedCause(fam, FAMILIES[fam][form], form, main,
                               own.p_above["pooled"], ch["form_conf"], own.improvement["pooled"],
                               own.ci95["pooled"], ch["gain"],
                               {s.key: current.values.get(s.key) for s in FORM_SPECS[form]})
            if share < vd.SHARE_MIN:
                partial.append({**cause.to_json(), "explained_share": share,
                                "why": f"removes only {100 * share:.0f} % of the {main} residual's structure"})
                continue
            if states[main].after.get("structured"):
                cause.caveats.append(vd.follows_text(main, states[main].after) + " after naming it (the final model "
                                     f"removed {vd.percent(share)} of the structure)")
                cause.confidence *= share
            named.append(cause)
        named.sort(key=lambda c: -c.own_improvement)
        bounds = [b for b in current.at_bound if b["key"].split(".")[0] not in FAMILY_OF]
        mism = vd.mismatch_entries([], bounds, states)
        unexplained = [vd.unexplained_entry(o, st, o in ctx.induced) for o, st in states.items()
                       if st.after.get("structured")]
        unexplained.sort(key=lambda u: u["induced"])
        if mism:
            verdict = "model_mismatch"
            partial += [{**c.to_json(), "why": "the model does not represent the data"} for c in named]
            named = []
        elif named:
            verdict = "named"
        elif unexplained:
            verdict = "unexplained"
        else:
            verdict = "explained"
        summary = vd.summary_line(verdict, named, unexplained, mism, states)
        gains = []
        m0, m1 = s0.mse(), cur_scores.mse()
        for o in ctx.outputs:
            b, a = np.sqrt(m0[o]) * ctx.sigma[o], np.sqrt(m1[o]) * ctx.sigma[o]
            gains.append(Gain(o, float(b), float(a), float((b - a) / b) if b > 0 and np.isfinite(a) else 0.0))
        series = _series(ctx, s0.sims, cur_scores.sims)
        if named:
            off = ctx.scores(switch(current.cfg, named[0].variant, False)).sims
            o = named[0].output
            series["cause_signal"] = np.concatenate([s[o] - f[o] for s, f in zip(cur_scores.sims, off)])
        calibration = {"judged": {"at_bound": fit0.at_bound, "undetermined": fit0.undetermined,
                                  "dropped": fit0.dropped, "rms_noise_units": float(np.sqrt(fit0.rss / max(fit0.n, 1)))},
                       "final": {"at_bound": current.at_bound, "undetermined": current.undetermined,
                                 "dropped": current.dropped,
                                 "rms_noise_units": float(np.sqrt(current.rss / max(current.n, 1)))}}
        if fit0.undetermined:
            self.notes.append("not determined by these data (kept near the model's values): "
                              + ", ".join(fit0.undetermined))
        cands = sorted(candidates.values(), key=lambda c: -c.score)
        self.notes.append(f"diagnose took {time.perf_counter() - self.t0:.1f} s")
        return DiagnoseResult(
            verdict, summary, named, cands, gains, {"before": tests0, "after": tests1},
            enabled_effects(self.model), enabled_effects(current.cfg),
            {"before": dict(fit0.values), "after": dict(current.values)}, series, self.notes,
            unexplained=unexplained, mismatch=mism, partial=partial,
            noise={o: ctx.noise[o].to_json() for o in ctx.outputs}, calibration=calibration,
            holdout=hold.to_json(), iterations=iterations, provenance=self._prov(hold), outputs=ctx.outputs)
