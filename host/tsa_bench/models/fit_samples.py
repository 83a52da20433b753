"""The samples a fit reads from a run: a checked numeric column and the quasi-static mask.

Units: run-file columns in their contract units (turn, V, ohm, mm, s).

Contract: :func:`quasi_static_mask` keeps the samples with the motor stopped in the last
third of their segment (heater input: only at the twist where the heater was used, when the
run has a twist; a run without one has only its heater segments); a run
without segments (:func:`uses_whole_run`) is used whole. A missing, non-numeric or empty
column raises :class:`FitError` naming the file. :mod:`tsa_bench.models.fitting` and
:mod:`tsa_bench.models.twist_heat` both read runs through these.
"""

from __future__ import annotations

import numpy as np

from tsa_bench.rundata import RunData


class FitError(ValueError):
    """A fit or prediction that cannot run; the message names the file and the problem."""


def _column(run: RunData, name: str) -> np.ndarray:
    if name not in run.samples:
        raise FitError(f"{run.path}: no sample column '{name}' (columns: {', '.join(run.samples)})")
    if run.samples[name].dtype.kind not in "fiu":
        raise FitError(f"{run.path}: column '{name}' is not numeric")
    a = np.asarray(run.samples[name], dtype=float)
    if not np.isfinite(a).any():
        raise FitError(f"{run.path}: column '{name}' has no finite samples")
    return a


def uses_whole_run(run: RunData) -> bool:
    """True when the run has no segments (every sample's ``segment`` < 0): no holds to choose from."""
    seg = np.asarray(run.samples["segment"])
    return not bool((seg >= 0).any())


def quasi_static_mask(run: RunData, input_col: str) -> np.ndarray:
    """Motor stopped and in the last third of its segment; heater input: only at the heating twist
    (a run without twist, all NaN, has only its heater segments).

    A run without segments (:func:`uses_whole_run`) is used whole.
    """
    moving = np.asarray(run.samples["motor_moving"]).astype(bool)
    seg = np.asarray(run.samples["segment"])
    t = run.t_s
    if uses_whole_run(run):
        return np.ones(len(t), bool)
    mask = np.zeros(len(t), bool)
    # one pass over the still samples grouped by segment (a stable sort keeps time order
    # within each segment): O(n log n), where a loop over segments would be samples x segments
    still = np.flatnonzero(~moving)
    if seg.dtype.kind == "f":
        still = still[np.isfinite(seg[still])]   # a NaN segment matches no segment
    if len(still):
        order = np.argsort(seg[still], kind="stable")
        idx = still[order]
        s = seg[idx]
        first = np.flatnonzero(np.r_[True, s[1:] != s[:-1]])
        last = np.r_[first[1:], len(idx)] - 1
        t_start, t_end = t[idx[first]], t[idx[last]]
        threshold = np.repeat(t_start + 2.0 * (t_end - t_start) / 3.0, last - first + 1)
        mask[idx[t[idx] >= threshold]] = True
    if input_col == "heater_voltage":
        volts = _column(run, "heater_voltage")
        if not np.nanmax(volts) > 0:
            raise FitError(f"{run.path}: heater_voltage is never above 0 V; nothing to fit against it")
        turns = np.asarray(run.samples["turns"], float) if "turns" in run.samples else np.full(len(t), np.nan)
        if np.isfinite(turns).any():  # a run without twist (an SMA, a heated string alone) is all at one twist
            heating_twist = turns[int(np.nanargmax(volts))]
            mask &= np.abs(turns - heating_twist) < 1e-6
    return mask
