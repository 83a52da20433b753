"""Online length estimate from resistance alone: the self-sensing inverse run sample by sample.

Units: time in s, resistance in ohm, length in mm.

Contract: :class:`OnlineLengthEstimator` holds the states of a
:class:`~tsa_bench.models.self_sensing.SelfSensingModel` (generalized play operators
of eq. 3.17 with the tanh envelopes of eq. 3.18, the creep states of eq. 3.13, the
transient decay of eq. 3.9 restarted at every stop) and updates them with one sample
at a time (:meth:`update`: device time, resistance or NaN when not measured, the
motor-moving flag). It follows the offline estimate step for step: the initial length
comes from the median resistance measured before the first motion, a hold starts at
the first stopped sample after motion, the running mean of ``y - y_t`` over the hold
gives ``u`` (eq. 3.16) and the length (eq. 3.15), the step rate comes from two
fixed-point passes on the current estimate, and the play and creep states are
committed when the motor moves again. The estimate at the last sample of a hold equals
the offline model's hold estimate (:meth:`SelfSensingModel.estimate`). With ``window_s``
the mean covers only the last ``window_s`` seconds of the hold, so a long hold follows a
change (a new load) within that window instead of ever more slowly. With
``transient_settled_s`` the decay y_t is held at its value at that time for the rest of
the hold (the thesis saw the resistance settle after about two minutes, section 2.5.2;
eq. 3.9 alone keeps falling, which over holds of several minutes would drift the
estimate). With ``skip_s`` the samples of the first ``skip_s`` seconds of each hold are
left out (NaN): there the decay's logarithm is steepest, the first stopped sample is up
to a sampling period after the real stop, and a converting ADC (the CS5513's sinc
filter) still averages the motion; one such sample would bias the mean for the whole
window. While the motor
turns, before the first stop and during a hold without any measured resistance (heater
on) the estimate is NaN (:attr:`last_mm` keeps the last valid one). Nothing here reads
the position sensor.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from tsa_bench.models.self_sensing import SelfSensingModel, envelope


class OnlineLengthEstimator:
    """Per-sample length estimates (mm) from resistance (see the module contract)."""

    def __init__(self, model: SelfSensingModel, length_range_mm: tuple[float, float] = (1.0, 1000.0),
                 window_s: float | None = None, transient_settled_s: float | None = None,
                 skip_s: float = 0.0) -> None:
        f = model.forward
        self.model = model
        self.window_s = window_s   # None: mean over the whole hold (the thesis); else its last window_s
        self._recent: deque[tuple[float, float]] = deque()
        self.transient_settled_s = transient_settled_s  # None: eq. 3.9 for ever; else constant from then on
        self.skip_s = skip_s    # samples this soon after the stop are left out of the mean
        self._range = length_range_mm
        self._p = np.asarray(f.weights_ohm_per_mm, float)
        self._dens = np.asarray(f.creep_densities_ohm_per_mm, float)
        self._lam = np.asarray(f.creep_rates_per_s, float)
        n = len(self._p)
        unit = np.arange(n) / max(n - 1, 1)
        s = np.cumsum(self._p)
        # thresholds are scale(rate) * unit, so the inverse thresholds are scale * rbar_unit
        self._rbar_unit = unit * s - np.cumsum(unit * self._p)
        self._pbar = np.empty(n)
        self._pbar[0] = 1.0 / s[0]
        self._pbar[1:] = 1.0 / s[1:] - 1.0 / s[:-1]
        self._r0_unit = unit
        self._before: list[float] = []   # resistance before the first motion
        self._started = False            # the first motion has been seen
        self._moving = False
        self._in_hold = False
        self._t0 = 0.0                   # stop instant of the current hold
        self._sum = 0.0
        self._count = 0
        self._hold_result: tuple[np.ndarray, float, float] | None = None  # (state, u, v) of this hold so far
        self._last_t = 0.0
        self.last_mm = math.nan
        self.holds = 0

    # -- building blocks ------------------------------------------------------
    def _scale(self, rate_mm_per_s: float) -> float:
        f = self.model.forward
        return f.alpha_mm * math.log(f.beta + f.lam * abs(rate_mm_per_s) ** f.epsilon)

    def _start(self, t_s: float) -> None:
        """The first motion: the state before it, from the resistance measured until now."""
        finite = [r for r in self._before if math.isfinite(r)]
        self._t_prev = t_s
        self._started = True
        self._before = []
        self._initialise(float(np.median(finite)) if finite else math.nan)

    def _initialise(self, y_init_ohm: float) -> None:
        """Length, play and creep states of a TSA at rest whose steady resistance is ``y_init_ohm``
        (NaN: not known yet; then the first measured hold sample initialises them)."""
        m = self.model
        v = m._initial_length(y_init_ohm, *self._range) if math.isfinite(y_init_ohm) else math.nan
        self._v_prev = v
        self._u_prev = m._loading(v) if math.isfinite(v) else math.nan
        rbar0 = self._scale(0.0) * self._rbar_unit
        self._state = np.maximum(envelope(self._u_prev, *m.rho) - rbar0, 0.0)
        self._x = np.full(len(self._lam), v)

    def _begin_hold(self, t_s: float) -> None:
        d = np.exp(-self._lam * (t_s - self._t_prev))
        self._x = d * self._x + (1.0 - d) * self._v_prev
        self._t0 = t_s
        self._dt = t_s - self._t_prev
        self._sum, self._count = 0.0, 0
        self._recent.clear()
        self._hold_result = None
        self._in_hold = True
        self.holds += 1

    def _end_hold(self) -> None:
        if self._hold_result is not None:   # a hold without resistance leaves the states as they were
            self._state, self._u_prev, self._v_prev = self._hold_result
            self._t_prev = self._t0
        self._in_hold = False

    def _length(self, u: float) -> tuple[float, np.ndarray]:
        m = self.model
        rising, falling = u > self._u_prev, u < self._u_prev
        v_est = self._v_prev
        for _ in range(2):
            rate = abs(v_est - self._v_prev) / max(self._dt, 1e-9)
            rbar = self._scale(rate) * self._rbar_unit[1:]
            if rising:
                f = np.maximum(float(envelope(u, *m.rho)) - rbar, self._state[1:])
            elif falling:
                f = np.minimum(float(envelope(u, *m.phi)) + rbar, self._state[1:])
            else:
                f = self._state[1:]
            v_est = float(self._pbar[0] * u + f @ self._pbar[1:])
        new_state = self._state.copy()
        new_state[1:] = f
        return v_est, new_state

    # -- the per-sample update ---------------------------------------------------
    def update(self, t_s: float, resistance_ohm: float, motor_moving: bool) -> float:
        """One sample; returns the length estimate (mm) at it, NaN when there is none."""
        if motor_moving:
            if not self._started:
                self._start(t_s)
            elif self._in_hold:
                self._end_hold()
            self._moving = True
            return math.nan
        if not self._started:
            self._before.append(resistance_ohm)
            return math.nan
        if self._moving or not self._in_hold:
            self._begin_hold(t_s)
        self._moving = False
        self._last_t = t_s
        if not math.isfinite(resistance_ohm):
            return math.nan if self._hold_result is None else self._hold_result[2]
        f = self.model.forward
        since = t_s - self._t0
        if since < self.skip_s:
            return math.nan
        if self.transient_settled_s is not None:
            since = min(since, self.transient_settled_s)
        lg = math.log(since + f.eps_s)
        if not math.isfinite(self._v_prev):  # nothing measured before the first motion
            self._initialise(resistance_ohm - (f.b1_ohm * lg * lg + f.b2_ohm * lg))
        y = resistance_ohm - (f.b1_ohm * lg * lg + f.b2_ohm * lg)
        self._sum += y
        self._count += 1
        if self.window_s is not None:
            self._recent.append((t_s, y))
            while self._recent[0][0] < t_s - self.window_s:
                self._sum -= self._recent.popleft()[1]
                self._count -= 1
        z = self._sum / self._count
        u = f.sign * (z - f.offset_ohm - float(self._x @ self._dens))
        v, state = self._length(u)
        self._hold_result = (state, u, v)
        self.last_mm = v
        return v

    @property
    def hold_time_s(self) -> float:
        """How long the current hold has lasted at its last sample (0 while moving)."""
        return self._last_t - self._t0 if self._in_hold else 0.0


class TwistResistanceEstimator:
    """Per-sample length estimates (mm) from resistance AND twist with a load-strain model
    (:mod:`tsa_bench.models.load_strain`): the resistance, freed of the decay since the stop and
    averaged over the last ``window_s`` of the hold (after ``skip_s``), and the twist solve the
    kinematics and the strain-load-resistance relation together for length and load, so a load
    change does not read as a length change. NaN while moving and without resistance. Same
    ``update`` as :class:`OnlineLengthEstimator` plus the twist (turns)."""

    def __init__(self, model, window_s: float = 10.0, skip_s: float = 0.5) -> None:
        self.model, self.window_s, self.skip_s = model, window_s, skip_s
        self._recent: deque[tuple[float, float]] = deque()
        self._sum = 0.0
        self._t0 = -math.inf     # at rest since before the run: the decay has settled
        self._moving = False
        self.last_mm = math.nan
        self.last_load_N = math.nan

    def update(self, t_s: float, resistance_ohm: float, motor_moving: bool, turns: float = 0.0) -> float:
        from tsa_bench.models.load_strain import SETTLED_S

        if motor_moving:
            self._moving = True
            return math.nan
        if self._moving:
            self._moving, self._t0, self._sum = False, t_s, 0.0
            self._recent.clear()
        since = t_s - self._t0
        if since < self.skip_s or not math.isfinite(resistance_ohm):
            return math.nan
        m = self.model
        lg = math.log(min(since, SETTLED_S) + 1e-5)
        y = resistance_ohm - (m.b1_ohm * lg * lg + m.b2_ohm * lg)
        self._recent.append((t_s, y))
        self._sum += y
        while self._recent[0][0] < t_s - self.window_s:
            self._sum -= self._recent.popleft()[1]
        load, _, length, _ = m.solve(turns, self._sum / len(self._recent))
        if math.isfinite(length):
            self.last_mm, self.last_load_N = length, load
        return length
