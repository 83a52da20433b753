"""The end of a diagnosis: final checks, ordering, confidence, verdict, the result.

Units: RMSE in the output's units; improvements in noise variances per sample.

Contract: :class:`Finisher` turns the engine's state into a
:class:`~tsa_bench.analysis.result.DiagnoseResult`: ``mismatch_only`` when the inputs
cannot be used, ``complete`` otherwise (each named cause's own part against the final
model re-calibrated without it, dominant first, confidences, the residual tested again,
caveats and demotions, mismatch checks, the verdict; see
:mod:`tsa_bench.analysis.verdict`), with provenance.
"""

from __future__ import annotations

import json
import time

import numpy as np

from tsa_bench.analysis import verdict as vd
from tsa_bench.analysis.calibrate import Fit, calibrate
from tsa_bench.analysis.context import REFIT_NFEV, UNITS, Context, Progress
from tsa_bench.analysis.families import FAMILIES, FAMILY_OF, FORM_SPECS
from tsa_bench.analysis.holdout import Holdout
from tsa_bench.analysis.inputs import OUTPUTS
from tsa_bench.analysis.modelspec import baseline_specs, enabled_effects, get_value, switch
from tsa_bench.analysis.provenance import provenance
from tsa_bench.analysis.result import DiagnoseResult, Gain, NamedCause
from tsa_bench.analysis.scoring import Scores


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


class Finisher:
    """Builds the result (final checks, ordering, verdict, provenance)."""

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

    def complete(self, ctx: Context, fit0: Fit, s0: Scores, tests0: dict, current: Fit, cur_scores: Scores,
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
                s_drop = ctx.scores(drop.cfg, keep_sims=False)
            own = ctx.compare(s_drop, cur_scores)
            main = max(ctx.outputs, key=lambda o: own.improvement[o])
            share = vd.share_removed(states[main])
            cause = NamedCause(fam, FAMILIES[fam][form], form, main,
                               own.p_above["pooled"], ch["form_conf"], own.improvement["pooled"],
                               own.ci95["pooled"], ch["gain"],
                               {s.key: current.values.get(s.key) for s in FORM_SPECS[form]})
            lo, hi = own.ci95["pooled"]
            if len(chosen) > 1 and not lo > 0:   # passed its gate, but the final model does as well without it
                partial.append({**cause.to_json(), "explained_share": share,
                                "why": f"in the final model its own held-out improvement is not above zero "
                                       f"(95 % {lo:.3g} to {hi:.3g} noise variances per sample)"})
                continue
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
