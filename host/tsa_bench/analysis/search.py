"""The search for causes: forward selection through the naming gate, then backward elimination.

Units: improvements in noise variances per sample (:mod:`tsa_bench.analysis.scoring`).

Contract: :func:`search` adds one cause per iteration (:func:`tsa_bench.analysis.naming.iteration`:
screen, refit, gate) until nothing passes the gate or ``max_causes`` are in the model; then
each cause's **own part** is measured (the held-out improvement of the model over the model
re-calibrated without it; with one cause, over the judged model). A cause whose own part's
95 % interval reaches 0, or whose estimate is below the floor, no longer earns its place:
the weakest such cause is **demoted**, it leaves the model (the model is re-calibrated
without it), its form is not tried again, and its iteration is given back, so the forward
search resumes from the smaller model. This repeats until every cause in the model earns
its place; at most :data:`EXTRA_ITERATIONS` iterations beyond ``2 max_causes`` are run in
all, so the cost stays bounded. The model returned holds the causes named and nothing else.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tsa_bench.analysis.calibrate import Fit, calibrate
from tsa_bench.analysis.context import FLOOR, REFIT_NFEV, Context, Progress
from tsa_bench.analysis.families import FAMILIES, FAMILY_OF, OUTPUT_OF
from tsa_bench.analysis.modelspec import baseline_specs, switch
from tsa_bench.analysis.naming import iteration
from tsa_bench.analysis.result import Candidate
from tsa_bench.analysis.scoring import Comparison, Scores

EXTRA_ITERATIONS = 2


@dataclass
class Chosen:
    """A cause in the model: its form and what the search learnt of it."""

    form: str
    gain: dict[str, float]              # relative held-out MSE gain per output when it was added
    form_conf: float
    select: float
    iteration: int
    alternatives: list[dict] = field(default_factory=list)
    at_bound: list[dict] = field(default_factory=list)
    before: tuple | None = None         # (fit, scores) of the model it was added to
    own: Comparison | None = None       # the model against the model without it (held out)

    @property
    def family(self) -> str:
        return FAMILY_OF[self.form]

    def main_output(self, outputs: tuple[str, ...]) -> str:
        """The output the cause is judged on: the one its family acts on when its own part is
        significant there, else the one where it is most clearly so."""
        acts = OUTPUT_OF[self.family]
        if self.own is None:
            return acts if acts in outputs else outputs[0]
        return acts if acts in outputs and self.own.lower.get(acts, -1.0) > 0 else self.own.main_output()


@dataclass
class SearchResult:
    fit0: Fit                           # the judged model (re-calibrated if a refit found a better optimum)
    s0: Scores
    current: Fit                        # the final model: the named causes and nothing else
    scores: Scores
    chosen: list[Chosen]
    demoted: list[dict]
    iterations: list[dict]
    candidates: dict[str, Candidate]


def own_parts(ctx: Context, current: Fit, scores: Scores, chosen: list[Chosen], s0: Scores, centre: dict,
              say: Progress) -> dict[str, Fit | None]:
    """Set each cause's ``own`` comparison; returns, per form, the model re-calibrated without it
    (None with a single cause: the judged model is that model)."""
    drops: dict[str, Fit | None] = {}
    for k, c in enumerate(chosen):
        if len(chosen) == 1:
            c.own, drops[c.form] = ctx.compare(s0, scores), None
            continue
        say(f"backward elimination: re-calibrating without {c.family}, {k + 1} of {len(chosen)}")
        cfg = switch(current.cfg, c.form, False)
        drop = calibrate(ctx.small, cfg, baseline_specs(cfg), start=dict(current.values), centre=centre,
                         max_nfev=REFIT_NFEV)
        c.own, drops[c.form] = ctx.compare(ctx.scores(drop.cfg, keep_sims=False), scores), drop
    return drops


def earns_place(c: Chosen) -> bool:
    """Whether the model does significantly and relevantly better with the cause than without it."""
    return c.own is not None and c.own.significant(FLOOR)


def eliminate(ctx: Context, current: Fit, scores: Scores, chosen: list[Chosen], fit0: Fit, s0: Scores,
              centre: dict, say: Progress) -> tuple[Fit, Scores, list[Chosen], dict | None]:
    """One backward step: measure every cause's own part and demote the weakest that does not earn
    its place (it leaves the model, which is re-calibrated without it). Returns the model, its
    scores, the causes kept and the demoted one (None: all earn their place)."""
    drops = own_parts(ctx, current, scores, chosen, s0, centre, say)
    weak = [c for c in chosen if not earns_place(c)]
    if not weak:
        return current, scores, chosen, None
    w = min(weak, key=lambda c: c.own.improvement["pooled"] if c.own else 0.0)
    main = w.main_output(ctx.outputs)
    lo, hi = w.own.ci95[main] if w.own else (0.0, 0.0)
    demoted = {"form": w.form, "family": w.family, "iteration": w.iteration,
               "own_improvement_noise_var": w.own.improvement["pooled"] if w.own else 0.0,
               "own_improvement_ci95": [lo, hi],
               "why": f"in the model with the other causes its own held-out improvement is not significantly above "
                      f"the floor on any output ({main}: 95 % {lo:.3g} to {hi:.3g} noise variances per sample): "
                      "removed from the model"}
    kept = [c for c in chosen if c is not w]
    drop = drops.get(w.form)
    if not kept:
        return fit0, s0, kept, demoted
    say(f"backward elimination: {w.family} removed; re-calibrating the model without it")
    cfg = switch(current.cfg, w.form, False) if drop is None else drop.cfg
    start = dict(current.values) if drop is None else dict(drop.values)
    fit = calibrate(ctx.problem, cfg, baseline_specs(cfg), start=start, centre=centre, max_nfev=REFIT_NFEV)
    return fit, ctx.scores(fit.cfg), kept, demoted


def confirm_alternatives(ctx: Context, current: Fit, scores: Scores, chosen: list[Chosen], centre: dict,
                         say: Progress) -> None:
    """Keep as an alternative of a named cause only what explains the held-out data as well in the
    final model: the cause is swapped for it (the model re-calibrated) and the final model must not
    be significantly better (on any output) than the swapped one. Alternatives named themselves are
    dropped."""
    named = {c.family for c in chosen}
    for c in chosen:
        kept = []
        for a in c.alternatives:
            if a["effect"] in named:
                continue
            say(f"confusability: {c.family} swapped for {a['effect']} ({a['form']})")
            params = {k.split(".", 1)[1]: v for k, v in a["params"].items() if v is not None}
            cfg = switch(switch(current.cfg, c.form, False), a["variant"], True, params)
            start = {**current.values, **{k: v for k, v in a["params"].items() if v is not None}}
            fit = calibrate(ctx.small, cfg, baseline_specs(cfg), start=start, centre=centre, max_nfev=REFIT_NFEV)
            swap = ctx.compare(ctx.scores(fit.cfg, keep_sims=False), scores)
            a["final_model_better_on"] = [o for o in ctx.outputs if swap.lower[o] > 0]
            if not swap.significant(0.0):
                kept.append(a)
        c.alternatives = kept


def search(ctx: Context, fit0: Fit, s0: Scores, centre: dict, max_causes: int, say: Progress,
           notes: list[str]) -> SearchResult:
    """Forward selection then backward elimination (module docstring)."""
    current, scores = fit0, s0
    chosen: list[Chosen] = []
    demoted: list[dict] = []
    excluded: set[str] = set()
    iterations: list[dict] = []
    candidates: dict[str, Candidate] = {}
    budget = 2 * max_causes + EXTRA_ITERATIONS
    it, redone = 0, False
    while True:
        while len(chosen) < max_causes and it < budget:
            it += 0 if redone else 1
            tag = f"{it} (at most {budget})"
            ev, pick, better = iteration(ctx, current, scores, [c.family for c in chosen], centre, it,
                                         lambda m: say(m.replace(f"iteration {it}:", f"iteration {tag}:", 1)),
                                         frozenset(excluded))
            iterations.append(ev)
            for f, sc in ev["screened"].items():
                candidates[f] = Candidate(f, "effect", sc["score"], {
                    "family": FAMILY_OF[f], "form": FAMILIES[FAMILY_OF[f]][f], "iteration": it, "screen": sc,
                    **({"refit": ev["refit"][f]} if f in ev["refit"] else {})})
            if better is not None and not redone:
                current, scores = better
                if not chosen:
                    fit0, s0 = better
                notes.append(f"iteration {it}: re-calibrated the model's own parameters (a better optimum)")
                redone = True
                continue
            redone = False
            if pick is None:
                notes.append(f"iteration {it}: no candidate passed the naming gate")
                break
            for k, form in enumerate(pick["forms"]):
                chosen.append(Chosen(form, pick["cmp"].relative, pick["form_conf"] if k == 0 else 1.0,
                                     pick["select"], it, pick["alternatives"] if k == 0 else [],
                                     [b for b in pick["at_bound"] if b["key"].split(".")[0] == form],
                                     (current, scores)))
                notes.append(f"iteration {it}: {FAMILY_OF[form]} ({FAMILIES[FAMILY_OF[form]][form]}) passed"
                             + (f", held-out improvement {pick['cmp'].improvement['pooled']:.2f} noise variances"
                                if k == 0 else " as its companion"))
            current, scores = pick["fit"], pick["scores"]
        if not chosen:
            break
        current, scores, chosen, out = eliminate(ctx, current, scores, chosen, fit0, s0, centre, say)
        if out is None:
            break
        demoted.append(out)
        excluded.add(out["form"])
        notes.append(f"backward elimination: {out['family']} ({FAMILIES[out['family']][out['form']]}) demoted and "
                     "removed from the model; its iteration is given back")
    confirm_alternatives(ctx, current, scores, chosen, centre, say)
    if chosen and chosen[0].before is not None and chosen[0].before[0] is not fit0:
        fit0, s0 = chosen[0].before
    if not chosen:
        current, scores = fit0, s0
    return SearchResult(fit0, s0, current, scores, chosen, demoted, iterations, candidates)
