"""Result types of :func:`tsa_bench.analysis.diagnose` (shared with the report and CLI).

Units: RMSE in the output's units (length mm, resistance ohm); improvements in noise
variances per sample; confidences and shares are fractions.

The JSON (``DiagnoseResult.to_json``, schema ``tsa-bench/diagnose`` version 2) is
documented in docs/diagnose.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

SCHEMA = "tsa-bench/diagnose"
SCHEMA_VERSION = 3
VERDICTS = ("explained", "named", "unexplained", "model_mismatch")


def plain(x: Any) -> Any:
    """JSON-safe copy: numpy scalars and arrays to Python, non-finite floats to None."""
    if isinstance(x, dict):
        return {str(k): plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return [plain(v) for v in x.tolist()]
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else None
    return x


@dataclass
class Candidate:
    """One candidate cause: a library effect in one form (``kind="effect"``).

    ``score``: fraction of the training residual (noise-normalised, outputs pooled) its
    signature explains at screening (or its refit model, when refitted).
    """

    name: str
    kind: str
    score: float
    evidence: dict = field(default_factory=dict)


@dataclass
class Gain:
    """Held-out RMSE of one output, judged -> final model, with block-bootstrap 95 % intervals."""

    output: str
    heldout_rmse_before: float
    heldout_rmse_after: float
    relative: float
    before_ci95: tuple[float, float] = (math.nan, math.nan)
    after_ci95: tuple[float, float] = (math.nan, math.nan)
    reduction_ci95: tuple[float, float] = (math.nan, math.nan)   # before - after, output units
    noise_rms: float = math.nan
    settling_sd: float = 0.0          # a named hold-to-hold variance component's sd (0: none)

    @property
    def stochastic_rms(self) -> float:
        """What no model of the inputs can predict: the noise and the hold-to-hold offsets."""
        return math.hypot(self.noise_rms, self.settling_sd)

    def to_json(self) -> dict:
        return {"output": self.output, "heldout_rmse_before": self.heldout_rmse_before,
                "heldout_rmse_after": self.heldout_rmse_after, "relative": self.relative,
                "before_ci95": list(self.before_ci95), "after_ci95": list(self.after_ci95),
                "reduction_ci95": list(self.reduction_ci95), "noise_rms": self.noise_rms,
                "after_over_noise": self.heldout_rmse_after / self.noise_rms if self.noise_rms > 0 else None,
                "settling_sd": self.settling_sd,
                "after_over_noise_and_settling": self.heldout_rmse_after / self.stochastic_rms
                if self.stochastic_rms > 0 else None}


@dataclass
class NamedCause:
    """One named cause: ``effect`` (a plant effect) in physical ``form`` (``variant`` is the
    plant's name for it), acting on ``output`` ("length" or "resistance"); ``confidence``
    and ``form_confidence`` in 0..1; ``own_improvement`` its held-out improvement in noise
    variances per sample (``ci95`` its 95 % interval); ``relative_gain`` the held-out RMSE
    gain per output when it was added (fraction); ``params`` its fitted parameters keyed
    ``<effect>.<parameter>`` in the effect's documented units."""

    effect: str
    form: str
    variant: str                      # plant effect / form name
    output: str
    confidence: float
    form_confidence: float
    own_improvement: float            # held-out, noise variances per sample, in the final model
    ci95: tuple[float, float]
    relative_gain: dict[str, float]   # held-out RMSE gain per output when it was added
    params: dict[str, float]
    caveats: list[str] = field(default_factory=list)
    alternatives: list[dict] = field(default_factory=list)   # confusable causes of other families
    at_bound: list[dict] = field(default_factory=list)       # form parameters at a soft bound
    kind: str = "effect"              # or "variance component" (hold-to-hold offsets)

    def to_json(self) -> dict:
        return {"effect": self.effect, "form": self.form, "variant": self.variant, "output": self.output,
                "kind": self.kind, "confidence": self.confidence, "form_confidence": self.form_confidence,
                "own_improvement_noise_var": self.own_improvement, "own_improvement_ci95": list(self.ci95),
                "heldout_gain": self.relative_gain, "params": self.params, "caveats": self.caveats,
                "alternatives": self.alternatives, "at_bound": self.at_bound}


@dataclass
class DiagnoseResult:
    """What :func:`~tsa_bench.analysis.diagnose` concluded (docs/diagnose.md reads it field by field).

    ``verdict``: one of :data:`~tsa_bench.analysis.VERDICTS`; ``summary`` one line saying it;
    ``named`` the causes, dominant first; ``gain`` the held-out RMSE of each output, judged
    -> final model (mm, ohm); ``calibrated``: ``{"before": ..., "after": ...}``, the
    parameters of the judged and of the final model, keyed ``geometry.<plant parameter>``
    or ``<effect>.<parameter>``, in the plant's units; ``model_effects_before`` /
    ``model_effects_after`` the effects switched on in each. :meth:`to_json` is what
    ``diagnose.json`` holds.
    """

    verdict: str
    summary: str
    named: list[NamedCause]
    candidates: list[Candidate]
    gain: list[Gain]
    residual_tests: dict
    model_effects_before: list[str]
    model_effects_after: list[str]
    calibrated: dict
    series: dict
    notes: list[str]
    unexplained: list[dict] = field(default_factory=list)
    mismatch: list[dict] = field(default_factory=list)
    partial: list[dict] = field(default_factory=list)
    noise: dict = field(default_factory=dict)
    calibration: dict = field(default_factory=dict)
    holdout: dict = field(default_factory=dict)
    iterations: list[dict] = field(default_factory=list)
    provenance: dict = field(default_factory=dict)
    outputs: tuple[str, ...] = ("length", "resistance")
    model_plant: dict = field(default_factory=dict)     # the extended model's plant (what --write-model writes)
    judged_plant: dict = field(default_factory=dict)    # the judged model calibrated on the training part
    components: list[dict] = field(default_factory=list)   # hold-to-hold variance components fitted
    validation: list[dict] = field(default_factory=list)   # prospective validation (set by the caller)

    @property
    def causes(self) -> list[str]:
        """Named effects, dominant first."""
        return [c.effect for c in self.named]

    @property
    def cause(self) -> str | None:
        return self.named[0].effect if self.named else None

    def to_json(self) -> dict:
        return plain({
            "schema": SCHEMA, "schema_version": SCHEMA_VERSION,
            "verdict": self.verdict, "summary": self.summary,
            "cause": self.cause, "causes": self.causes,
            "named": [c.to_json() for c in self.named],
            "unexplained": self.unexplained, "mismatch": self.mismatch, "partial": self.partial,
            "outputs": list(self.outputs),
            "candidates": [{"name": c.name, "kind": c.kind, "score": c.score, "evidence": c.evidence}
                           for c in self.candidates],
            "gain": [g.to_json() for g in self.gain],
            "components": self.components,
            "validation": self.validation,
            "extended_model": self.model_plant,
            "noise": self.noise,
            "residual_tests": self.residual_tests,
            "model_effects_before": self.model_effects_before,
            "model_effects_after": self.model_effects_after,
            "calibrated": self.calibrated,
            "calibration": self.calibration,
            "holdout": self.holdout,
            "iterations": self.iterations,
            "provenance": self.provenance,
            "notes": self.notes,
        })
