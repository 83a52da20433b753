"""``hold_until_settled``: when a hold has reached its steady state.

Units: time in s of device time, length in mm, resistance in ohm.

The thesis held each rotation "for 3 minutes, ensuring that the steady-state length and
resistance was reached" (section 2.5.1) and saw the resistance settle "after
approximately two minutes" (section 2.5.2). The criterion made explicit: the hold
ends once the least-squares slopes of resistance and length over the last
``window_s`` seconds are within the thresholds, |dR/dt| <= ``max_dR_dt_ohm_per_s`` and
|dL/dt| <= ``max_dL_dt_mm_per_s`` (a threshold of None is not judged), not before
``min_duration_s`` and never after ``max_duration_s``.

Execution contract (:class:`SettleHold`): the device holds with DWELLs of
:data:`CHUNK_S` (the first one ``min_duration_s`` long), at most two queued at a
time, their total never above ``max_duration_s``. Before queueing the next one the
runner asks :meth:`SettleHold.verdict`; once it says settled no more are queued and the
hold ends when the queued ones have run, so a hold runs at most about two chunks past
the moment it settled. A slope is judged only from samples of this hold that span at
least 80 % of the window, with at least 5 measured values: while the resistance is
not measured (heater on) the resistance criterion cannot be met.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tsa_bench.plan import Settle

#: Length of the DWELLs a settling hold is made of (s).
CHUNK_S = 1.0
#: Most DWELLs of one settling hold queued on the device at once.
IN_FLIGHT = 2
MIN_POINTS = 5
MIN_SPAN_FRACTION = 0.8


def slope(t: np.ndarray, y: np.ndarray, window_s: float) -> float | None:
    """Least-squares dy/dt over the samples in the last ``window_s`` (finite y only);
    None when they are too few or span too little of the window."""
    ok = np.isfinite(y)
    t, y = t[ok], y[ok]
    if len(t) < MIN_POINTS or t[-1] - t[0] < MIN_SPAN_FRACTION * window_s:
        return None
    tc = t - t.mean()
    return float(np.dot(tc, y - y.mean()) / np.dot(tc, tc))


@dataclass
class SettleHold:
    """The state of one settling hold while it runs (see the module contract)."""

    index: int
    action: Settle
    sent_s: float = 0.0                 # DWELL time queued so far
    t_start: float | None = None        # device time its first DWELL started
    settled: bool | None = None         # None: still holding; True/False once decided
    slopes: tuple[float | None, float | None] = (None, None)   # (dR/dt, dL/dt) last judged
    _t: list[float] = field(default_factory=list)
    _length: list[float] = field(default_factory=list)
    _resistance: list[float] = field(default_factory=list)

    def add(self, t_s: float, length_mm: float, resistance_ohm: float) -> None:
        """A sample taken during this hold."""
        if self.t_start is None:
            return
        self._t.append(t_s)
        self._length.append(length_mm)
        self._resistance.append(resistance_ohm)

    def next_chunk_s(self) -> float:
        """Length of the next DWELL (0: the maximum duration is all queued)."""
        a = self.action
        first = a.min_duration_s if self.sent_s == 0 and a.min_duration_s > 0 else CHUNK_S
        return max(0.0, min(first, a.max_duration_s - self.sent_s))

    def verdict(self) -> bool | None:
        """True once settled, False once the maximum is all queued, else None; sets :attr:`settled`."""
        if self.settled is not None:
            return self.settled
        a = self.action
        if self._t and self.t_start is not None and self._t[-1] - self.t_start >= a.min_duration_s:
            t = np.asarray(self._t)
            recent = t >= t[-1] - a.window_s
            dr = slope(t[recent], np.asarray(self._resistance)[recent], a.window_s)
            dl = slope(t[recent], np.asarray(self._length)[recent], a.window_s)
            self.slopes = (dr, dl)
            ok_r = a.max_dR_dt_ohm_per_s is None or (dr is not None and abs(dr) <= a.max_dR_dt_ohm_per_s)
            ok_l = a.max_dL_dt_mm_per_s is None or (dl is not None and abs(dl) <= a.max_dL_dt_mm_per_s)
            if ok_r and ok_l:
                self.settled = True
                return True
            keep = t >= t[-1] - a.window_s * 1.5   # memory stays bounded by the window
            if not keep.all():
                first = int(np.argmax(keep))
                del self._t[:first], self._length[:first], self._resistance[:first]
        if self.next_chunk_s() <= 0:
            self.settled = False
        return self.settled

    def outcome(self) -> dict:
        """What the hold found, added to its segment's parameters in the run file."""
        dr, dl = self.slopes
        return {"settled": bool(self.settled), "dR_dt_ohm_per_s": dr, "dL_dt_mm_per_s": dl}

    def describe(self, duration_s: float) -> str:
        dr, dl = self.slopes
        shown = ", ".join(f"{name} = {v:.3g} {unit}" for name, v, unit in
                          (("dR/dt", dr, "ohm/s"), ("dL/dt", dl, "mm/s")) if v is not None)
        if self.settled:
            return f"settled after {duration_s:.1f} s ({shown})"
        return f"not settled within {self.action.max_duration_s:g} s" + (f" ({shown})" if shown else "")
