"""Recorded inputs and outputs of a run, and what they lack for the judged model.

Units: t in s, turns in turns, heater voltage in V, load in g (converted from the
file's N), length in mm, resistance in ohm.

Contract: :func:`run_inputs` turns a :class:`~tsa_bench.rundata.RunData` into
:class:`RunInputs`: undeclared loads forward-filled (leading gaps from the model's
``initial_load_g``), a missing heater voltage read as 0 V, isolated missing twist
samples forward-filled (and never scored). :func:`missing_inputs` lists, as
(problem, remedy) pairs, what makes a run unusable for the judged model (no twist,
no measured output, time not increasing); the engine turns them into the verdict
``model_mismatch``. ``heldout`` is set by :mod:`tsa_bench.analysis.holdout`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

G0 = 9.80665
OUTPUTS = ("length", "resistance")


@dataclass
class RunInputs:
    t: np.ndarray
    turns: np.ndarray
    volts: np.ndarray
    load_g: np.ndarray
    moving: np.ndarray
    length: np.ndarray
    resistance: np.ndarray
    segment: np.ndarray
    cycle: np.ndarray | None = None
    heldout: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    name: str = ""
    scored: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))   # samples whose inputs are real
    load_recorded: bool = True

    def __len__(self) -> int:
        return len(self.t)

    def output(self, name: str) -> np.ndarray:
        return self.length if name == "length" else self.resistance

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0

    @property
    def rate_hz(self) -> float:
        d = np.diff(self.t)
        d = d[d > 0]
        return float(1.0 / np.median(d)) if len(d) else 1.0


def _ffill(x: np.ndarray, first: float) -> tuple[np.ndarray, np.ndarray]:
    ok = np.isfinite(x)
    if not ok.any():
        return np.full(len(x), float(first)), ok
    idx = np.where(ok, np.arange(len(x)), 0)
    np.maximum.accumulate(idx, out=idx)
    out = x[idx].astype(float)
    out[: int(np.argmax(ok))] = first
    return out, ok


def run_inputs(run, initial_load_g: float = 0.0) -> RunInputs:
    s = run.samples
    t = np.asarray(s["t"], float)
    load_raw = np.asarray(s["load"], float) / G0 * 1000.0
    load_g, load_ok = _ffill(load_raw, initial_load_g)
    load_g = np.maximum(load_g, 0.0)
    turns_raw = np.asarray(s["turns"], float)
    first = turns_raw[np.isfinite(turns_raw)][0] if np.isfinite(turns_raw).any() else 0.0
    turns, turns_ok = _ffill(turns_raw, first)
    seg = np.nan_to_num(np.asarray(s["segment"], float), nan=-1).astype(int)
    cycle = None
    if run.segments is not None and len(run.segments) and "cycle" in (run.segments.dtype.names or ()):
        cyc = np.asarray(run.segments["cycle"], int)
        cycle = np.where((seg >= 0) & (seg < len(cyc)), cyc[np.clip(seg, 0, len(cyc) - 1)], -1)
    volts = np.nan_to_num(np.asarray(s["heater_voltage"], float))
    moving = np.nan_to_num(np.asarray(s["motor_moving"], float)).astype(bool)
    return RunInputs(t, turns, volts, load_g, moving, np.asarray(s["length"], float),
                     np.asarray(s["resistance"], float), seg, cycle, np.zeros(len(t), bool),
                     str(getattr(run, "path", "")), turns_ok & np.isfinite(t), bool(load_ok.any()))


def missing_inputs(runs: list[RunInputs], outputs: tuple[str, ...]) -> list[tuple[str, str]]:
    """(problem, remedy) pairs that keep the judged model from these runs; empty = usable."""
    out: list[tuple[str, str]] = []
    for r in runs:
        name = r.name or "run"
        if len(r) < 20:
            out.append((f"{name}: only {len(r)} samples", "record a longer run"))
            continue
        if not np.all(np.isfinite(r.t)) or np.any(np.diff(r.t) <= 0):
            out.append((f"{name}: time is not finite and strictly increasing", "re-export the run with a clean time "
                        "column"))
        frac = float(np.mean(r.scored))
        if frac == 0.0:
            out.append((f"{name}: no motor twist recorded (turns is all NaN); the model is driven by the twist",
                        "record or import a turns column (tsa-bench import --map turns=...)"))
        elif frac < 0.5:
            out.append((f"{name}: motor twist missing on {100 * (1 - frac):.0f} % of the samples",
                        "record or import the turns column completely"))
        elif np.ptp(r.turns[r.scored]) == 0 and np.ptp(r.volts) == 0 and np.ptp(r.load_g) == 0:
            out.append((f"{name}: no input changes (twist, heater and load are constant); nothing excites the model",
                        "diagnose a run that moves the motor, heats or changes the load"))
    unmeasured = [o for o in outputs if not any(np.isfinite(r.output(o)).sum() >= 20 for r in runs)]
    if len(unmeasured) > 1:   # no other output to judge alone: one reason, one remedy
        out.append((f"{' and '.join(unmeasured)} are not measured (all NaN) in every run; nothing to compare the "
                    "model with", "record or import a measured length or resistance (tsa-bench import --map "
                    "length=COLUMN)"))
    for o in unmeasured if len(unmeasured) == 1 else []:
        other = [p for p in OUTPUTS if p != o]
        out.append((f"{o} is not measured (all NaN) in every run; the judged model's {o} cannot be compared",
                    f"judge the other output alone: --outputs {','.join(other)}"))
    return out
