"""A YAML protocol as one step of a Bluesky plan: the project's runner, its samples as events.

Units: the sample stream's columns are the run file's (``t`` s since the protocol
started, ``turns`` turn, ``length`` mm, ``resistance`` ohm, NaN where not measured,
``heater_voltage`` V, ``load`` N, ``step_position`` step); segment and event times in s
on the same clock.

Contract of :class:`ProtocolFlyer`: the protocol is read and checked against the rig's
bench when the flyer is made (a bad protocol raises :class:`ProtocolRejected` with its
file:line errors, before anything moves), and against the connected device at
``kickoff``. ``kickoff`` hands it to :class:`~tsa_bench.runner.Runner` on the rig's
session (the same runner and device client as ``tsa-bench run``); the rig refuses moves,
heater changes and readings while it runs. ``complete`` finishes when the runner ends
and fails with the runner's reason when the run did not succeed ("aborted",
"failed"). ``collect_pages`` hands over what arrived since the last collect, in three
streams: ``<name>`` (the samples), ``<name>_segments`` (one row per executed protocol
step) and ``<name>_events`` (device and host events), so a plan may collect while the
protocol runs (:func:`tsa_bench.bluesky.plans.run_protocol`) or once at the end
(``bluesky.plans.fly``). ``stop``, and ``pause`` (the RunEngine's pause cannot hold a
protocol half-way), make the runner send STOP at its next safe point: motor halted,
heater off, the run ends "aborted". Prompts in the protocol ("hang 200 g") are answered
at once on a simulated rig; on a real one they stop the run with
:class:`~tsa_bench.operator.channel.OperatorAbsent` unless an ``operator`` is given.
The configuration (``read_configuration``) holds the protocol and bench texts, so a
run file written from the documents (:mod:`tsa_bench.bluesky.bridge`) holds them too.
"""

from __future__ import annotations

import asyncio
import json
import threading
import time
from collections.abc import Iterator
from concurrent.futures import Future
from pathlib import Path
from typing import Any

from bluesky.protocols import PartialEventPage, Reading
from event_model import DataKey
from ophyd_async.core import AsyncStatus, Device

from tsa_bench.bluesky.operator import OperatorRefusal
from tsa_bench.bluesky.session import RigRefused
from tsa_bench.bluesky.sources import source_of
from tsa_bench.operator.channel import AutoOperator
from tsa_bench.operator.channel import OperatorChannel as Operator
from tsa_bench.plan import Plan, PlanErrors, Prompt, load_plan
from tsa_bench.rundocs import SAMPLE_COLUMNS, EventRecord, RunStart, RunStop, SampleBlock, SegmentRecord
from tsa_bench.runner.checks import PlanRejected, check_plan_against_device
from tsa_bench.runner.commands import plan_problems
from tsa_bench.runner.interrupts import Interrupts
from tsa_bench.runner.tracking import bench_problems
from tsa_bench.shipped import find_config

#: Sample columns of the ``<name>`` stream (the run file's; raw counts stay in the run file).
STREAM_COLUMNS = ("t", "turns", "length", "resistance", "heater_voltage", "load", "segment", "motor_moving",
                  "step_position", "counter")
#: Columns of ``<name>_segments``: (field, dtype, units, quantity in the source)
SEGMENT_FIELDS = (("index", "integer", "1"), ("kind", "string", ""), ("t_start", "number", "s"),
                  ("t_end", "number", "s"), ("completed", "integer", "1"), ("cycle", "integer", "1"),
                  ("source", "string", ""), ("params", "string", ""))
EVENT_FIELDS = (("t", "number", "s"), ("kind", "string", ""), ("detail", "string", ""))
_DTYPE = {"f8": "number", "i4": "integer", "u1": "integer", "u4": "integer"}


class ProtocolRejected(ValueError):
    """The protocol cannot run on this rig; the message lists every problem (file:line)."""


class _RemoteInterrupts(Interrupts):
    """The runner's safe-point interrupts, requested from another thread (a stop)."""

    def request(self) -> None:
        self.count += 1


class _Collector:
    """The runner's consumer: keeps what arrives, for ``collect_pages`` (thread-safe)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.start: RunStart | None = None
        self.wall0 = time.time()
        self.blocks: list[SampleBlock] = []
        self.segments: list[SegmentRecord] = []
        self.events: list[EventRecord] = []
        self.stop: RunStop | None = None

    def on_start(self, start: RunStart) -> None:
        self.start, self.wall0 = start, time.time()

    def on_samples(self, block: SampleBlock) -> None:
        with self.lock:
            self.blocks.append(block)

    def on_segment(self, segment: SegmentRecord) -> None:
        with self.lock:
            self.segments.append(segment)

    def on_event(self, event: EventRecord) -> None:
        with self.lock:
            self.events.append(event)

    def on_stop(self, stop: RunStop) -> None:
        self.stop = stop

    def take(self) -> tuple[list[SampleBlock], list[SegmentRecord], list[EventRecord]]:
        with self.lock:
            out = self.blocks, self.segments, self.events
            self.blocks, self.segments, self.events = [], [], []
        return out


def load_protocol(path: str | Path, rig: Any) -> Plan:
    """The protocol compiled under the rig's bench limits, every command checked to fit
    the wire (the checks of ``tsa-bench validate``); :class:`ProtocolRejected` otherwise."""
    found, _ = find_config(path, "protocols")
    try:
        plan = load_plan(found, rig.bench.limits)
    except PlanErrors as exc:
        raise ProtocolRejected(f"{found} is not a valid protocol; nothing was sent to any device:\n{exc}") from None
    problems = plan_problems(plan, rig.bench.steps_per_turn) + bench_problems(plan, rig.bench.name)
    if problems:
        raise ProtocolRejected(f"{found} cannot be sent to bench '{rig.bench.name}'; nothing was sent to any "
                               "device:\n" + "\n".join(problems))
    return plan


def _final_load_g(plan: Plan) -> float:
    load = plan.load_g
    for seg in plan.segments:
        if isinstance(seg.action, Prompt) and seg.action.load_g is not None:
            load = seg.action.load_g
    return float(load) if load is not None else float("nan")


class ProtocolFlyer(Device):
    """A YAML protocol run on ``rig`` (a :class:`~tsa_bench.bluesky.TsaRig`) as a flyer
    (see the module contract). ``operator`` answers the protocol's prompts (default: at
    once on a simulated rig; refused on a real one)."""

    def __init__(self, rig: Any, protocol: str | Path, *, name: str = "protocol",
                 operator: Operator | None = None, metadata: dict | None = None) -> None:
        object.__setattr__(self, "_rig", rig)   # a reference, not a child device
        self.plan = load_protocol(protocol, rig)
        self._operator = operator
        self._metadata = dict(metadata or {})
        self._collector: _Collector | None = None
        self._job: Future | None = None
        self._interrupts: _RemoteInterrupts | None = None
        super().__init__(name=name)

    # -- Flyable -----------------------------------------------------------------
    @AsyncStatus.wrap
    async def kickoff(self) -> None:
        """Check the protocol against the connected device and start it on the rig; done
        once the runner has started it (its run start emitted)."""
        rig = self._rig
        rig._require_idle()
        session = rig.session
        link = session.open_link
        try:
            check_plan_against_device(self.plan, link.identity)
        except PlanRejected as exc:
            raise ProtocolRejected(f"{exc}; nothing was run") from None
        simulated = link.simulated
        operator = self._operator or (AutoOperator() if simulated else OperatorRefusal())
        self._collector, self._interrupts = _Collector(), _RemoteInterrupts()
        rig._flying = True
        rig._invalidate()
        col = self._collector
        self._job = job = session.submit(session.run_protocol, self.plan, [col], operator, self._interrupts,
                                         self._metadata, _final_load_g(self.plan))
        # started means the runner holds the device: a stop from here on ends the run "aborted"
        # through its safe points (before that, the session's STOP alone would end it)
        while col.start is None and not job.done():
            await asyncio.sleep(0.01)
        if col.start is None:
            rig._flying = False
            job.result()   # it ended before starting (position unknown, a fault, a stop): say why

    @AsyncStatus.wrap
    async def complete(self) -> None:
        """Wait for the protocol to end; fail with the runner's reason unless it succeeded."""
        if self._job is None:
            raise RigRefused(f"{self.name}: complete() before kickoff()")
        try:
            stop: RunStop = await asyncio.wrap_future(self._job)
        finally:
            self._rig._flying = False
            self._rig._invalidate()
        if stop.exit_status != "success":
            raise RuntimeError(f"protocol '{self.plan.name}' ended {stop.exit_status}: {stop.reason}")

    @AsyncStatus.wrap
    async def stage(self) -> None:
        """Nothing to prepare (the protocol was checked when the flyer was made)."""

    @AsyncStatus.wrap
    async def unstage(self) -> None:
        """A protocol still running when its plan ends (aborted, failed, stopped) is stopped."""
        if self._job is not None and not self._job.done():
            await self.stop()

    async def stop(self, success: bool = False) -> None:
        """STOP at the runner's next safe point (motor halted, heater off); the run ends "aborted"."""
        if self._interrupts is not None and self._job is not None and not self._job.done():
            self._interrupts.request()
        await self._rig._send_stop()

    async def pause(self) -> None:
        """A protocol cannot wait half-way: pausing stops it (see :meth:`stop`)."""
        await self.stop()

    async def resume(self) -> None:
        """Nothing to resume: a paused protocol was stopped."""

    # -- configuration -------------------------------------------------------------
    def _config(self) -> dict[str, str]:
        bench = self._rig.bench
        return {"protocol": self.plan.source_text, "protocol_path": self.plan.path or "",
                "bench": bench.source_text, "bench_path": bench.path or ""}

    async def describe_configuration(self) -> dict[str, DataKey]:
        port = self._rig.port
        return {f"{self.name}-{k}": DataKey(dtype="string", shape=[], source=source_of(port, k))
                for k in self._config()}

    async def read_configuration(self) -> dict[str, Reading]:
        stamp = time.time()
        return {f"{self.name}-{k}": Reading(value=v, timestamp=stamp) for k, v in self._config().items()}

    # -- Collectable -----------------------------------------------------------------
    async def describe_collect(self) -> dict[str, dict[str, DataKey]]:
        """Three streams: the samples, the executed segments, the events."""
        port, n = self._rig.port, self.name
        samples = {f"{n}-{c}": DataKey(dtype=_DTYPE[SAMPLE_COLUMNS[c][0]], shape=[], source=source_of(port, c),
                                       units=SAMPLE_COLUMNS[c][1]) for c in STREAM_COLUMNS}
        segments = {f"{n}-segment_{f}": DataKey(dtype=d, shape=[], source=source_of(port, f"segment_{f}"), units=u)
                    for f, d, u in SEGMENT_FIELDS}
        events = {f"{n}-event_{f}": DataKey(dtype=d, shape=[], source=source_of(port, f"event_{f}"), units=u)
                  for f, d, u in EVENT_FIELDS}
        return {n: samples, f"{n}_segments": segments, f"{n}_events": events}

    def collect_pages(self) -> Iterator[PartialEventPage]:
        """What arrived since the last collect, one page per stream that has rows."""
        col = self._collector
        if col is None:
            return
        blocks, segments, events = col.take()
        n, wall0 = self.name, col.wall0
        if blocks:
            data = {f"{n}-{c}": [v.item() for b in blocks for v in b.columns[c]] for c in STREAM_COLUMNS}
            stamps = [wall0 + t for t in data[f"{n}-t"]]
            yield PartialEventPage(data=data, timestamps={k: stamps for k in data})
        if segments:
            rows = [(s.index, s.kind, s.t_start, s.t_end, int(s.completed), -1 if s.cycle is None else s.cycle,
                     s.source, json.dumps(s.params)) for s in segments]
            data = {f"{n}-segment_{f}": [r[i] for r in rows] for i, (f, _, _) in enumerate(SEGMENT_FIELDS)}
            stamps = [wall0 + s.t_end for s in segments]
            yield PartialEventPage(data=data, timestamps={k: stamps for k in data})
        if events:
            data = {f"{n}-event_t": [e.t for e in events], f"{n}-event_kind": [e.kind for e in events],
                    f"{n}-event_detail": [e.detail for e in events]}
            stamps = [wall0 + e.t for e in events]
            yield PartialEventPage(data=data, timestamps={k: stamps for k in data})
