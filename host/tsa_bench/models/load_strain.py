"""Load and strain estimated together from resistance and twist (thesis 5.2: "predict both load
and strain, given the resistance and twisting angle").

Units: twist in motor turns, resistance in ohm, length in mm, load in N, strain dimensionless
(contraction ``1 - L / L_untwisted(F)``), time in s.

Contract: the resistance is first freed of the transient decay after each stop (eq. 3.9, b1 and
b2 fitted on the training holds as in the thesis, held constant from 120 s after the stop on).
The model then has two relations, identified by least squares on the settled hold samples
(motor stopped at least ``settle_s``; mean of the last third of each hold) of training runs at
two or more loads:

* kinematics with a compliant string: ``L = a0 + a1 F + a2 T^2 + a3 T^2 F + a4 T^4`` (T in
  turns), the expansion of the TSA length ``sqrt(X0(F)^2 - T^2 w^2)`` (thesis eq. 4.4) around
  the untwisted length, stretched linearly by the load;
* resistance: ``R = b0 + b1 L + b2 T + b3 F`` (length, the strings' contact, load; thesis
  2.5.1 Fig. 2.7).

:func:`estimate` solves both at each settled sample of a run for the two unknowns (L, F),
from the resistance averaged over the last ``window_s`` of the hold and the twist: substituting
the first into the second leaves one equation in F, solved by bracketing (scipy brentq) within
the training loads widened by their span. Its uncertainty (one standard deviation) propagates
the residual scatter of both relations through that equation:
``sd_F = sqrt(sd_R^2 + (b1 sd_L)^2) / |dR/dF|`` with ``dR/dF = b1 dL/dF + b3``, and
``sd_L = sqrt((dL/dF sd_F)^2 + sd_L^2)``. Samples while moving, in the first ``settle_s``
of a hold, or without resistance get NaN. The run's load column and position sensor are not read.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import brentq

from tsa_bench.models.transient import decay, fit_decay, hold_curves
from tsa_bench.outputs import write_text
from tsa_bench.rundata import RunData

FORMAT = "tsa-bench/load-strain-model"
#: The decay after a stop is taken as settled from this time on (s; thesis 2.5.2: about two minutes).
SETTLED_S = 120.0
G_N_PER_G = 9.80665e-3


class LoadStrainError(ValueError):
    """A fit, file or run that cannot be used; the message names the file and the problem."""


@dataclass(frozen=True)
class LoadStrainModel:
    """The two relations (module contract) and their residual scatter."""

    a: tuple[float, float, float, float, float]   # mm, mm/N, mm/turn^2, mm/(turn^2 N), mm/turn^4
    b: tuple[float, float, float, float]          # ohm, ohm/mm, ohm/turn, ohm/N
    sd_length_mm: float
    sd_resistance_ohm: float
    load_range_N: tuple[float, float]
    twist_range_turns: tuple[float, float]
    settle_s: float = 10.0
    window_s: float = 10.0
    b1_ohm: float = 0.0            # transient decay after each stop (eq. 3.9), subtracted first,
    b2_ohm: float = 0.0            # held at its value from SETTLED_S on
    bench: str | None = None       # name of the bench the training runs were recorded on

    def length_range_mm(self) -> tuple[float, float]:
        """Lengths (mm) the model spans over its training twists and loads."""
        grid = [self.length(t, f) for t in np.linspace(*self.twist_range_turns, 21)
                for f in np.linspace(*self.load_range_N, 5)]
        return float(min(grid)), float(max(grid))

    def length(self, turns: float, load_N: float) -> float:
        a, t2 = self.a, turns * turns
        return a[0] + a[1] * load_N + a[2] * t2 + a[3] * t2 * load_N + a[4] * t2 * t2

    def resistance(self, turns: float, length_mm: float, load_N: float) -> float:
        b = self.b
        return b[0] + b[1] * length_mm + b[2] * abs(turns) + b[3] * load_N

    def solve(self, turns: float, resistance_ohm: float) -> tuple[float, float, float, float]:
        """(load N, sd, length mm, sd) at one twist and resistance; NaNs when no load in range fits."""
        lo, hi = self.load_range_N
        span = hi - lo
        lo, hi = lo - span, hi + span

        def g(f: float) -> float:
            return self.resistance(turns, self.length(turns, f), f) - resistance_ohm

        if not (math.isfinite(resistance_ohm) and g(lo) * g(hi) < 0):
            return (math.nan,) * 4
        f = brentq(g, lo, hi, xtol=1e-6)
        dl_df = self.a[1] + self.a[3] * turns * turns
        dr_df = self.b[1] * dl_df + self.b[3]
        sd_f = math.hypot(self.sd_resistance_ohm, self.b[1] * self.sd_length_mm) / abs(dr_df)
        return f, sd_f, self.length(turns, f), math.hypot(dl_df * sd_f, self.sd_length_mm)

    def as_json(self) -> dict[str, Any]:
        d = asdict(self)
        return {"format": FORMAT, "format_version": "1.0", "model": "load-strain",
                "units": {"a": ["mm", "mm/N", "mm/turn^2", "mm/(turn^2 N)", "mm/turn^4"],
                          "b": ["ohm", "ohm/mm", "ohm/turn", "ohm/N"], "sd_length_mm": "mm",
                          "sd_resistance_ohm": "ohm", "load_range_N": "N", "twist_range_turns": "turn",
                          "settle_s": "s", "window_s": "s", "b1_ohm": "ohm", "b2_ohm": "ohm"}, **d}


def _settled_holds(run: RunData, settle_s: float) -> list[tuple[int, int]]:
    """(start, stop) sample slices of the last third of each hold at least ``settle_s`` long."""
    moving = np.asarray(run.samples["motor_moving"]).astype(bool)
    t = run.t_s
    out = []
    for c in hold_curves(t, moving):
        dur = t[c.stop - 1] - c.t0_s
        if dur < settle_s:
            continue
        start = c.start + int(np.searchsorted(t[c.start:c.stop], c.t0_s + max(settle_s, 2 * dur / 3)))
        if c.stop - start >= 3:
            out.append((start, c.stop))
    return out


def corrected_resistance(run: RunData, b1: float, b2: float) -> np.ndarray:
    """The run's resistance minus the transient decay since each stop (ohm; 0 while moving)."""
    t = run.t_s
    r = _column(run, "resistance").copy()
    for c in hold_curves(t, np.asarray(run.samples["motor_moving"]).astype(bool)):
        r[c.start:c.stop] -= decay(np.minimum(t[c.start:c.stop] - c.t0_s, SETTLED_S), b1, b2)
    return r


def _column(run: RunData, name: str) -> np.ndarray:
    if name not in run.samples:
        raise LoadStrainError(f"{run.path}: no sample column '{name}'")
    return np.asarray(run.samples[name], dtype=float)


def fit(runs: list[RunData], settle_s: float = 10.0, window_s: float = 10.0) -> LoadStrainModel:
    """Identify the model on training runs (module contract); at least two loads are needed."""
    curves = []
    for run in runs:
        t, res = run.t_s, _column(run, "resistance")
        for c in hold_curves(t, np.asarray(run.samples["motor_moving"]).astype(bool)):
            keep = t[c.start:c.stop] - c.t0_s < SETTLED_S
            curves.append(((t[c.start:c.stop] - c.t0_s)[keep], res[c.start:c.stop][keep]))
    try:
        b1, b2, _ = fit_decay(curves)
    except ValueError as exc:
        raise LoadStrainError(f"{', '.join(r.path for r in runs)}: {exc}") from None
    rows = []
    for run in runs:
        turns, length, load = (_column(run, n) for n in ("turns", "length", "load"))
        res = corrected_resistance(run, b1, b2)
        for i, j in _settled_holds(run, settle_s):
            vals = [np.nanmean(c[i:j]) for c in (turns, res, length, load)]
            if all(math.isfinite(v) for v in vals):
                rows.append(vals)
    if len(rows) < 12:
        raise LoadStrainError(f"{', '.join(r.path for r in runs)}: {len(rows)} settled holds; at least 12 are needed")
    t, r, length, f = np.array(rows).T
    if np.ptp(f) < 0.1:
        raise LoadStrainError(f"{', '.join(r.path for r in runs)}: every hold is at one load "
                              f"({f[0] / G_N_PER_G:.0f} g); load and length cannot be told apart without two or more")
    t2 = t * t
    ka = np.column_stack([np.ones_like(t), f, t2, t2 * f, t2 * t2])
    a, *_ = np.linalg.lstsq(ka, length, rcond=None)
    kb = np.column_stack([np.ones_like(t), length, np.abs(t), f])
    b, *_ = np.linalg.lstsq(kb, r, rcond=None)
    sd_l = float(np.std(length - ka @ a, ddof=5))
    sd_r = float(np.std(r - kb @ b, ddof=4))
    return LoadStrainModel(tuple(float(x) for x in a), tuple(float(x) for x in b), sd_l, sd_r,  # type: ignore[arg-type]
                           (float(f.min()), float(f.max())), (float(t.min()), float(t.max())), settle_s, window_s,
                           b1, b2, _bench(runs))


def _bench(runs: list[RunData]) -> str | None:
    from tsa_bench.models.fitting import _bench_name

    names = {_bench_name(r.bench_text) for r in runs}
    return names.pop() if len(names) == 1 else None


def save(model: LoadStrainModel, path: str | Path) -> None:
    import json

    write_text(path, json.dumps(model.as_json(), indent=1) + "\n")


def load(path: str | Path) -> LoadStrainModel:
    """Read a model file; LoadStrainError naming the file and the problem."""
    from tsa_bench.userfiles import DocumentError, read_json

    p = Path(path)
    try:
        doc = read_json(p, what="load-strain model file")
    except DocumentError as exc:
        raise LoadStrainError(str(exc)) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise LoadStrainError(f"{p}: 'format' is {got!r}, expected {FORMAT!r} (a file from `tsa-bench estimate --train`)")
    try:
        return LoadStrainModel(tuple(map(float, doc["a"])), tuple(map(float, doc["b"])),  # type: ignore[arg-type]
                               float(doc["sd_length_mm"]), float(doc["sd_resistance_ohm"]),
                               tuple(map(float, doc["load_range_N"])),  # type: ignore[arg-type]
                               tuple(map(float, doc["twist_range_turns"])),  # type: ignore[arg-type]
                               float(doc["settle_s"]), float(doc["window_s"]), float(doc["b1_ohm"]),
                               float(doc["b2_ohm"]), doc.get("bench") if isinstance(doc.get("bench"), str) else None)
    except (KeyError, TypeError, ValueError) as exc:
        raise LoadStrainError(f"{p}: missing or malformed field ({exc})") from None


@dataclass(frozen=True)
class Estimates:
    """Per-sample estimates (NaN where there is none); arrays of the run's length."""

    load_N: np.ndarray
    load_sd_N: np.ndarray
    length_mm: np.ndarray
    length_sd_mm: np.ndarray
    strain: np.ndarray
    strain_sd: np.ndarray


def estimate(model: LoadStrainModel, run: RunData) -> Estimates:
    """Load and strain at every settled sample of ``run`` from resistance and twist only."""
    t = run.t_s
    turns, res = _column(run, "turns"), corrected_resistance(run, model.b1_ohm, model.b2_ohm)
    moving = np.asarray(run.samples["motor_moving"]).astype(bool)
    n = len(t)
    out = np.full((6, n), np.nan)
    for c in hold_curves(t, moving):
        for k in range(c.start, c.stop):
            if t[k] - c.t0_s < model.settle_s:
                continue
            lo = c.start + int(np.searchsorted(t[c.start:k + 1], t[k] - model.window_s))
            r = float(np.nanmean(res[lo:k + 1])) if np.isfinite(res[lo:k + 1]).any() else math.nan
            f, sd_f, length, sd_l = model.solve(float(turns[k]), r)
            if not math.isfinite(f):
                continue
            untwisted = model.length(0.0, f)
            out[:, k] = (f, sd_f, length, sd_l, 1.0 - length / untwisted, sd_l / untwisted)
    return Estimates(*out)


def _after_load_changes(run: RunData, window_s: float) -> np.ndarray:
    """Samples more than ``window_s`` after the last change of the declared load (all when none)."""
    load = np.asarray(run.samples["load"], float) if "load" in run.samples else np.zeros(len(run))
    t = run.t_s
    ok = np.ones(len(t), bool)
    changes = np.flatnonzero(np.abs(np.diff(load)) > 1e-9) + 1
    for k in changes:
        ok &= ~((t >= t[k]) & (t < t[k] + window_s))
    return ok


def hold_table(est: Estimates, run: RunData) -> list[dict[str, float]]:
    """The estimate at the last sample of each hold that has one, with its errors where the run
    recorded a load and a length (NaN otherwise)."""
    t, turns = run.t_s, _column(run, "turns")
    load = np.asarray(run.samples["load"], float) if "load" in run.samples else np.full(len(t), np.nan)
    length = np.asarray(run.samples["length"], float) if "length" in run.samples else np.full(len(t), np.nan)
    rows = []
    for c in hold_curves(t, np.asarray(run.samples["motor_moving"]).astype(bool)):
        ok = np.flatnonzero(np.isfinite(est.load_N[c.start:c.stop]))
        if not len(ok):
            continue
        k = c.start + int(ok[-1])
        rows.append({"t_s": float(t[k]), "turns": float(turns[k]), "load_N": float(est.load_N[k]),
                     "load_sd_N": float(est.load_sd_N[k]), "strain": float(est.strain[k]),
                     "strain_sd": float(est.strain_sd[k]), "length_mm": float(est.length_mm[k]),
                     "load_err_percent": float(100 * (est.load_N[k] - load[k]) / load[k]) if load[k] else math.nan,
                     "length_err_mm": float(est.length_mm[k] - length[k])})
    return rows


def summary(est: Estimates, run: RunData, window_s: float = 10.0) -> dict[str, Any]:
    """How many samples have an estimate and, where the run recorded them, the largest errors over
    the samples more than ``window_s`` after a load change (the estimate's averaging window)."""
    ok = np.isfinite(est.load_N)
    out: dict[str, Any] = {"n": int(ok.sum())}
    if "load" in run.samples and "length" in run.samples:
        load = np.asarray(run.samples["load"], float)
        length = np.asarray(run.samples["length"], float)
        sel = ok & _after_load_changes(run, window_s) & np.isfinite(load) & (load > 0) & np.isfinite(length)
        if sel.any():
            rel = np.abs(est.load_N[sel] - load[sel]) / load[sel]
            dl = np.abs(est.length_mm[sel] - length[sel])
            out.update(load_err_max_percent=float(100 * rel.max()), load_err_mean_percent=float(100 * rel.mean()),
                       length_err_max_mm=float(dl.max()),
                       length_err_max_percent=float(100 * (dl / length[sel]).max()))
    return out
