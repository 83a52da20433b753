"""Held-out scores of a model and the block bootstrap that compares two of them.

Units: squared errors in units of each output's noise variance (dimensionless), so
"1.0" is one noise variance; RMSE in the output's units.

Contract: :func:`unit_scores` replays a config on every run (full resolution) and sums,
per held-out resampling unit (:func:`tsa_bench.analysis.holdout.units`) and output,
the squared noise-normalised error and the sample count. Asked for the scores alone
(``keep_sims`` False), it replays a plant whose memory is at most the last motor stop
(:func:`tsa_bench.analysis.replay.memory`) on the held-out samples and the pauses they
begin in only (:func:`tsa_bench.analysis.replay.scoring_samples`): the same numbers. :func:`compare` resamples the
units with replacement (``B`` times, seeded) and returns, per output and pooled over
outputs, the mean improvement of B over A (``(SSE_A - SSE_B) / n``, noise variances
per sample), its 95 % interval and the fraction of replicates in which it exceeds
``floor``. The pooled improvement is the sum over outputs of their per-sample
improvements. Resampling contiguous units keeps the autocorrelation of the residuals
inside them, so the interval is honest where a per-sample bootstrap would be far too
narrow.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tsa_bench.analysis.holdout import units
from tsa_bench.analysis.inputs import RunInputs
from tsa_bench.analysis.replay import ReplayCache, deterministic, memory, replay, scoring_samples


@dataclass
class Scores:
    sse: np.ndarray        # (units, outputs), noise-normalised
    count: np.ndarray      # (units, outputs)
    outputs: tuple[str, ...]
    sims: list[dict[str, np.ndarray]]

    def subset(self, keep: np.ndarray) -> "Scores":
        """The same scores on the units ``keep`` (a boolean mask) only."""
        return Scores(self.sse[keep], self.count[keep], self.outputs, self.sims)

    def without_sims(self) -> "Scores":
        """The same scores without the replays (full-resolution arrays a comparison no longer needs)."""
        return Scores(self.sse, self.count, self.outputs, [])

    def mse(self) -> dict[str, float]:
        return {o: float(self.sse[:, j].sum() / self.count[:, j].sum()) if self.count[:, j].sum() else float("nan")
                for j, o in enumerate(self.outputs)}


def all_units(runs: list[RunInputs], target: int = 40) -> list[tuple[int, np.ndarray]]:
    """Resampling units of every run's held-out part, about ``target`` in all (at least 20 s each)."""
    spans = sum(int(np.sum(np.diff(np.r_[0, r.heldout.astype(np.int8)]) == 1)) for r in runs)
    per_block = int(min(target, max(4, target // max(spans, 1))))
    return [(i, u) for i, r in enumerate(runs) for u in units(r, per_block=per_block)]


def unit_scores(cfg: Mapping[str, Any], runs: list[RunInputs], unit_list: list[tuple[int, np.ndarray]],
                sigma: Mapping[str, float], outputs: tuple[str, ...],
                sims: list[dict[str, np.ndarray]] | None = None, cache: ReplayCache | None = None,
                keep_sims: bool = True) -> Scores:
    """Unit scores of ``cfg`` (module docstring); without ``keep_sims`` the result holds no replays."""
    at: list = [None] * len(runs)    # per run: the replayed samples when not all of them
    if sims is None:
        sims = []
        partial = not keep_sims and memory(deterministic(cfg)) != "path"
        for i, r in enumerate(runs):
            if partial:
                mine = [u for j, u in unit_list if j == i]
                at[i] = scoring_samples(r, np.unique(np.concatenate(mine)) if mine else np.zeros(0, int))
            length, res = replay(cfg, r, at[i], cache=cache)
            sims.append({"length": length, "resistance": res})
    sse = np.zeros((len(unit_list), len(outputs)))
    cnt = np.zeros((len(unit_list), len(outputs)))
    for k, (i, u) in enumerate(unit_list):
        r = runs[i]
        pos = u if at[i] is None else np.searchsorted(at[i], u)
        for j, o in enumerate(outputs):
            d = (sims[i][o][pos] - r.output(o)[u]) / sigma[o]
            d = d[np.isfinite(d) & r.scored[u]]
            sse[k, j] = float(d @ d)
            cnt[k, j] = len(d)
    return Scores(sse, cnt, outputs, sims if keep_sims else [])


@dataclass
class Comparison:
    improvement: dict[str, float]         # per output and "pooled": noise variances per sample
    ci95: dict[str, tuple[float, float]]
    p_above: dict[str, float]             # fraction of replicates above the floor
    p_worse: dict[str, float]             # fraction of replicates below minus the floor
    relative: dict[str, float]            # (MSE_A - MSE_B) / MSE_A per output
    mse_before: dict[str, float]          # MSE_A per output, noise variances per sample
    draws: np.ndarray                     # (B,) pooled improvement replicates
    lower: dict[str, float] = field(default_factory=dict)   # per output: lower bound adjusted for the outputs

    def significant(self, floor: float) -> bool:
        """Whether some output's held-out improvement is significantly above 0 (its 95 % lower bound,
        Bonferroni-adjusted for the number of outputs, above 0) and at least ``floor``, and the pooled
        improvement is at least ``floor``. Per output, so that one output's error swamped by random
        offsets does not hide a clear gain on the other."""
        return self.improvement.get("pooled", 0.0) >= floor and any(
            self.lower.get(o, -1.0) > 0 and self.improvement[o] >= floor for o in self.lower)

    def main_output(self) -> str:
        """The output whose improvement is most clearly above 0 (largest adjusted lower bound)."""
        return max(self.lower, key=lambda o: self.lower[o]) if self.lower else "pooled"

    def to_json(self) -> dict:
        return {"improvement_noise_var": self.improvement, "ci95": {k: list(v) for k, v in self.ci95.items()},
                "adjusted_lower": self.lower,
                "p_above_floor": self.p_above, "p_worse_than_floor": self.p_worse, "relative_mse": self.relative,
                "mse_before_noise_var": self.mse_before}


def _stat(da: np.ndarray, cnt: np.ndarray) -> np.ndarray:
    """Per-output improvement per sample for summed unit rows."""
    return np.where(cnt > 0, da / np.maximum(cnt, 1), 0.0)


def compare(a: Scores, b: Scores, floor: float, n_boot: int = 1000, seed: int = 0,
            weights: np.ndarray | None = None) -> Comparison:
    """Improvement of ``b`` over ``a`` on the held-out units (see the module docstring)."""
    outs = a.outputs
    diff = a.sse - b.sse
    cnt = a.count
    point = _stat(diff.sum(axis=0), cnt.sum(axis=0))
    rng = np.random.default_rng(seed)
    m = len(diff)
    if m == 0:
        z = {o: 0.0 for o in (*outs, "pooled")}
        return Comparison(z, {k: (0.0, 0.0) for k in z}, z, z, {o: 0.0 for o in outs}, {o: 0.0 for o in outs},
                          np.zeros(0))
    pick = rng.integers(0, m, size=(n_boot, m))
    dsum = diff[pick].sum(axis=1)          # (B, outputs)
    csum = cnt[pick].sum(axis=1)
    per = _stat(dsum, csum)
    pooled = per.sum(axis=1)
    imp = {o: float(point[j]) for j, o in enumerate(outs)}
    imp["pooled"] = float(point.sum())
    ci = {o: (float(np.percentile(per[:, j], 2.5)), float(np.percentile(per[:, j], 97.5))) for j, o in enumerate(outs)}
    ci["pooled"] = (float(np.percentile(pooled, 2.5)), float(np.percentile(pooled, 97.5)))
    pa = {o: float(np.mean(per[:, j] > floor)) for j, o in enumerate(outs)}
    pa["pooled"] = float(np.mean(pooled > floor))
    pw = {o: float(np.mean(per[:, j] < -floor)) for j, o in enumerate(outs)}
    pw["pooled"] = float(np.mean(pooled < -floor))
    ma, mb = a.mse(), b.mse()
    rel = {o: (ma[o] - mb[o]) / ma[o] if ma[o] > 0 and np.isfinite(ma[o]) and np.isfinite(mb[o]) else 0.0
           for o in outs}
    lower = {o: float(np.percentile(per[:, j], 2.5 / len(outs))) for j, o in enumerate(outs)}
    return Comparison(imp, ci, pa, pw, rel, ma, pooled, lower)


def rmse(s: Scores, sigma: Mapping[str, float]) -> dict[str, float]:
    """Held-out RMSE per output, in the output's units (what the report prints and ``predict`` reproduces)."""
    mse = s.mse()
    return {o: float(np.sqrt(mse[o]) * sigma[o]) for o in s.outputs}


def rmse_intervals(a: Scores, b: Scores | None, sigma: Mapping[str, float], n_boot: int = 1000, seed: int = 0
                   ) -> dict[str, dict[str, tuple[float, float]]]:
    """Block-bootstrap 95 % intervals of the held-out RMSE of ``a`` and ``b`` per output and of their
    difference (``a - b``, the reduction), resampling the units as :func:`compare` does."""
    m = len(a.sse)
    out: dict[str, dict[str, tuple[float, float]]] = {}
    if m == 0:
        return {o: {} for o in a.outputs}
    pick = np.random.default_rng(seed).integers(0, m, size=(n_boot, m))

    def boot(s: Scores, j: int) -> np.ndarray:
        c = s.count[pick, j].sum(axis=1)
        return np.sqrt(s.sse[pick, j].sum(axis=1) / np.maximum(c, 1)) * sigma[s.outputs[j]]

    def ci(x: np.ndarray) -> tuple[float, float]:
        return float(np.percentile(x, 2.5)), float(np.percentile(x, 97.5))

    for j, o in enumerate(a.outputs):
        ra = boot(a, j)
        out[o] = {"a": ci(ra)}
        if b is not None:
            rb = boot(b, j)
            out[o]["b"], out[o]["reduction"] = ci(rb), ci(ra - rb)
    return out
