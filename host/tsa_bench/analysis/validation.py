"""A plant config scored on runs: the held-out RMSE a diagnosis reports, and prospective validation.

Units: RMSE and offsets in the output's units (length mm, resistance ohm).

Contract: :func:`score_model` replays a plant config (a bench file's ``plant``, e.g. the
model ``diagnose --write-model`` writes) on runs and returns, per output, the RMSE over
every scored sample and over the held-out part a diagnosis of those runs chooses (the
same split, noise model, resampling units and arithmetic as
:func:`tsa_bench.analysis.diagnose`, so the figure a diagnosis printed for its final model
comes back bit for bit from the written file). :func:`validate` scores the judged and the
final model of a diagnosis on runs it never touched (neither calibration nor selection
saw them): RMSE over the whole run with a block-bootstrap 95 % interval (units cut at
segment boundaries), as a multiple of that run's own noise RMS, the RMSE over the part of
it a diagnosis would hold out (comparable with the held-out figure of the diagnosed run), and the run's mean
residual (a constant offset, e.g. a contact that re-seated between runs) with its
interval, beside the RMSE once that offset is removed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tsa_bench.analysis.holdout import split, units
from tsa_bench.analysis.inputs import OUTPUTS, RunInputs, missing_inputs, run_inputs
from tsa_bench.analysis.noise import noise_model
from tsa_bench.analysis.replay import replay
from tsa_bench.analysis.scoring import all_units, rmse, rmse_intervals, unit_scores

N_BOOT = 1000


def _inputs(cfg: Mapping[str, Any], runs: Sequence[Any], outputs: tuple[str, ...]) -> list[RunInputs]:
    inputs = [run_inputs(r, float(cfg.get("initial_load_g", 0.0))) for r in runs]
    missing = missing_inputs(inputs, outputs)
    if missing:
        raise ValueError("; ".join(f"{p} ({r})" for p, r in missing))
    return inputs


def score_model(cfg: Mapping[str, Any], runs: Sequence[Any], holdout: str | None = None,
                outputs: tuple[str, ...] = OUTPUTS) -> dict[str, dict[str, float]]:
    """Per output: ``rmse_all`` (every scored sample), ``rmse_heldout`` (the held-out part of the split
    ``holdout``, None: diagnose's default) and ``noise_rms``; raises ValueError for runs lacking an input."""
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        inputs = _inputs(cfg, runs, outputs)
        split(inputs, holdout)
        noise = {o: noise_model(inputs, o) for o in outputs}
        sigma = {o: noise[o].rms for o in outputs}
        held = rmse(unit_scores(cfg, inputs, all_units(inputs), sigma, outputs), sigma)
        whole = _whole(cfg, inputs, sigma, outputs)
    return {o: {"rmse_all": whole[o]["rmse"], "rmse_heldout": held[o], "noise_rms": sigma[o]} for o in outputs}


def _whole(cfg: Mapping[str, Any], inputs: list[RunInputs], sigma: Mapping[str, float],
           outputs: tuple[str, ...], seed: int = 0) -> dict[str, dict]:
    """RMSE over every scored sample (interval from units over the whole run) and the mean residual."""
    out: dict[str, dict] = {}
    sims = [dict(zip(("length", "resistance"), replay(cfg, r))) for r in inputs]
    saved = [r.heldout for r in inputs]
    try:
        for r in inputs:
            r.heldout = np.ones(len(r), bool)
        ul = [(i, u) for i, r in enumerate(inputs) for u in units(r, per_block=40)]
        s = unit_scores(cfg, inputs, ul, sigma, outputs, sims=sims)
    finally:
        for r, h in zip(inputs, saved):
            r.heldout = h
    ci = rmse_intervals(s, None, sigma, N_BOOT, seed)
    for j, o in enumerate(outputs):
        d = np.concatenate([(r.output(o) - sm[o])[r.scored] for r, sm in zip(inputs, sims)])
        d = d[np.isfinite(d)]
        means = np.array([np.nanmean((inputs[i].output(o) - sims[i][o])[u]) for i, u in ul])
        offset = float(np.mean(d)) if len(d) else float("nan")
        pick = np.random.default_rng(seed).integers(0, len(means), size=(N_BOOT, len(means)))
        boot = np.nanmean(means[pick], axis=1)
        out[o] = {"rmse": rmse(s, sigma)[o], "rmse_ci95": ci[o].get("a"), "offset": offset,
                  "offset_ci95": (float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))),
                  "rmse_offset_removed": float(np.sqrt(np.mean((d - offset) ** 2))) if len(d) else float("nan")}
    return out


def validate(final_cfg: Mapping[str, Any], judged_cfg: Mapping[str, Any], runs: Sequence[Any],
             outputs: tuple[str, ...], seed: int = 0) -> list[dict]:
    """Prospective validation (module docstring): one entry per run and output."""
    from threadpoolctl import threadpool_limits

    out = []
    with threadpool_limits(limits=1, user_api="blas"):
        for r in runs:
            inputs = _inputs(final_cfg, [r], outputs)
            noise = {o: noise_model(inputs, o) for o in outputs}
            sigma = {o: noise[o].rms for o in outputs}
            after = _whole(final_cfg, inputs, sigma, outputs, seed)
            before = _whole(judged_cfg, inputs, sigma, outputs, seed)
            split(inputs, None)
            held = rmse(unit_scores(final_cfg, inputs, all_units(inputs), sigma, outputs), sigma)
            for o in outputs:
                out.append({"run": str(getattr(r, "path", "")), "output": o, "noise_rms": sigma[o],
                            "rmse_judged": before[o]["rmse"], "rmse_heldout_part": held[o], **after[o]})
    return out

