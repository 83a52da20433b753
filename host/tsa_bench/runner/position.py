"""The twist zero at the start of a run: kept by the device, or declared by the operator.

Units: positions in steps (microsteps), turns for the operator.

Contract: :func:`settle_position` takes the QUEUE_STATUS the run starts with. When the
device kept its position across the reset (the state has no position_unknown bit) it
returns an event saying so and where. Otherwise (power-on, a reset mid-move, a released
motor) it asks the operator whether the TSA hangs untwisted; yes -> SET_POSITION 0 and
an event recording the answer; no (or Enter alone, which the question says) -> :class:`PositionUnknown`,
nothing moved. The
simulated and firmware-in-the-loop benches answer yes themselves (their plant starts
untwisted). The device refuses moves until its position is known, so this runs before
the first segment.
"""

from __future__ import annotations

from typing import Callable

from tsa_bench.device import BenchClient
from tsa_bench.protocol import msg
from tsa_bench.operator import OperatorChannel as Operator

QUESTION = ("The device does not know the motor's position (it powered up, or reset while moving or "
            "released). Is the TSA untwisted now (strings hanging straight, twist zero)?")


#: What a no (or Enter alone) to :data:`QUESTION` does; shown with the question.
IF_NO = "the run stops before anything moves"


class PositionUnknown(RuntimeError):
    """The operator did not confirm the twist zero: the run cannot start."""


def settle_position(client: BenchClient, operator: Operator, status: msg.QueueStatus, steps_per_turn: int,
                    record: Callable[[str, str], None]) -> None:
    """Make the device's position known before the run (see module contract);
    ``record(kind, detail)`` writes an event to the run."""
    if not status.state & msg.DeviceState.POSITION_UNKNOWN:
        record("position_kept", f"the device kept its position across the reset: {status.step_position} steps "
                                f"({status.step_position / steps_per_turn:g} turns)")
        return
    if not operator.confirm(QUESTION, if_no=IF_NO):
        raise PositionUnknown("the twist zero is unknown and the operator did not confirm the TSA is untwisted "
                              "(answered no, or Enter alone): untwist it (or declare its twist with "
                              "`tsa-bench zero --turns N`) and run it again; nothing moved")
    client.set_position(0)
    record("position_set", "operator confirmed the TSA untwisted: position set to 0 steps (twist zero)")
