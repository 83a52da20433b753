"""Alternative forms of missed steps: a pull-out torque that falls with speed, and a slip
that sets in above a twist (the library's ``missed_steps`` is the torque-limited static form).

Units: twist in turns, speed in turns/s, torque in N m, time in s.

Contract: see :mod:`tsa_bench.sim.effects.base` (``register_form``). Both forms act in
the ``motor`` stage on the actual twist ``state.turns``; only twisting further (``|turns|``
growing) can lose steps, the lost twist is kept (the device's step count does not
know), and they are off unless a plant config names them.
"""

from __future__ import annotations

from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_form
from tsa_bench.sim.effects.motor import load_torque_Nm


@register_form
class MissedStepsPullout(Effect):
    """The stepper's pull-out torque falls with speed, ``T_po = T0 / (1 + w / w_c)``; beyond it
    the rotor slips.

    ``w`` is the commanded speed (change of the commanded twist over the sample interval,
    0 at rest). While twisting further, an increment whose end would need a load torque
    ``T = F |dX/dtheta|`` above ``T_po(w)`` keeps only the fraction ``(T_po / T)^n`` of
    itself; the rest is lost. A large ``slip_exponent`` n is a stall at the torque limit,
    a small one a rotor that loses a growing share of its steps as the overload grows.
    Slow moves reach further than fast ones. Source: stepper torque-speed curves (pull-out
    torque falls as back-EMF limits the phase current; e.g. NEMA 17HS4401 datasheet curve);
    TSA transmission ratio, thesis eq. 4.4.
    """

    name = "missed_steps_pullout"
    stage = "motor"
    form_of = "missed_steps"
    form = "speed-dependent pull-out"
    source = "stepper pull-out torque-speed curve; thesis eq. 4.4"

    @dataclass(frozen=True)
    class Params:
        pullout_torque_Nm: float = param(0.4, "N m", "pull-out torque T0 at standstill", minimum=0.0)
        corner_speed_turns_per_s: float = param(2.0, "turn/s", "speed w_c at which the pull-out torque halves",
                                                minimum=1e-6)
        slip_exponent: float = param(20.0, "1", "n: share (T_po/T)^n of an overloaded increment kept",
                                     minimum=0.0)

    def reset(self) -> None:
        self.lost_turns = 0.0
        self._prev_cmd: float | None = None
        self._prev: float | None = None

    def apply(self, state: PlantState) -> None:
        p = self.params
        cmd = state.turns_cmd
        prev_cmd = cmd if self._prev_cmd is None else self._prev_cmd
        speed = abs(cmd - prev_cmd) / state.dt_s if state.motor_moving and state.dt_s > 0.0 else 0.0
        self._prev_cmd = cmd
        want = cmd - self.lost_turns
        prev = want if self._prev is None else self._prev
        if abs(want) > abs(prev) and want * prev >= 0.0:
            limit = p.pullout_torque_Nm / (1.0 + speed / p.corner_speed_turns_per_s)
            torque = load_torque_Nm(state, want)
            if torque > limit:
                actual = prev + (want - prev) * (limit / torque) ** p.slip_exponent
                self.lost_turns += want - actual
                want = actual
        self._prev = want
        state.turns = want


@register_form
class MissedStepsSaturating(Effect):
    """Above a twist threshold the motor keeps only part of each twisting increment.

    Of every increment that takes ``|turns|`` beyond ``threshold_turns`` the part beyond
    it is shortened by ``slip_fraction`` (e.g. a coupling or a belt that slips once the
    string torque builds up); untwisting is not affected, so the lost twist accumulates
    over cycles. Source: observed TSA test rigs (slip at high twist, thesis 2.4.3 notes
    unaccounted friction in the setup); assumption.
    """

    name = "missed_steps_saturating"
    stage = "motor"
    form_of = "missed_steps"
    form = "saturating above a twist"
    source = "assumption; thesis 2.4.2-2.4.3 (unaccounted friction and slip in the setup)"

    @dataclass(frozen=True)
    class Params:
        threshold_turns: float = param(40.0, "turn", "twist above which increments slip", minimum=0.0)
        slip_fraction: float = param(0.3, "1", "fraction of each increment beyond the threshold that is lost",
                                     minimum=0.0)

    def reset(self) -> None:
        self.lost_turns = 0.0
        self._prev: float | None = None

    def apply(self, state: PlantState) -> None:
        p = self.params
        want = state.turns_cmd - self.lost_turns
        prev = want if self._prev is None else self._prev
        if abs(want) > abs(prev) and want * prev >= 0.0:
            beyond = abs(want) - max(abs(prev), p.threshold_turns)
            if beyond > 0.0:
                loss = min(1.0, p.slip_fraction) * beyond * (1.0 if want > 0 else -1.0)
                self.lost_turns += loss
                want -= loss
        self._prev = want
        state.turns = want
