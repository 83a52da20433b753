"""Plans for a rig: a protocol run whose samples stream into the run while it runs.

Contract: :func:`run_protocol` stages the flyer (so whatever ends the plan early - an
abort, a pause, an error - its unstage stops a protocol still running: STOP, heater
off), opens a run, kicks off a
:class:`~tsa_bench.bluesky.flyer.ProtocolFlyer`, collects what arrived every ``poll_s``
s of wall time until the protocol ends (so live callbacks see its samples as it runs),
collects the rest, and closes the run; a protocol that ended "aborted" or "failed"
fails the plan after everything received was collected.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

import bluesky.plan_stubs as bps
import bluesky.preprocessors as bpp
from bluesky.utils import Msg, short_uid


def run_protocol(flyer: Any, *, poll_s: float = 0.5, md: dict | None = None) -> Generator[Msg, Any, Any]:
    """One run: the protocol of ``flyer`` from kickoff to its end (see the module contract).
    ``poll_s`` (s, > 0): how often collected samples become events; ``md``: run metadata."""
    if not poll_s > 0:
        raise ValueError(f"poll_s must be > 0 s, got {poll_s!r}")
    plan = flyer.plan
    meta = {"plan_name": "run_protocol", "protocol": plan.name, "protocol_path": plan.path or "", **(md or {})}

    @bpp.stage_decorator([flyer])   # its unstage stops a protocol the plan leaves running
    @bpp.run_decorator(md=meta)
    def inner() -> Generator[Msg, Any, Any]:
        yield from bps.kickoff(flyer, wait=True)
        group = short_uid("protocol")
        status = yield from bps.complete(flyer, group=group, wait=False)
        while not status.done:
            yield from bps.collect(flyer)
            yield from bps.sleep(poll_s)
        yield from bps.collect(flyer)
        yield from bps.wait(group)

    return (yield from inner())
