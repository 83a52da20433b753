"""Length as a function of twist and heater voltage together: the thesis's additive model and a coupled one.

Units: twist T in motor turns, heater voltage V in volts (the equivalent DC voltage the
device applies, the thesis's temperature surrogate), length in mm; a coefficient of
``T^i V^j`` is in mm / (turn^i V^j).

Forms (both fitted by ordinary least squares on quasi-static samples):

* ``twist-heat-additive``, thesis eq. 3.3 with the third-order polynomials of eq. 3.4 for
  each input: ``L = p(T) + q(V) = sum_{i<=3} a_i T^i + sum_{1<=j<=3} b_j V^j`` (one shared
  offset). The thesis notes it "does not apply when heat and twists are applied to the
  TSA simultaneously or in an arbitrary order", because it was identified with the
  strings heated only after full twist (section 3.1.1).
* ``twist-heat-coupled`` extends it with the cross terms ``c_ij T^i V^j`` for
  ``i, j >= 1, i + j <= 3`` (T V, T^2 V, T V^2): the length change that heating gives
  depends on the twist. Why it should: the string contracts thermally by a factor
  ``1 - s(V)`` and the TSA kinematics (thesis eqs. 4.4-4.5, ``X = sqrt(L^2 - (theta r)^2)``)
  turn a string-length change ``dL`` into ``dX = (L / X) dL``, larger the more the
  strings are twisted; to second order in T that is a ``T^2 V`` term, and a twist-
  dependent stiffness adds ``T V``.

Contract: :func:`fit_saved` identifies one form on run files and returns a
:class:`~tsa_bench.models.saved.SavedModel` (input ``turns+heater_voltage``, output
``length``; options: the form, its terms and the twist and voltage ranges it was fitted
on); :func:`predict_run` predicts a run's length at every sample and says which samples
are scored (the quasi-static ones: motor stopped, last third of each segment, the same
rule as the thesis's other quasi-static models). Metrics add ``rmse`` (mm) to the
thesis metrics. A run lacking ``turns``, ``heater_voltage`` or ``length``, or with too
few quasi-static samples, raises ``FitError`` naming the file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from tsa_bench.models.saved import SavedModel
    from tsa_bench.rundata import RunData

ADDITIVE = "twist-heat-additive"
COUPLED = "twist-heat-coupled"
NAMES = (ADDITIVE, COUPLED)
INPUT_COLUMN = "turns+heater_voltage"
INPUT_UNIT = "turn, V"
_ADDITIVE_TERMS = ((0, 0), (1, 0), (2, 0), (3, 0), (0, 1), (0, 2), (0, 3))
_CROSS_TERMS = ((1, 1), (2, 1), (1, 2))
TERMS = {ADDITIVE: _ADDITIVE_TERMS, COUPLED: _ADDITIVE_TERMS + _CROSS_TERMS}


def term_name(i: int, j: int) -> str:
    """Parameter name of the ``T^i V^j`` coefficient, e.g. ``c_T2_V1``."""
    return f"c_T{i}_V{j}"


def term_unit(i: int, j: int) -> str:
    """Unit of the ``T^i V^j`` coefficient, e.g. ``mm/(turn^2 V)``."""
    parts = ([f"turn^{i}" if i > 1 else "turn"] if i else []) + ([f"V^{j}" if j > 1 else "V"] if j else [])
    if not parts:
        return "mm"
    return f"mm/{parts[0]}" if len(parts) == 1 else f"mm/({' '.join(parts)})"


@dataclass(frozen=True)
class TwistHeatModel:
    """``L = sum_k coefficients[k] T^terms[k][0] V^terms[k][1]`` (mm; module docstring)."""

    terms: tuple[tuple[int, int], ...]
    coefficients: tuple[float, ...]

    @staticmethod
    def design(turns: np.ndarray, volts: np.ndarray, terms: tuple[tuple[int, int], ...]) -> np.ndarray:
        t, v = np.asarray(turns, float), np.asarray(volts, float)
        return np.column_stack([t ** i * v ** j for i, j in terms])

    @classmethod
    def fit(cls, turns: np.ndarray, volts: np.ndarray, length: np.ndarray,
            terms: tuple[tuple[int, int], ...]) -> "TwistHeatModel":
        """Least squares on the finite samples; inputs are scaled to about 1 for conditioning."""
        t, v, y = (np.asarray(a, float) for a in (turns, volts, length))
        ok = np.isfinite(t) & np.isfinite(v) & np.isfinite(y)
        if ok.sum() <= 2 * len(terms):
            raise ValueError(f"{len(terms)} coefficients need more than {2 * len(terms)} quasi-static samples, "
                             f"got {int(ok.sum())}")
        ts = max(float(np.max(np.abs(t[ok]))), 1e-9)
        vs = max(float(np.max(np.abs(v[ok]))), 1e-9)
        a = cls.design(t[ok] / ts, v[ok] / vs, terms)
        scaled, *_ = np.linalg.lstsq(a, y[ok], rcond=None)
        coef = tuple(float(c / (ts ** i * vs ** j)) for c, (i, j) in zip(scaled, terms))
        return cls(tuple(terms), coef)

    def predict(self, turns: np.ndarray, volts: np.ndarray) -> np.ndarray:
        """Length (mm) at each (turns, volts) pair."""
        return self.design(turns, volts, self.terms) @ np.asarray(self.coefficients)


# -- run files <-> saved model -------------------------------------------------
def _inputs(run: RunData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from tsa_bench.models.fit_samples import _column

    return _column(run, "turns"), _column(run, "heater_voltage"), _column(run, "length")


def scored_mask(run: RunData) -> np.ndarray:
    """The quasi-static samples (motor stopped, last third of each segment) with finite inputs."""
    from tsa_bench.models.fit_samples import quasi_static_mask

    t, v, y = _inputs(run)
    return quasi_static_mask(run, "turns") & np.isfinite(t) & np.isfinite(v) & np.isfinite(y)


def to_model(saved: SavedModel) -> TwistHeatModel:
    """The model object of a saved twist-heat model (ModelFileError on a missing parameter)."""
    terms = TERMS[saved.model]
    return TwistHeatModel(terms, tuple(float(saved.value(term_name(i, j))) for i, j in terms))


def predict_run(model: TwistHeatModel, run: RunData) -> tuple[np.ndarray, np.ndarray]:
    """(predicted length at every sample, mask of the samples it is scored on)."""
    t, v, _ = _inputs(run)
    pred = np.full(len(t), np.nan)
    ok = np.isfinite(t) & np.isfinite(v)
    pred[ok] = model.predict(t[ok], v[ok])
    return pred, scored_mask(run)


def score(model: TwistHeatModel, run: RunData) -> tuple[np.ndarray, dict[str, Any]]:
    """Prediction of ``run`` and its metrics (thesis metrics + ``rmse``, mm) on the scored samples."""
    from tsa_bench.models.fit_samples import FitError
    from tsa_bench.models.metrics import compare

    pred, mask = predict_run(model, run)
    y = _inputs(run)[2]
    if not mask.any():
        raise FitError(f"{run.path}: no quasi-static samples (motor stopped, end of a hold) to score on")
    err = pred[mask] - y[mask]
    return pred, {**compare(y[mask], pred[mask], "mm").as_dict(), "rmse": float(np.sqrt(np.mean(err ** 2)))}


def fit_saved(name: str, runs: list[RunData], validate: list[RunData] | None = None) -> SavedModel:
    """Identify the ``name`` form on ``runs`` and score it on them and on ``validate``."""
    from tsa_bench.models.fit_samples import FitError
    from tsa_bench.models.saved import SavedModel, param

    ts, vs, ys = [], [], []
    for r in runs:
        t, v, y = _inputs(r)
        m = scored_mask(r)
        if not m.any():
            raise FitError(f"{r.path}: no quasi-static samples (motor stopped, end of a hold) to fit")
        ts.append(t[m]); vs.append(v[m]); ys.append(y[m])
    t, v, y = np.concatenate(ts), np.concatenate(vs), np.concatenate(ys)
    if np.ptp(v) <= 0 or np.ptp(t) <= 0:
        raise FitError(f"{', '.join(r.path for r in runs)}: the quasi-static samples need more than one twist "
                       "and more than one heater voltage")
    try:
        model = TwistHeatModel.fit(t, v, y, TERMS[name])
    except ValueError as exc:
        raise FitError(f"{', '.join(r.path for r in runs)}: {exc}") from None
    params = {term_name(i, j): param(c, term_unit(i, j)) for (i, j), c in zip(model.terms, model.coefficients)}
    saved = SavedModel(name, {"column": INPUT_COLUMN, "unit": INPUT_UNIT}, {"column": "length", "unit": "mm"}, params)
    saved.options = {"form": "thesis eq. 3.3 (additive) with eq. 3.4 polynomials" if name == ADDITIVE
                     else "thesis eq. 3.3 + cross terms T V, T^2 V, T V^2",
                     "terms": [list(k) for k in model.terms],
                     "turns_range": [round(float(t.min()), 6), round(float(t.max()), 6)],
                     "voltage_range_V": [round(float(v.min()), 6), round(float(v.max()), 6)]}
    saved.training_files = [r.path for r in runs]
    for r in runs:
        saved.metrics["identification"][r.path] = score(model, r)[1]
    for r in validate or []:
        saved.metrics["validation"][r.path] = score(model, r)[1]
    return saved


def compare_forms(train: list[RunData], held_out: list[RunData]) -> list[dict[str, Any]]:
    """Fit both forms on ``train``; per held-out run the RMSE (mm) of each on its quasi-static
    samples and the coupled form's gain, ``100 (1 - rmse_coupled / rmse_additive)`` percent."""
    fitted = {name: fit_saved(name, train, held_out) for name in NAMES}
    rows = []
    for r in held_out:
        a, c = (fitted[name].metrics["validation"][r.path] for name in NAMES)
        rows.append({"run": r.path, "n": a["n"], "rmse_additive_mm": a["rmse"], "rmse_coupled_mm": c["rmse"],
                     "gain_percent": 100.0 * (1.0 - c["rmse"] / a["rmse"]) if a["rmse"] > 0 else 0.0})
    return rows
