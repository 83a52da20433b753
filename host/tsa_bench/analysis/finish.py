"""The end of a diagnosis: final checks, variance components, confidence, verdict, the extended model.

Units: RMSE in the output's units; improvements in noise variances per sample.

Contract: :class:`Finisher` turns the search's result (:mod:`tsa_bench.analysis.search`:
the final model holds the causes named and nothing else, each with its own part) into a
:class:`~tsa_bench.analysis.result.DiagnoseResult`: ``mismatch_only`` when the inputs
cannot be used, ``complete`` otherwise. ``complete`` tests the final model's residual;
where an output is still structured, fits its hold-to-hold variance component
(:mod:`tsa_bench.analysis.settling`) and names it when its likelihood-ratio test says
so, testing what is left once the offsets are removed. A cause whose output keeps most
of its structure (the final model removed less than half of it) is demoted and leaves
the model (re-calibrated without it). Confidence = the share of bootstrap replicates of
the cause's own part above the floor, times the share of the structure removed when its
output is still structured, capped by confusable alternatives and by form parameters at
the edge of their range (:mod:`tsa_bench.analysis.confusion`). The **extended model**
(``result.model_plant``: the final model's plant with the named effects, the
recalibrated parameters, the named variance components and the noise measured) goes
through a YAML round trip before the final held-out RMSE is computed from it, so that
the file ``--write-model`` writes gives that figure back bit for bit
(:func:`tsa_bench.analysis.validation.score_model`). The gain per output carries
block-bootstrap 95 % intervals of the RMSE before and after and of the reduction.
"""

from __future__ import annotations

import json
import time

import numpy as np
import yaml

from tsa_bench.analysis import verdict as vd
from tsa_bench.analysis.calibrate import calibrate
from tsa_bench.analysis.confusion import cap
from tsa_bench.analysis.context import N_BOOT, REFIT_NFEV, UNITS, Context, Progress
from tsa_bench.analysis.families import FAMILIES, FORM_SPECS
from tsa_bench.analysis.holdout import Holdout
from tsa_bench.analysis.inputs import OUTPUTS
from tsa_bench.analysis.modelspec import baseline_specs, enabled_effects, get_value, switch
from tsa_bench.analysis.near import near_misses
from tsa_bench.analysis.provenance import provenance
from tsa_bench.analysis.result import DiagnoseResult, Gain, NamedCause, plain
from tsa_bench.analysis.scoring import rmse, rmse_intervals
from tsa_bench.analysis.search import Chosen, SearchResult
from tsa_bench.analysis.settling import EFFECT, Component


def _series(ctx: Context, before: list[dict], after: list[dict]) -> dict[str, np.ndarray]:
    parts: dict[str, list] = {k: [] for k in ("t", "heldout")}
    t_off = 0.0
    for r, b, a in zip(ctx.inputs, before, after):
        parts["t"].append(r.t - r.t[0] + t_off)
        t_off += r.duration_s + 1.0
        parts["heldout"].append(r.heldout)
        for o in OUTPUTS:
            for key, arr in ((f"{o}_measured", r.output(o)), (f"{o}_before", b[o]), (f"{o}_after", a[o])):
                parts.setdefault(key, []).append(arr)
    return {k: v[0] if len(v) == 1 else np.concatenate(v) for k, v in parts.items()}   # one run: no copies


def _r2_noise_free(ctx: Context, sims: list[dict], o: str) -> float | None:
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


def declared_settling(cfg: dict, outputs: tuple[str, ...]) -> list[str]:
    """Outputs whose model has a hold-to-hold variance component (a settling effect with hold draws)."""
    on = set(enabled_effects(cfg))
    return [o for o in outputs if EFFECT[o][0] in on and get_value(cfg, ".".join(EFFECT[o])) > 0]


def extended_plant(ctx: Context, cfg: dict, components: dict[str, Component]) -> dict:
    """The final model's plant as a file holds it: the named effects and recalibrated parameters,
    the variance components and the noise measured (read back through YAML)."""
    plant = switch(cfg, "sensor_noise", True, {
        **({"length_noise_mm": ctx.noise["length"].sigma} if "length" in ctx.outputs else {}),
        **({"resistance_noise_ohm": ctx.noise["resistance"].sigma} if "resistance" in ctx.outputs else {})})
    for o, comp in components.items():
        effect, param = EFFECT[o]
        other = "run_sd_mm" if o == "length" else "run_sd_ohm"
        keep = get_value(plant, f"{effect}.{other}") if effect in enabled_effects(plant) else 0.0
        plant = switch(plant, effect, True, {param: comp.tau, other: keep})
    return yaml.safe_load(yaml.safe_dump(plain(plant), sort_keys=False))


class Finisher:
    """Builds the result (final checks, ordering, verdict, the extended model, provenance)."""

    def __init__(self, runs, model, model_path, seed, t0, outputs, notes) -> None:
        self.runs, self.model, self.model_path, self.seed, self.t0 = runs, model, model_path, seed, t0
        self.outputs, self.notes = outputs, notes

    def _prov(self, hold: Holdout) -> dict:
        return provenance(self.runs, self.model_path, json.dumps(self.model, sort_keys=True, default=str),
                          hold.to_json(), self.seed, time.perf_counter() - self.t0)

    def mismatch_only(self, missing: list[tuple[str, str]], hold: Holdout) -> DiagnoseResult:
        mism = vd.mismatch_entries(missing, [], {})
        effects = enabled_effects(self.model)
        return DiagnoseResult("model_mismatch", vd.summary_line("model_mismatch", [], [], mism, {}), [], [], [], {},
                              effects, effects, {}, {}, self.notes, mismatch=mism, holdout=hold.to_json(),
                              provenance=self._prov(hold), outputs=self.outputs)

    def _test(self, ctx: Context, found: SearchResult, declared: list[str], say: Progress
              ) -> tuple[dict, dict[str, Component], dict[str, Component]]:
        """Residual tests of the final model, the declared components re-fitted and new ones named."""
        sims = found.scores.sims
        r0 = get_value(found.current.cfg, "geometry.resistance_ohm")
        settle = {o: ctx.component(sims, o) for o in declared}
        tests = ctx.residual_tests(sims, r0, settle)
        named: dict[str, Component] = {}
        self.tested: dict[str, Component] = dict(settle)
        for o in ctx.outputs:
            if o in settle or not tests[o].get("structured"):
                continue
            say(f"testing the {o} residual for hold-to-hold offsets (a variance component)")
            comp = self.tested[o] = ctx.component(sims, o)
            follows = [f["signal"] for f in tests[o].get("follows", [])]
            if follows:      # a residual that follows an input is (also) a deterministic misfit: not settling
                comp.named = False
                comp.follows.append("the residual follows " + ", ".join(follows))
            if not comp.named:
                continue
            # named only if removing the offsets removes most of the structure (as a cause must)
            after = ctx.residual_tests(sims, r0, {o: comp})[o]
            b, a = tests[o].get("structured_rms") or 0.0, after.get("structured_rms") or 0.0
            if b > 0 and 1.0 - (a * a) / (b * b) >= vd.SHARE_MIN:
                named[o] = comp
            else:
                comp.named = False
                comp.follows.append("(removing the offsets leaves most of the structure)")
        if named:
            tests = ctx.residual_tests(sims, r0, {**settle, **named})
        return tests, settle, named

    def _demote_weak_share(self, ctx: Context, found: SearchResult, states: dict, centre: dict,
                           say: Progress) -> list[dict]:
        """Causes whose output keeps most of its structure leave the model (re-calibrated without them)."""
        out, keep = [], []
        for c in found.chosen:
            main = c.main_output(ctx.outputs)
            share = vd.share_removed(states[main])
            if share < vd.SHARE_MIN:
                out.append({"form": c.form, "family": c.family, "explained_share": share,
                            "why": f"removes only {100 * share:.0f} % of the {main} residual's structure: removed "
                                   "from the model"})
            else:
                keep.append(c)
        if out:
            cfg = found.current.cfg
            for d in out:
                cfg = switch(cfg, d["form"], False)
            say("final model: re-calibrating without the causes that explain too little")
            fit = calibrate(ctx.problem, cfg, baseline_specs(cfg), start=dict(found.current.values), centre=centre,
                            max_nfev=REFIT_NFEV) if keep else found.fit0
            found.current, found.scores, found.chosen = fit, ctx.scores(fit.cfg) if keep else found.s0, keep
        return out

    def _cause(self, ctx: Context, c: Chosen, states: dict, named_families: set[str], values: dict) -> NamedCause:
        own = c.own
        main = c.main_output(ctx.outputs)
        share = vd.share_removed(states[main])
        cause = NamedCause(c.family, FAMILIES[c.family][c.form], c.form, main,
                           own.p_above[main] if own else 0.0, c.form_conf,
                           own.improvement[main] if own else 0.0, own.ci95[main] if own else (0.0, 0.0),
                           c.gain, {s.key: values.get(s.key) for s in FORM_SPECS[c.form]})
        if states[main].after.get("structured"):
            cause.caveats.append(vd.follows_text(main, states[main].after) + " after naming it (the final model "
                                 f"removed {vd.percent(share)} of the structure)")
            cause.confidence *= share
        cause.alternatives = [a for a in c.alternatives if a["effect"] not in named_families]
        cause.at_bound = c.at_bound
        cause.confidence, caveats = cap(cause.confidence, c.family, cause.alternatives, c.at_bound)
        cause.caveats += caveats
        return cause

    def complete(self, ctx: Context, found: SearchResult, tests0: dict, hold: Holdout, centre: dict,
                 say: Progress) -> DiagnoseResult:
        say("testing the final model")
        declared = declared_settling(self.model, ctx.outputs)
        tests1, settle, components = self._test(ctx, found, declared, say)
        states = {o: vd.OutputState(tests0[o], tests1[o], _r2_noise_free(ctx, found.scores.sims, o), UNITS[o])
                  for o in ctx.outputs}
        partial = [{**d, "effect": d["family"], "form": FAMILIES[d["family"]][d["form"]], "variant": d["form"]}
                   for d in found.demoted]
        weak = self._demote_weak_share(ctx, found, states, centre, say)
        if weak:
            partial += [{**d, "effect": d["family"], "form": FAMILIES[d["family"]][d["form"]], "variant": d["form"]}
                        for d in weak]
            tests1, settle, components = self._test(ctx, found, declared, say)
            states = {o: vd.OutputState(tests0[o], tests1[o], _r2_noise_free(ctx, found.scores.sims, o), UNITS[o])
                      for o in ctx.outputs}
        current = found.current
        fams = {c.family for c in found.chosen}
        named = sorted((self._cause(ctx, c, states, fams, current.values) for c in found.chosen),
                       key=lambda c: -c.own_improvement)
        named += [self._random(ctx, comp) for comp in components.values()]
        bounds = [b for b in current.at_bound if b["key"].split(".")[0] not in FORM_SPECS]
        mism = vd.mismatch_entries([], bounds, states)
        near = near_misses(ctx, found, states)
        unexplained = [vd.unexplained_entry(o, st, o in ctx.induced, near.get(o, [])) for o, st in states.items()
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
        plant = extended_plant(ctx, current.cfg, {**settle, **components})
        say("final model: scoring the extended model as its file reads back")
        s_file = ctx.scores(plant)
        gains = self._gains(ctx, found, s_file, {**settle, **components})
        series = _series(ctx, found.s0.sims, s_file.sims)
        if named and named[0].variant not in (e for e, _ in EFFECT.values()):
            off = ctx.scores(switch(current.cfg, named[0].variant, False)).sims
            o = named[0].output
            series["cause_signal"] = np.concatenate([s[o] - f[o] for s, f in zip(found.scores.sims, off)])
        fit0 = found.fit0
        calibration = {"judged": {"at_bound": fit0.at_bound, "undetermined": fit0.undetermined,
                                  "dropped": fit0.dropped, "rms_noise_units": float(np.sqrt(fit0.rss / max(fit0.n, 1)))},
                       "final": {"at_bound": current.at_bound, "undetermined": current.undetermined,
                                 "dropped": current.dropped,
                                 "rms_noise_units": float(np.sqrt(current.rss / max(current.n, 1)))}}
        if fit0.undetermined:
            self.notes.append("not determined by these data (kept near the model's values): "
                              + ", ".join(fit0.undetermined))
        cands = sorted(found.candidates.values(), key=lambda c: -c.score)
        self.notes.append(f"diagnose took {time.perf_counter() - self.t0:.1f} s")
        return DiagnoseResult(
            verdict, summary, named, cands, gains, {"before": tests0, "after": tests1},
            enabled_effects(self.model), enabled_effects(plant),
            {"before": dict(fit0.values), "after": dict(current.values)}, series, self.notes,
            unexplained=unexplained, mismatch=mism, partial=partial,
            noise={o: ctx.noise[o].to_json() for o in ctx.outputs}, calibration=calibration,
            holdout=hold.to_json(), iterations=found.iterations, provenance=self._prov(hold), outputs=ctx.outputs,
            model_plant=plant, judged_plant=plain(fit0.cfg), components=[c.to_json() for c in self.tested.values()])

    def _gains(self, ctx: Context, found: SearchResult, s_file, comps: dict[str, Component]) -> list[Gain]:
        before, after = rmse(found.s0, ctx.sigma), rmse(s_file, ctx.sigma)
        ci = rmse_intervals(found.s0, s_file, ctx.sigma, N_BOOT, ctx.seed)
        out = []
        for o in ctx.outputs:
            b, a = before[o], after[o]
            out.append(Gain(o, b, a, float((b - a) / b) if b > 0 and np.isfinite(a) else 0.0,
                            ci[o].get("a", (np.nan, np.nan)), ci[o].get("b", (np.nan, np.nan)),
                            ci[o].get("reduction", (np.nan, np.nan)), ctx.sigma[o],
                            comps[o].tau if o in comps else 0.0))
        return out

    @staticmethod
    def _random(ctx: Context, comp: Component) -> NamedCause:
        effect, param = EFFECT[comp.output]
        nv = ctx.sigma[comp.output] ** 2
        held = "" if comp.heldout_tau is None else f"; on the held-out holds {comp.heldout_tau:.3g} {UNITS[comp.output]}"
        c = NamedCause(effect, "hold-to-hold offsets (a variance component)", effect, comp.output, 1.0 - comp.p, 1.0,
                       comp.tau ** 2 / nv, (comp.ci95[0] ** 2 / nv, comp.ci95[1] ** 2 / nv), {},
                       {f"{effect}.{param}": comp.tau})
        c.kind = "variance component"
        c.caveats.append(f"a random offset at every stop and heater change, sd {comp.tau:.3g} {UNITS[comp.output]} "
                         f"(95 % {comp.ci95[0]:.3g} to {comp.ci95[1]:.3g}, likelihood ratio {comp.lr:.1f}, p "
                         f"{comp.p:.2g}, {comp.n_holds} holds{held}): no model of the inputs predicts it; it sets how "
                         "closely any model can follow a new hold")
        return c

