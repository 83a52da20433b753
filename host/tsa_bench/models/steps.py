"""A run cut into its holds (transient curves), the time base of the strain-resistance models.

Units: time in s, length in mm, resistance in ohm, rates in mm/s.

Contract: :func:`series_from_arrays` keeps the four columns the models read.
:func:`step_sequence` finds the holds (a hold starts at the first stopped sample after
motion, :func:`~tsa_bench.models.transient.hold_curves`) and returns one row per
hold plus a leading row ``-1`` for the state before the first motion (its length is
the median of the samples before the first move; without such samples, the first
hold's). ``step_s[k]`` is the time between consecutive stops (the thesis's step
duration including the move), and ``rate[k] = |v(k) - v(k-1)| / step_s[k]`` the
length step divided by the step duration (thesis 3.2.2, below eq. 3.12).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tsa_bench.models.transient import HoldCurve, hold_curves


@dataclass(frozen=True)
class RunSeries:
    """The columns the self-sensing models use; ``name`` identifies the run (file path)."""

    name: str
    t_s: np.ndarray
    length_mm: np.ndarray
    resistance_ohm: np.ndarray
    motor_moving: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.t_s)
        for col in ("length_mm", "resistance_ohm", "motor_moving"):
            if len(getattr(self, col)) != n:
                raise ValueError(f"{self.name}: column {col} has {len(getattr(self, col))} samples, t has {n}")


def series_from_arrays(name: str, t_s: np.ndarray, length_mm: np.ndarray, resistance_ohm: np.ndarray,
                       motor_moving: np.ndarray) -> RunSeries:
    return RunSeries(name, np.asarray(t_s, float), np.asarray(length_mm, float), np.asarray(resistance_ohm, float),
                     np.asarray(motor_moving).astype(bool))


@dataclass(frozen=True)
class StepSequence:
    """Per-hold quantities of one run; index 0 is the state before the first motion."""

    curves: list[HoldCurve]
    t0_s: np.ndarray        # (m + 1,) stop instants; [0] = start of the first motion
    step_s: np.ndarray      # (m + 1,) time since the previous stop; [0] = 0
    length_mm: np.ndarray   # (m + 1,) mean length over each hold; [0] = initial length
    rate_mm_per_s: np.ndarray  # (m + 1,) |length step| / step duration; [0] = 0
    initial_resistance_ohm: float  # median resistance before the first motion (NaN if none)


def step_sequence(run: RunSeries) -> StepSequence:
    """Cut ``run`` into holds (module docstring); raises ValueError without any hold."""
    curves = hold_curves(run.t_s, run.motor_moving)
    if not curves:
        raise ValueError(f"{run.name}: no hold after motor motion (motor_moving never goes from 1 to 0)")
    moving_idx = np.flatnonzero(run.motor_moving)
    first_move = int(moving_idx[0])
    lengths = np.array([np.nanmean(run.length_mm[c.start:c.stop]) for c in curves])
    before = run.length_mm[:first_move]
    v_init = float(np.nanmedian(before)) if first_move > 0 and np.isfinite(before).any() else float(lengths[0])
    r_before = run.resistance_ohm[:first_move]
    r_init = float(np.nanmedian(r_before)) if first_move > 0 and np.isfinite(r_before).any() else float("nan")
    t0 = np.r_[run.t_s[first_move], [c.t0_s for c in curves]]
    v = np.r_[v_init, lengths]
    step = np.r_[0.0, np.diff(t0)]
    rate = np.zeros_like(v)
    rate[1:] = np.abs(np.diff(v)) / np.maximum(step[1:], 1e-9)
    return StepSequence(curves, t0, step, v, rate, r_init)
