"""Does a model fitted at some conditions transfer to a condition it never saw?

Units: those of the runs' columns (e.g. temperature in degC -> strain, 1).

Contract: runs are grouped by one condition value each (a stress, a load, ...).
:func:`transfer_study` fits ``model`` (preisach or polynomial, through
:func:`tsa_bench.models.fitting.fit`) on every run but the held-out one and reports,
for each fitted run, its identification error and, for the held-out run, the error of
three ways of predicting it without fitting it:

* ``nearest``: the model of the nearest condition;
* ``interpolated``: linear interpolation, in the condition, between the predictions of
  the two neighbouring conditions' models (nearest when the held-out one is outside);
* ``pooled``: one model fitted on all the other runs together (the condition ignored).

Errors are E_aver (eq. 3.5) in the output's unit over the samples :func:`fit` scores.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tsa_bench.models.fit_samples import quasi_static_mask
from tsa_bench.models.fitting import evaluate, fit
from tsa_bench.rundata import RunData


@dataclass(frozen=True)
class TransferResult:
    """Identification errors per fitted condition and the held-out errors (module contract)."""

    model: str
    held_out: float
    identification: dict[float, float]
    nearest: float
    interpolated: float
    pooled: float
    unit: str


def transfer_study(runs: dict[float, RunData], model: str, input_col: str, output_col: str, held_out: float,
                   levels: int = 20) -> TransferResult:
    """Fit per condition, hold one condition out (module contract)."""
    if held_out not in runs:
        raise ValueError(f"held-out condition {held_out:g} is not among {sorted(runs)}")
    fitted = {c: fit(model, [r], input_col, output_col, levels=levels) for c, r in runs.items() if c != held_out}
    ident = {c: float(s.metrics["identification"][runs[c].path]["e_aver"]) for c, s in fitted.items()}
    target = runs[held_out]
    preds = {c: evaluate(s, target)[0] for c, s in fitted.items()}
    y = np.asarray(target.samples[output_col], float)
    scored = quasi_static_mask(target, input_col) & np.isfinite(y)
    conds = np.array(sorted(fitted))
    nearest_c = float(conds[np.argmin(np.abs(conds - held_out))])
    below, above = conds[conds < held_out], conds[conds > held_out]
    if len(below) and len(above):
        lo, hi = float(below.max()), float(above.min())
        w = (hi - held_out) / (hi - lo)
        interp = w * preds[lo] + (1.0 - w) * preds[hi]
    else:
        interp = preds[nearest_c]
    pooled = fit(model, [runs[c] for c in conds], input_col, output_col, levels=levels)

    def err(p: np.ndarray) -> float:
        m = scored & np.isfinite(p)
        return float(np.mean(np.abs(p[m] - y[m])))
    return TransferResult(model, held_out, ident, err(preds[nearest_c]), err(interp), err(evaluate(pooled, target)[0]),
                          target.units.get(output_col, ""))
