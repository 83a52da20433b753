"""Result types of :func:`tsa_bench.analysis.diagnose` (shared with the report and CLI).

Units: RMSE in the output's units (length mm, resistance ohm); scores are fractions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np


def _plain(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, np.ndarray):
        return [_plain(v) for v in x.tolist()]
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else None
    return x


@dataclass
class Candidate:
    """One candidate cause: a library effect (``kind="effect"``) or a generic signal (``"signal"``).

    ``score``: fraction of the training residual variance (each output in units of its
    noise level, outputs pooled) the candidate explains -- by its refit model when it
    was refitted, else by a least-squares regression of the residual on its signature.
    """

    name: str
    kind: str
    score: float
    evidence: dict = field(default_factory=dict)


@dataclass
class Gain:
    output: str
    heldout_rmse_before: float
    heldout_rmse_after: float
    relative: float


@dataclass
class DiagnoseResult:
    cause: str | None
    causes: list[str]
    candidates: list[Candidate]
    gain: list[Gain]
    residual_tests: dict
    model_effects_before: list[str]
    model_effects_after: list[str]
    calibrated: dict
    series: dict
    notes: list[str]

    def to_json(self) -> dict:
        return _plain({
            "cause": self.cause,
            "causes": list(self.causes),
            "candidates": [{"name": c.name, "kind": c.kind, "score": c.score, "evidence": c.evidence}
                           for c in self.candidates],
            "gain": [{"output": g.output, "heldout_rmse_before": g.heldout_rmse_before,
                      "heldout_rmse_after": g.heldout_rmse_after, "relative": g.relative} for g in self.gain],
            "residual_tests": self.residual_tests,
            "model_effects_before": self.model_effects_before,
            "model_effects_after": self.model_effects_after,
            "calibrated": self.calibrated,
            "notes": self.notes,
        })
