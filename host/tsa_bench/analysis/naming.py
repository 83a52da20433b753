"""Candidates, refits and the naming gate: one iteration of the search for a cause.

Units: improvements in noise variances per sample (:mod:`tsa_bench.analysis.scoring`).

Contract: :func:`iteration` screens every candidate form the data can test and may blame
(:func:`eligible`), refits the contenders together with the model's own parameters on
the smaller subsample, gates each (:func:`gate`; the rule is in
:mod:`tsa_bench.analysis.diagnose` and docs/diagnose.md), polishes the one named on the
full subsample and returns the evidence of the iteration. :func:`induced` finds outputs
whose structure is only the other output's misfit showing through the joint fit.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from tsa_bench.analysis.calibrate import Fit, Problem, calibrate
from tsa_bench.analysis.context import (COMPANIONS, CONTENDER, FLOOR, HARM_P, HARM_REL, PROPAGATED, REFIT_MAX,
                                        REFIT_NFEV, SCREEN_MIN, Context, Progress, run_scale)
from tsa_bench.analysis.families import FAMILIES, FAMILY_OF, FORM_SPECS, NEEDS, OUTPUT_OF, READING_ONLY
from tsa_bench.analysis.modelspec import baseline_specs, enabled_effects, get_value, switch
from tsa_bench.analysis.noise import window_length
from tsa_bench.analysis.scoring import Comparison, Scores
from tsa_bench.analysis.screening import jacobian, screen, stacked


def induced(ctx: Context, fit0: Fit, structured: list[str], centre: dict, say: Progress) -> set[str]:
    """Outputs whose residual is noise when the judged model is calibrated on them alone."""
    out = set()
    for o in structured:
        say(f"calibrating the judged model on the {o} alone")
        p = ctx.small
        alone = Problem(p.runs, p.idx, p.train, p.sigma, (o,), p.cache, p.state)
        fit = calibrate(alone, fit0.cfg, baseline_specs(fit0.cfg), start=dict(fit0.values), centre=centre,
                        max_nfev=REFIT_NFEV)
        sims = ctx.scores(fit.cfg).sims
        test = ctx.residual_tests(sims, get_value(fit.cfg, "geometry.resistance_ohm"))[o]
        if not test["structured"]:
            out.add(o)
    return out if len(out) < len(structured) else set()


def _blamable(ctx: Context, fam: str, on: set[str], propagated: bool = False) -> bool:
    """Whether the output ``fam`` acts on (length effects also through dR/dX) was structured in
    the judged model on its own account (a later cause must never just repair what an earlier
    one did to an output that was fine) and, for effects on the resistance alone, whether its
    structure now is more than the length error showing through dR/dX (``propagated``)."""
    acts = OUTPUT_OF[fam]
    if acts not in ctx.outputs:
        acts = "resistance" if acts == "length" and "resistance_length" in on and fam not in READING_ONLY else ""
    if acts == "resistance" and OUTPUT_OF[fam] == "resistance" and propagated:
        return False
    return acts in ctx.source and acts not in ctx.induced


def propagated_share(ctx: Context, scores: Scores, cfg: Mapping[str, Any]) -> float:
    """Share of the resistance residual's slow structure that the length residual explains
    through one coefficient (the model's resistance follows its length: a length error shows in
    the resistance as dR/dX times itself). Window means (the structure test's windows) keep the
    regressor's noise from hiding the relation."""
    if not {"length", "resistance"} <= set(ctx.outputs):
        return 0.0
    w = window_length(ctx.rate)
    el, er = [], []
    for r, sim in zip(ctx.inputs, scores.sims):
        dl, dr = sim["length"] - r.length, sim["resistance"] - r.resistance
        ok = np.isfinite(dl) & np.isfinite(dr) & r.scored
        m = int(ok.sum()) // w
        if m:
            el.append(dl[ok][: m * w].reshape(m, w).mean(axis=1))
            er.append(dr[ok][: m * w].reshape(m, w).mean(axis=1))
    if not el:
        return 0.0
    x, y = np.concatenate(el), np.concatenate(er)
    x0, y0 = x - x.mean(), y - y.mean()
    sxx = float(x0 @ x0)
    noise_r = ctx.noise["resistance"].inflation * ctx.noise["resistance"].rms ** 2 / w
    structured = float(np.mean(y0 * y0)) - noise_r
    if sxx <= 0 or structured <= 0:
        return 0.0
    explained = float((x0 @ y0) ** 2 / sxx) / len(y0)
    return min(1.0, explained / structured)


def eligible(ctx: Context, cfg: Mapping[str, Any], named_families: list[str], propagated: bool = False
             ) -> list[str]:
    on = set(enabled_effects(cfg))
    out = []
    for fam, forms in FAMILIES.items():
        if fam in named_families or any(f in on for f in forms):
            continue
        if not any(k in ctx.kinds for k in NEEDS.get(fam, ())):
            continue
        if not _blamable(ctx, fam, on, propagated):
            continue
        out += list(forms)
    return out


def gate(c: Comparison, own_train: float, own: Comparison | None, outputs: tuple[str, ...],
         bars: Mapping[str, tuple[float, str]] | None = None, acts: str = "length") -> tuple[bool, str]:
    """The naming gate (docs/diagnose.md, step 8). A form parameter at a soft bound does not
    stop it: it caps the cause's confidence (:func:`tsa_bench.analysis.confusion.cap`)."""
    if not c.significant(0.0):
        return False, "held-out improvement not significant (the 95 % interval reaches 0 on every output)"
    if c.improvement["pooled"] < FLOOR:
        return False, f"held-out improvement {c.improvement['pooled']:.3f} noise variances is below the floor {FLOOR}"
    if own_train < FLOOR:
        return False, "switching the form off again in the refitted model barely changes the fit: the gain is the " \
                      "re-calibration's, not the form's"
    if own is not None and not own.significant(0.0):
        return False, "where the form acts on the held-out data, switching it off is not significantly worse"
    main = acts if acts in outputs else max(outputs, key=lambda o: c.improvement[o])
    bar, earlier = (bars or {}).get(main, (0.0, ""))
    if c.improvement[main] <= bar:
        return False, (f"its improvement is within the uncertainty of {earlier}'s form on the {main} (the spread "
                       f"between that effect's forms, {bar:.3g} noise variances): it may only mop up that form's error")
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


def _refit(ctx: Context, current: Fit, cur_scores: Scores, forms: tuple[str, ...], params: dict, centre: dict
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
    s_new = ctx.scores(fit.cfg, keep_sims=False)
    abl_cfg = fit.cfg
    for f in forms:
        abl_cfg = switch(abl_cfg, f, False)
    v_abl = problem.vector(abl_cfg)
    rss_abl = float(v_abl @ v_abl)
    c = ctx.compare(cur_scores, s_new)
    own, own_train = _own(ctx, fit, s_new, abl_cfg, rss_abl)
    ok, why = gate(c, own_train, own, ctx.outputs, ctx.form_bars, OUTPUT_OF[FAMILY_OF[forms[0]]])
    if not ok and own_train >= FLOOR and c.improvement["pooled"] >= FLOOR:
        # a near miss may be the refit's coarser calibration: judge it calibrated as well as the
        # current model (every parameter, the full subsample) before turning it down
        fit = calibrate(ctx.problem, fit.cfg, baseline_specs(fit.cfg), start=dict(fit.values), centre=centre,
                        max_nfev=REFIT_NFEV)
        s_new = ctx.scores(fit.cfg, keep_sims=False)
        c = ctx.compare(cur_scores, s_new)
        v_abl = ctx.problem.vector(abl_cfg := _switch_off(fit.cfg, forms))
        rss_abl = float(v_abl @ v_abl)
        own, own_train = _own(ctx, fit, s_new, abl_cfg, rss_abl)
        ok, why = gate(c, own_train, own, ctx.outputs, ctx.form_bars, OUTPUT_OF[FAMILY_OF[forms[0]]])
        rss_abl = _rss(ctx.small, abl_cfg)
        problem = ctx.problem
    return {"fit": fit, "problem": problem, "scores": s_new, "cmp": c, "ok": ok, "why": why, "own_train": own_train, "own": own,
            "abl_cfg": abl_cfg, "rss_abl": rss_abl, "forms": forms}


def _switch_off(cfg: Mapping[str, Any], forms: tuple[str, ...]) -> dict:
    for f in forms:
        cfg = switch(cfg, f, False)
    return cfg


def _rss(problem: Problem, cfg: Mapping[str, Any]) -> float:
    v = problem.vector(cfg)
    return float(v @ v)


def _own(ctx: Context, fit: Fit, s_fit: Scores, abl_cfg: dict, rss_abl: float | None = None,
         problem: Problem | None = None) -> tuple[Comparison | None, float]:
    """Held-out comparison of the ablated config against the fit (None where the ablation changes
    nothing held out) and the training-fit loss per sample of the ablation (on ``problem``, the
    subsample the fit was made on)."""
    if rss_abl is None:
        rss_abl = _rss(problem or ctx.small, abl_cfg)
    s_abl = ctx.scores(abl_cfg, keep_sims=False)
    # resample only the units where the form acts (changes the error by a tenth of the floor
    # per sample or more): elsewhere the comparison is about 0 by construction
    acting = np.abs(s_abl.sse - s_fit.sse).sum(axis=1) >= 0.1 * FLOOR * s_fit.count.max(axis=1)
    own = ctx.compare(s_abl.subset(acting), s_fit.subset(acting)) if acting.any() else None
    return own, (rss_abl - fit.rss) / max(fit.n, 1)


def iteration(ctx: Context, current: Fit, cur_scores: Scores, named_families: list[str], centre: dict,
              it: int, say: Progress, exclude: frozenset[str] = frozenset()) -> tuple[dict, dict | None, tuple | None]:
    """Screen, refit, gate. Returns (evidence, pick, better_current): ``pick`` = {forms, fit, scores,
    cmp, form_conf, select, alternatives, at_bound} or None; ``better_current`` = (fit, scores)
    when a refit showed the judged parameters were a poorer optimum (the caller re-runs).
    ``exclude``: forms not screened (demoted earlier in this diagnosis)."""
    problem = ctx.problem
    small = ctx.small
    residual = stacked(small.residuals(current.cfg), ctx.outputs)
    scale = run_scale(ctx, current.cfg)
    share = propagated_share(ctx, cur_scores, current.cfg)
    # the length error shows in the resistance through dR/dX, unless the length's own structure is
    # only the resistance misfit showing through the joint fit (then the resistance is the source)
    propagated = share >= PROPAGATED and "length" not in ctx.induced
    forms = [f for f in eligible(ctx, current.cfg, named_families, propagated) if f not in exclude]
    say(f"iteration {it}: screening {len(forms)} candidate forms")
    jac = jacobian(small, current.cfg, residual)
    screened = {f: screen(small, current.cfg, f, residual, residual, scale, jac) for f in forms}
    # rank by the largest share of one output's residual a form explains: an output whose residual
    # is large in noise units (random hold offsets, say) must not hide an effect on the other one
    rank = {f: max([screened[f]["score"], *screened[f].get("per_output", {}).values()]) for f in forms}
    by_family: dict[str, list[str]] = {}
    for f in sorted(forms, key=lambda f: -rank[f]):
        if rank[f] >= SCREEN_MIN:
            by_family.setdefault(FAMILY_OF[f], []).append(f)
    fam_rank = sorted(by_family, key=lambda fam: -rank[by_family[fam][0]])
    # every form of the leading family (the form is decided on held-out data, not by the
    # screen), then the best form of each next family
    to_refit: list[str] = [f for f in FAMILIES[fam_rank[0]] if f in screened] if fam_rank else []
    to_refit.sort(key=lambda f: -rank[f])
    top = rank[to_refit[0]] if to_refit else 0.0
    for fam in fam_rank[1:]:
        if len(to_refit) < REFIT_MAX and rank[by_family[fam][0]] >= CONTENDER * top:
            to_refit.append(by_family[fam][0])
    evidence: dict = {"iteration": it, "resistance_structure_from_length": share, "screened": {f: {"family": FAMILY_OF[f], **screened[f]} for f in forms},
                      "refit": {}, "named": None}
    jobs = [(f,) for f in to_refit]
    for f in to_refit:
        comp = [g for g in COMPANIONS.get(f, ()) if g in forms or (g in FAMILIES and
                                                                    _companion_ok(ctx, current.cfg, g))]
        jobs += [(f, *comp)] if comp else []
    results = {}
    for k, fs in enumerate(jobs):
        f = "+".join(fs)
        say(f"iteration {it}: refitting {' with '.join(FAMILY_OF[g] for g in fs)} ({FAMILIES[FAMILY_OF[fs[0]]][fs[0]]}), "
            f"{k + 1} of {len(jobs)}")
        params = {g: (screened[g]["params"] if g in screened else {}) for g in fs}
        res = _refit(ctx, current, cur_scores, fs, params, centre)
        res["scores"] = res["scores"].without_sims()     # only its unit scores are compared from here on
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
    # how much the named effect's shape matters on the output it acts on: a later effect
    # acting there must beat this spread between its forms
    best_cmp = results[best]["cmp"]
    for o in ctx.outputs:
        if o != OUTPUT_OF[FAMILY_OF[lead]] or best_cmp.improvement[o] <= 0 or not same:
            continue
        spread = best_cmp.improvement[o] - max(results[f]["cmp"].improvement[o] for f in same)
        if spread > ctx.form_bars.get(o, (0.0, ""))[0]:
            ctx.form_bars[o] = (spread, FAMILY_OF[lead])
    r = results[best]
    fit, s_new, c = r["fit"], r["scores"], r["cmp"]
    picked = [lead]
    for g in r["forms"][1:]:   # a companion is named only if its own part passes too
        own, own_train = _own(ctx, fit, s_new, switch(fit.cfg, g, False), problem=r["problem"])
        ok = own_train >= FLOOR and (own is None or own.significant(0.0))
        evidence["refit"][best][f"companion_{g}"] = {"passed": ok, "own_train_noise_var": own_train,
                                                     "own_heldout": own.to_json() if own else None}
        if ok:
            picked.append(g)
        else:
            fit = calibrate(ctx.small, switch(fit.cfg, g, False), baseline_specs(switch(fit.cfg, g, False)),
                            start=dict(fit.values), centre=centre, max_nfev=REFIT_NFEV)
            s_new = ctx.scores(fit.cfg, keep_sims=False)
            c = ctx.compare(cur_scores, s_new)
    evidence["named"] = picked
    alternatives = rivals_within_interval(results, best, lead)
    evidence["alternatives"] = alternatives
    # polish every parameter on the full subsample (a resistance-side refit kept the length's
    # parameters, which the judged calibration may have bent to absorb the resistance structure)
    say(f"iteration {it}: polishing every parameter with {' and '.join(FAMILY_OF[g] for g in picked)}")
    polished = calibrate(problem, fit.cfg, baseline_specs(fit.cfg), start=dict(fit.values), centre=centre,
                         max_nfev=REFIT_NFEV)
    fit, s_new = polished, ctx.scores(polished.cfg)     # never worse than its start on the full subsample
    c = ctx.compare(cur_scores, s_new)
    at_bound = [b for b in fit.at_bound if b["key"].split(".")[0] in picked]
    return evidence, {"forms": picked, "fit": fit, "scores": s_new, "cmp": c, "form_conf": form_conf,
                      "select": select, "alternatives": alternatives, "at_bound": at_bound}, None


def rivals_within_interval(results: dict[str, dict], best: str, lead: str) -> list[dict]:
    """Refitted effects of other families whose held-out improvement the named one does not beat
    significantly (the 95 % interval of the paired difference of their bootstrap replicates reaches
    0) and that explain the held-out data themselves (interval above 0, at least the floor): the
    data cannot tell them from the named one."""
    out = []
    mine = results[best]["cmp"].draws
    for f, r in results.items():
        variant = r["forms"][0]
        if f == best or FAMILY_OF[variant] == FAMILY_OF[lead] or len(r["cmp"].draws) != len(mine):
            continue
        c = r["cmp"]
        if not (r["ok"] or c.significant(FLOOR)):
            continue
        d = mine - c.draws
        if float(np.percentile(d, 2.5)) > 0:
            continue
        out.append({"effect": FAMILY_OF[variant], "form": FAMILIES[FAMILY_OF[variant]][variant], "variant": variant,
                    "improvement_noise_var": c.improvement["pooled"], "ci95": list(c.ci95["pooled"]),
                    "named_better_share": float(np.mean(d > 0)),
                    "params": {s.key: r["fit"].values.get(s.key) for s in FORM_SPECS[variant]},
                    "at_bound": [b for b in r["fit"].at_bound if b["key"].split(".")[0] == variant]})
    return out


def _companion_ok(ctx: Context, cfg: Mapping[str, Any], g: str) -> bool:
    fam = FAMILY_OF.get(g)
    on = set(enabled_effects(cfg))
    return fam is not None and not any(f in on for f in FAMILIES[fam]) and \
        any(k in ctx.kinds for k in NEEDS.get(fam, ())) and _blamable(ctx, fam, on)


