"""Recorded inputs and outputs of a run, and the train / held-out split.

Units: t in s, turns in turns, heater voltage in V, load in g (converted from the
file's N), length in mm, resistance in ohm.

Contract: :func:`run_inputs` turns a :class:`~tsa_bench.store.RunData` into
:class:`RunInputs` (undeclared loads forward-filled, leading gaps from the model's
``initial_load_g``). :func:`split` applies a holdout SPEC: ``None`` (whole last run
when several, else the last 30 % cut at a segment boundary), ``"run:N"``,
``"after:SECONDS"``, ``"fraction:F"``; held-out samples always form one suffix per
run, never interleaved with training samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

G0 = 9.80665


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

    def __len__(self) -> int:
        return len(self.t)

    @property
    def n_train(self) -> int:
        """Training samples form the prefix [0, n_train)."""
        h = np.flatnonzero(self.heldout)
        return int(h[0]) if len(h) else len(self.t)


def run_inputs(run, initial_load_g: float = 0.0) -> RunInputs:
    s = run.samples
    t = np.asarray(s["t"], float)
    load_n = np.asarray(s["load"], float)
    load_g = load_n / G0 * 1000.0
    ok = np.isfinite(load_g)
    if ok.any():
        idx = np.where(ok, np.arange(len(t)), 0)
        np.maximum.accumulate(idx, out=idx)
        filled = load_g[idx]
        first = int(np.argmax(ok))
        filled[:first] = initial_load_g
        load_g = filled
    else:
        load_g = np.full(len(t), float(initial_load_g))
    load_g = np.maximum(load_g, 0.0)
    seg = np.asarray(s["segment"], int)
    cycle = None
    if run.segments is not None and len(run.segments) and "cycle" in (run.segments.dtype.names or ()):
        cyc = np.asarray(run.segments["cycle"], int)
        cycle = np.where((seg >= 0) & (seg < len(cyc)), cyc[np.clip(seg, 0, len(cyc) - 1)], -1)
    volts = np.nan_to_num(np.asarray(s["heater_voltage"], float))
    return RunInputs(t, np.asarray(s["turns"], float), volts, load_g,
                     np.asarray(s["motor_moving"]).astype(bool), np.asarray(s["length"], float),
                     np.asarray(s["resistance"], float), seg, cycle, np.zeros(len(t), bool),
                     str(getattr(run, "path", "")))


def _cut_at_segment(inp: RunInputs, i: int) -> int:
    """Move a cut index to the nearest segment boundary (change of segment index)."""
    b = np.flatnonzero(np.diff(inp.segment) != 0) + 1
    if len(b) == 0:
        return i
    return int(b[np.argmin(np.abs(b - i))])


def split(runs: list[RunInputs], holdout: str | None) -> str:
    """Set each run's ``heldout`` mask from the SPEC; return a description."""
    for r in runs:
        r.heldout = np.zeros(len(r), bool)
    if holdout is None:
        if len(runs) > 1:
            runs[-1].heldout[:] = True
            return f"held out: whole last run ({runs[-1].name})"
        holdout = "fraction:0.3"
        segment_cut = True
    else:
        segment_cut = False
    kind, _, arg = holdout.partition(":")
    try:
        value = float(arg)
    except ValueError:
        raise ValueError(f"holdout {holdout!r}: expected run:N, after:SECONDS or fraction:F") from None
    if kind == "run":
        k = int(value)
        if not -len(runs) <= k < len(runs):
            raise ValueError(f"holdout {holdout!r}: only {len(runs)} run(s)")
        if len(runs) < 2:
            raise ValueError(f"holdout {holdout!r}: holding out a whole run needs several runs")
        runs[k].heldout[:] = True
        return f"held out: run {k}"
    if kind == "after":
        for r in runs:
            r.heldout = r.t >= value
        return f"held out: t >= {value} s"
    if kind == "fraction":
        if not 0.0 < value < 1.0:
            raise ValueError(f"holdout {holdout!r}: fraction must be in (0, 1)")
        for r in runs:
            t0, t1 = r.t[0], r.t[-1]
            i = int(np.searchsorted(r.t, t1 - value * (t1 - t0)))
            if segment_cut:
                i = _cut_at_segment(r, i)
            r.heldout[i:] = True
        return f"held out: last {value:.0%} of the time" + (" (cut at a segment boundary)" if segment_cut else "")
    raise ValueError(f"holdout {holdout!r}: expected run:N, after:SECONDS or fraction:F")
