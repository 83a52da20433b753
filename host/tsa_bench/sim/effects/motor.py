"""Motor effects: the stepper loses steps when the load torque exceeds its holding torque.

Units: twist in turns, torque in N m, force in N, length in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tsa_bench.sim.effects.base import Effect, PlantState, param, register_effect
from tsa_bench.sim.effects.mechanics import tsa_length_mm

_TWO_PI = 2.0 * math.pi


def load_torque_Nm(state: PlantState, turns: float) -> float:
    """Torque the hanging load puts on the motor at ``turns``: ``F * |dX/dtheta|``.

    Uses the TSA transmission ratio ``dX/dtheta = theta r^2 / X`` (= ``r tan(alpha)``)
    at the current radius (``r = r0 sqrt(L0/X)`` with radius growth), with ``L`` from the
    previous sample. The exact derivative of the radius-growth cubic diverges at full
    twist, an artefact of instantaneous, lossless radius growth; the transmission ratio
    at the current radius stays finite and grows with over-twist.
    """
    theta = _TWO_PI * abs(turns)
    if theta == 0.0:
        return 0.0
    x = tsa_length_mm(state.string_length_mm, turns, state.radius_mm, state.untwisted_length_mm,
                      state.radius_growth)
    r2 = state.radius_mm * state.radius_mm * (state.untwisted_length_mm / x if state.radius_growth else 1.0)
    return state.load_N * theta * r2 / x * 1e-3


@register_effect
class MissedSteps(Effect):
    """The stepper slips when ``F |dX/dtheta|`` exceeds its holding torque; twist lags.

    Each sample the wanted twist is ``turns_cmd - lost``; if the load torque there
    exceeds ``holding_torque_Nm`` the actual twist stops where the torque equals it (found
    by bisection) and the difference is added to ``lost``. The device's step count does
    not know. Source: NEMA 17HS4401 datasheet (holding torque ~0.4 N m); TSA transmission
    ratio (thesis eq. 4.4; Palli et al.).
    """

    name = "missed_steps"
    stage = "motor"
    source = "NEMA 17HS4401 datasheet; TSA transmission ratio, thesis eq. 4.4"

    @dataclass(frozen=True)
    class Params:
        holding_torque_Nm: float = param(0.4, "N m", "stepper holding torque (NEMA 17HS4401: 0.4 N m)",
                                         minimum=0.0)

    def reset(self) -> None:
        self.lost_turns = 0.0

    def apply(self, state: PlantState) -> None:
        want = state.turns_cmd - self.lost_turns
        hold = self.params.holding_torque_Nm
        if load_torque_Nm(state, want) > hold:
            lo, hi = 0.0, abs(want)
            sign = 1.0 if want > 0 else -1.0
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                if load_torque_Nm(state, sign * mid) > hold:
                    hi = mid
                else:
                    lo = mid
            actual = sign * lo
            self.lost_turns = state.turns_cmd - actual
            want = actual
        state.turns = want
