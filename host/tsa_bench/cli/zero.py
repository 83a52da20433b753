"""`tsa-bench zero`: declare the twist the TSA has now (default: untwisted, the twist zero).

The firmware refuses moves while it does not know the motor's position (after power-up,
a reset while the motor turned, or a released motor) and keeps a declared position across
resets when the driver stays energized (firmware/README.md, "The twist zero across
resets"). A fault latched before it is cleared after saying so. Exit codes: 0 set, 1 the
device could not be reached, refused, or the operator did not confirm, 2 bad input
(nothing was sent).
"""

from __future__ import annotations

import click

from tsa_bench.cli.exits import EXIT_FAILED, fail
from tsa_bench.cli.loading import ALLOW_URL
from tsa_bench.cli.rig import _BENCH, _PORT, _open_or_exit, _rig


@click.command()
@_PORT
@_BENCH
@click.option("--turns", type=float, default=0.0, show_default=True,
              help="The twist the TSA has now (turns); 0 = hanging untwisted.")
@click.option("--yes", is_flag=True, help="Do not ask for confirmation.")
@ALLOW_URL
def zero(port: str | None, bench_path: str | None, turns: float, yes: bool, allow_url: bool) -> None:
    """Declare the TSA's present twist to the device (the twist zero when untwisted).

    Nothing moves. Asks for confirmation (the twist limits of every later run are
    counted from here), unless --yes.
    """
    from tsa_bench.protocol import msg
    from tsa_bench.rig.link import RigError

    bench, url = _rig(port, bench_path, allow_url)
    lim = bench.limits
    if (lim.max_twist_turns is not None and turns > lim.max_twist_turns) or \
            (lim.min_twist_turns is not None and turns < lim.min_twist_turns):
        fail(f"--turns {turns:g} is outside the bench's twist limits ({lim.min_twist_turns}..{lim.max_twist_turns} turns)")
    try:
        with _open_or_exit(url, bench) as link:
            st = link.status()
            spt = link.steps_per_turn
            if st.state & msg.DeviceState.POSITION_UNKNOWN:
                click.echo("device position  unknown (power-up, a reset while moving, or a released motor)")
            else:
                click.echo(f"device position  {st.step_position / spt:g} turns ({st.step_position} steps)")
            what = "hanging untwisted (twist zero)" if turns == 0 else f"twisted by {turns:g} turns"
            if not yes and not _confirmed(f"Is the TSA {what} now? Later twist limits count from here."):
                fail("not confirmed; the device's position is unchanged", EXIT_FAILED)
            steps = link.set_position(turns)
            after = link.status()
    except RigError as exc:
        fail(str(exc), EXIT_FAILED)
    if after.state & msg.DeviceState.POSITION_UNKNOWN:
        fail(f"the device still reports an unknown position after SET_POSITION {steps}", EXIT_FAILED)
    if after.step_position != steps:
        fail(f"the device reports {after.step_position} steps after SET_POSITION {steps}", EXIT_FAILED)
    click.echo(f"position set     {turns:g} turns ({steps} steps); the device keeps it across resets while its "
               f"driver stays energized")


def _confirmed(question: str) -> bool:
    """The person's answer through the operator channel (no answer possible: exit 1)."""
    from tsa_bench.operator import OperatorAbsent
    from tsa_bench.operator.terminal import TerminalOperator

    try:
        return TerminalOperator().confirm(question, if_no="the device's position stays unchanged")
    except OperatorAbsent as exc:
        fail(f"{exc}; give --yes to declare without asking; the device's position is unchanged", EXIT_FAILED)
