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
5. the search (:mod:`~tsa_bench.analysis.search`): forward selection, one cause per
   iteration (:func:`~tsa_bench.analysis.naming.iteration`: screen every candidate form the
   data can test and may blame, refit the leading effect's forms and the best form of every
   other effect that screens at all, together with the model's own parameters, and name the
   one with the largest held-out improvement among those that pass the gate: on some output
   the 95 % block-bootstrap interval of its held-out improvement is above 0 and it is at
   least the relevance floor, switching it off again worsens the training fit by the floor
   and the held-out fit significantly, no output is made more than 10 % worse);
   then backward elimination: a cause that no longer earns its place in the model leaves it
   and gives its iteration back; confusable alternatives are kept only if swapping them in
   does as well;
6. the final model (:mod:`~tsa_bench.analysis.finish`): the residual tested again, the
   hold-to-hold variance component named where it is random, confidences capped by
   confusable alternatives and parameters at the edge of their range, near misses, the
   verdict (verdict.py), and the extended model whose final held-out RMSE is computed from
   its YAML round trip (what ``--write-model`` writes and ``predict`` reads back).
Progress lines say the stage (``[stage k/6 name]``) and how far within it.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from tsa_bench.analysis import validation
from tsa_bench.analysis.calibrate import calibrate
from tsa_bench.analysis.context import UNITS, Context, Progress
from tsa_bench.analysis.finish import Finisher, declared_settling
from tsa_bench.analysis.holdout import Holdout, split
from tsa_bench.analysis.inputs import OUTPUTS, missing_inputs, run_inputs
from tsa_bench.analysis.modelspec import baseline_specs, get_value
from tsa_bench.analysis.naming import induced
from tsa_bench.analysis.noise import noise_model
from tsa_bench.analysis.quasistatic import hold_points, staged_start
from tsa_bench.analysis.result import DiagnoseResult
from tsa_bench.analysis.search import SearchResult, search


#: stages of a diagnosis, for the progress lines ("[stage 5/6 search] iteration 2 (at most 14): ...")
STAGES = 6
#: most causes in the model at once (forward selection stops there; a demoted one frees its place)
MAX_CAUSES = 6


def diagnose(runs: list, model_plant_cfg: Mapping[str, Any], holdout: str | None = None, *,
             max_causes: int = MAX_CAUSES, seed: int = 0, progress: Progress | None = None,
             outputs: tuple[str, ...] | None = None, model_path: str | Path | None = None,
             validate: list | None = None) -> DiagnoseResult:
    """Judge ``model_plant_cfg`` against ``runs`` (RunData); see the module docstring.

    ``validate``: runs scored with the judged and the extended model at the end and
    nothing else (prospective validation, :func:`tsa_bench.analysis.validation.validate`).
    Raises :class:`~tsa_bench.analysis.holdout.HoldoutError` for a bad ``holdout`` and
    ValueError for bad ``outputs`` or a validation run lacking an input; every other
    problem of the data ends in a verdict. BLAS runs on one thread: the fits' matrices
    are small, and on a busy machine the threads' spinning costs more CPU than they save.
    """
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        result = _diagnose(runs, model_plant_cfg, holdout, max_causes=max_causes, seed=seed, progress=progress,
                           outputs=outputs, model_path=model_path)
    if validate and result.model_plant:
        if progress:
            progress(f"[stage {STAGES}/{STAGES} final checks] prospective validation on {len(validate)} run(s)")
        result.validation = validation.validate(result.model_plant, result.judged_plant, validate, result.outputs,
                                                seed)
    return result


def _diagnose(runs: list, model_plant_cfg: Mapping[str, Any], holdout: str | None, *, max_causes: int, seed: int,
              progress: Progress | None, outputs: tuple[str, ...] | None, model_path: str | Path | None
              ) -> DiagnoseResult:
    t0 = time.perf_counter()
    emit = progress or (lambda msg: None)
    where = [f"1/{STAGES} inputs"]

    def stage(k: int, name: str) -> None:
        where[0] = f"{k}/{STAGES} {name}"

    def say(msg: str) -> None:
        emit(f"[stage {where[0]}] {msg}")
    outputs = tuple(outputs or OUTPUTS)
    if not outputs or any(o not in OUTPUTS for o in outputs):
        raise ValueError(f"outputs must be among {', '.join(OUTPUTS)}, got {', '.join(outputs) or 'none'}")
    model = dict(model_plant_cfg)
    inputs = [run_inputs(r, float(model.get("initial_load_g", 0.0))) for r in runs]
    notes: list[str] = []
    finish = Finisher(runs, model, model_path, seed, t0, outputs, notes)
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
    say("estimating the sensor noise and choosing the held-out blocks")
    noise = {o: noise_model(inputs, o) for o in outputs}
    bad = [(f"{o}: too few samples to estimate the sensor noise", "record longer holds") for o in outputs
           if not np.isfinite(noise[o].rms)]
    for o in outputs:
        y = np.concatenate([r.output(o) for r in inputs])
        spread = float(np.nanstd(y)) if np.isfinite(y).any() else 0.0
        if np.isfinite(noise[o].rms) and noise[o].rms ** 2 > 0.5 * spread ** 2:
            other = [p for p in OUTPUTS if p != o]
            what = (f"the {o} reading never changes" if spread <= 1e-12 * max(1.0, float(np.nanmax(np.abs(y)))) else
                    f"the {o} reading is mostly noise (sample-to-sample scatter {noise[o].rms:.3g} against a spread "
                    f"of {spread:.3g} {UNITS[o]})")
            bad.append((f"{what}: nothing to judge the model on",
                        f"check the {o} sensor and column, or judge the other output alone: --outputs {other[0]}"))
    if bad:
        return finish.mismatch_only(bad, hold)
    ctx = Context(inputs, outputs, noise, hold, seed)

    stage(2, "calibration")
    say("calibrating the judged model: geometry from the holds")
    pts = hold_points(inputs)
    start = staged_start(model, pts, noise["length"].sigma) if "length" in outputs else {}
    specs = baseline_specs(model)
    centre = {s.key: get_value(model, s.key) for s in specs}
    say("calibrating the judged model: all parameters")
    fit0 = calibrate(ctx.problem, model, specs, start=start, centre=centre, max_nfev=60)
    if start:
        say("calibrating the judged model: second start (the model's own values)")
        alt = calibrate(ctx.problem, model, specs, centre=centre, max_nfev=60)
        if alt.cost < fit0.cost:
            fit0 = alt
    stage(3, "residual tests")
    say("testing the judged model's residuals")
    s0 = ctx.scores(fit0.cfg)
    r0 = get_value(fit0.cfg, "geometry.resistance_ohm")
    declared = declared_settling(model, outputs)     # the model's own hold-to-hold offsets are not structure
    tests0 = ctx.residual_tests(s0.sims, r0, {o: ctx.component(s0.sims, o) for o in declared})
    structured = [o for o in outputs if tests0[o]["structured"]]
    ctx.source = set(structured)
    if len(structured) > 1:
        stage(4, "blame")
        ctx.induced = induced(ctx, fit0, structured, centre, say)
        for o in sorted(ctx.induced):
            notes.append(f"the {o} residual is structured only when the model must fit both outputs: calibrated on "
                         f"the {o} alone it is noise, so its structure comes from the other output's misfit and "
                         f"effects acting on the {o} alone are not candidates")
    if any(t["structured"] for t in tests0.values()):
        stage(5, "search")
        found = search(ctx, fit0, s0, centre, max_causes, say, notes)
    else:
        notes.append("the judged model's residuals are consistent with the noise model: no candidate screened")
        found = SearchResult(fit0, s0, fit0, s0, [], [], [], {})
    if found.s0 is not s0:
        tests0 = ctx.residual_tests(found.s0.sims, get_value(found.fit0.cfg, "geometry.resistance_ohm"),
                                    {o: ctx.component(found.s0.sims, o) for o in declared})
    stage(6, "final checks")
    return finish.complete(ctx, found, tests0, hold, centre, say)


