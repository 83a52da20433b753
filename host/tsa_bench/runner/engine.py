"""The run engine: executes a compiled Plan on a connected bench and emits documents.

Contract: :meth:`Runner.run` keeps the device's command queue fed from the plan, one
device command per plan segment (operator prompts are handled on the host once the
device is idle), converts samples to physical units with the bench calibration, and
emits :mod:`tsa_bench.rundocs` to every consumer. It never sleeps on wall
time for device-timed work: holds and moves are timed by the device, and the runner
only waits for bytes. It always ends with ``on_stop``: "success" when every segment
is done, "aborted" on Ctrl-C (after an immediate STOP, which also turns the heater
off), "failed" on a device fault, a refused command or a lost connection, keeping
everything received so far.

Signals (:mod:`tsa_bench.runner.interrupts`): SIGINT and SIGTERM are taken over for
the run (when it runs in the main thread) and acted on only at safe points, so the
first one always leads to STOP and a file closed "aborted", even when it arrives
during a flush; a second one only hurries the end. A signal that arrives after the
last segment but before the file is closed still ends the run "aborted" (the user
asked to stop; STOP is sent to an idle device).

Settling holds (:mod:`tsa_bench.runner.settle`) are sent as short DWELLs while the
runner judges the samples; nothing after such a hold is queued until it has settled.
Resume (:mod:`tsa_bench.runner.resume`): given a :class:`ResumePoint`, the runner
starts at its segment (indices stay those of the plan), after set-up commands that
bring the rig to the state the plan had there (sampling period, twist, heater, load).

Pacing (:mod:`tsa_bench.runner.pacing`): when to heartbeat, and where a simulated device
in this process may deliver in batches (open-loop stretches; the recorded run is the same).
On a line, a :class:`~tsa_bench.device.keepalive.Keepalive` thread also heartbeats while the
run's thread is busy (started with the run, stopped on every way out; prompts are waits
for a person, not stalls).
Samples are handed over in blocks of exactly ``block_samples`` rows (or what came within
``BLOCK_WALL_S`` of wall time), each followed by the documents received after its rows.

Link: samples are stored in counter order, each once: a sample whose counter is not
after the last stored one (a duplicate or a late frame the link layer let through) is
dropped and counted (``samples_discarded``), and ``samples_lost`` is exactly the sum of
the counter gaps in the stored rows. Segment indices: the device's 16-bit index is
unwrapped to the plan segment nearest the oldest one not done
(:func:`~tsa_bench.runner.commands.plan_segment`), and every block is checked before a
consumer gets it: an index outside the plan is stored as -1 and fails the run. A
QUEUE_EMPTY is recorded as ``queue_underrun`` only when it follows the last command of a
burst (:mod:`tsa_bench.runner.underrun`).
"""

from __future__ import annotations

import math
import signal
from array import array
import time
from contextlib import AbstractContextManager, nullcontext
from typing import NamedTuple, Sequence

from tsa_bench.benchdata import BenchConfig
from tsa_bench.device import BenchClient, DeviceError
from tsa_bench.device.faults import CLEARS, RECOVERY, fault_name, latched_text
from tsa_bench.device.keepalive import Keepalive
from tsa_bench.plan import Move, Plan, Prompt, Segment, Settle, TrackLength
from tsa_bench.protocol import msg
from tsa_bench.protocol.blocks import refusal_reason
from tsa_bench.runner.checks import PlanRejected, check_plan_against_device  # noqa: F401 (re-exported)
from tsa_bench.runner.clock_fit import RunClocks
from tsa_bench.runner.commands import NO_SEGMENT, WIRE_SEGMENTS, device_commands, load_mg, plan_segment
from tsa_bench.rundocs import (
    EventRecord, RunConsumer, RunStart, RunStop, SegmentRecord, StorageFull,
)
from tsa_bench.operator import OperatorAbsent
from tsa_bench.operator import OperatorChannel as Operator
from tsa_bench.runner.interrupts import Interrupts
from tsa_bench.runner.pacing import Pacing
from tsa_bench.runner.position import PositionUnknown, settle_position
from tsa_bench.runner.resume import ResumePoint
from tsa_bench.runner.samples import length_mm, resistance_ohm, sample_block, segments_outside_plan
from tsa_bench.units import G_N_PER_G
from tsa_bench.runner.settle import IN_FLIGHT, SettleHold
from tsa_bench.runner.tracking import COLUMNS as TRACKING_COLUMNS, Tracking
from tsa_bench.runner.underrun import Bursts

_SEGMENT_STARTED, _SEGMENT_DONE = int(msg.EventKind.SEGMENT_STARTED), int(msg.EventKind.SEGMENT_DONE)
_FAULT, _QUEUE_EMPTY = int(msg.EventKind.FAULT), int(msg.EventKind.QUEUE_EMPTY)
COUNTER_MOD = 1 << 32         # SAMPLE.counter is a u32
_HALF_WIRE = WIRE_SEGMENTS // 2
BLOCK_SAMPLES = 2048          # emit a sample block once this many samples are pending,
BLOCK_WALL_S = 0.5            # or this much wall time has passed (segment records and events
                              # wait with them, emitted in order after the block)


def plan_load_known(load_g: float) -> bool:
    return load_g == load_g  # not NaN


class RunFailed(Exception):
    """Ends a run as failed with the given reason."""


class Runner:
    """Runs one plan on a connected :class:`~tsa_bench.device.BenchClient`; see the module contract.

    ``client`` must be connected (``ValueError`` otherwise); ``plan`` compiled under
    ``bench.limits``; ``consumers`` get the run documents in order (a
    :class:`~tsa_bench.store.RunWriter` writes the file); ``operator`` answers prompts, an
    :class:`~tsa_bench.operator.channel.OperatorChannel` (``AutoOperator`` on a simulated
    bench, ``TerminalOperator`` at a real rig).
    ``backend`` ("sim", "serial", "simavr") and ``port_name`` are recorded in the run file;
    ``metadata`` adds to the protocol's; ``block_samples`` rows per
    :class:`~tsa_bench.rundocs.SampleBlock`. One Runner runs once.
    """

    def __init__(self, client: BenchClient, plan: Plan, bench: BenchConfig, consumers: Sequence[RunConsumer],
                 operator: Operator, *, backend: str, port_name: str, interrupts: Interrupts | None = None,
                 resume: ResumePoint | None = None, metadata: dict | None = None,
                 block_samples: int = BLOCK_SAMPLES) -> None:
        if client.identity is None:
            raise ValueError("connect the client before running")
        self.client, self.plan, self.bench = client, plan, bench
        self.consumers = list(consumers)
        self.operator = operator
        self.backend, self.port_name = backend, port_name
        self.interrupts = interrupts if interrupts is not None else Interrupts()
        self.ident: msg.Identity = client.identity
        self.spt = self.ident.steps_per_turn
        self.simulated = bool(self.ident.flags & msg.DeviceFlags.SIMULATED)
        self.resume = resume
        self.metadata = {**plan.metadata, **(metadata or {})}
        n = self._n_segments = len(plan.segments)
        first = resume.first_segment if resume is not None else 0
        if not 0 <= first <= n:
            raise ValueError(f"resume segment {first} is outside the plan's {n} segments")
        # per plan segment: typed arrays (indexed a few times per segment, which numpy scalars make
        # slow; a list would hold a float object per start time, 32 B a segment instead of 8)
        self._t_start = array("d", [math.nan]) * n    # s; NaN until its SEGMENT_STARTED
        self._done = array("b", [1]) * first + array("b", [0]) * (n - first)
        self._parts = array("i", [0]) * n       # device commands of each segment (a long hold: several)
        self._parts_done = array("i", [0]) * n  # SEGMENT_DONE events seen per segment
        self._to_send: list[NamedTuple] = []       # commands of segment _next not yet accepted
        self._next = first              # next plan segment to send
        self._oldest = first            # oldest segment not yet done
        self._settle: SettleHold | None = None   # the settling hold being sent, if any
        self._settle_done_t: float | None = None  # when its last queued DWELL ended
        self._settle_outcome: dict[int, dict] = {}  # what each decided settling hold found
        self._free = self.ident.queue_slots
        self._sent = 0                  # commands sent (ACKed or not)
        self._sent_at_heartbeat = -1    # _sent just after the runner's last heartbeat
        self._last_sent_wire = NO_SEGMENT
        self._t0_us: int | None = None
        self._now_us = 0
        self._last_tx_dev_us = 0
        self._last_rx_wall = time.monotonic()
        # hanging mass (g) as the protocol declares it; NaN = not declared (unknown)
        self._load_g = float(plan.load_g) if plan.load_g is not None else float("nan")
        if resume is not None:
            self._load_g = float(resume.load_g) if resume.load_g is not None else float("nan")
        self._prompt_segment: int | None = None
        self._last_status: msg.QueueStatus | None = None
        self._fault_at_start_ok = False   # while the set-up looks at a fault latched before the run
        self._rows: list[tuple] = []
        self.block_samples = max(1, int(block_samples))  # 1: documents handed over at every read
        # documents waiting for the rows before them: (how many of _rows came before, name, doc)
        self._later: list[tuple[int, str, object]] = []
        self._last_block_wall = time.monotonic()
        self._last_counter: int | None = None
        self.samples = 0
        self.samples_lost = 0
        self.samples_discarded = 0
        self._segments_done = 0
        self._bursts = Bursts()         # which QUEUE_EMPTY is an underrun (runner/underrun.py)
        self._pacing = Pacing(client, plan, self.ident)   # heartbeats, batched delivery (runner/pacing.py)
        self._clocks = RunClocks(self._pacing.device_clock)   # device and sensor clock fits (runner/clock_fit.py)
        # a line's watchdog fed from a thread of its own (in process, sim:// keeps the device's time)
        self._keepalive = None if self._pacing.device_clock else Keepalive(client, self._pacing.heartbeat_wall_s)
        self._tracking = Tracking.for_plan(plan, self.spt)   # track_length segments (runner/tracking.py)
        self._silence_s = max(3.0, 4 * self.ident.watchdog_ms / 1000.0)

    # -- emit ------------------------------------------------------------------
    def _emit(self, name: str, doc) -> None:
        for c in self.consumers:
            getattr(c, name)(doc)

    def _emit_later(self, name: str, doc) -> None:
        """A segment record or event: emitted after the samples received before it, with
        the next sample block (at once when no samples are pending)."""
        if self._rows:
            self._later.append((len(self._rows), name, doc))
        else:
            self._emit(name, doc)

    def _t(self, t_us: float) -> float:
        return (t_us - (self._t0_us or 0)) / 1e6

    def _event(self, kind: str, detail: str, t_us: float | None = None) -> None:
        if t_us is None:    # a host-side event: now, on the device's clock
            t_us = self._clocks.event_us(self._now_us, time.monotonic())
        self._emit_later("on_event", EventRecord(self._t(t_us), kind, detail))

    # -- protocol helpers --------------------------------------------------
    def _unwrap(self, wire: int) -> int:
        """The plan segment the device names (-1: none; runner/commands.py plan_segment)."""
        return plan_segment(wire, self._oldest, len(self._done))

    def _segment_named(self, wire: int) -> str:
        idx = self._unwrap(wire)
        return f"segment {idx}" if idx >= 0 else "outside the plan's segments"

    def _command(self, message: NamedTuple) -> msg.Ack:
        ack = self.client.command(message, check=False)
        self._last_tx_dev_us = self._pacing.device_now_us(self._now_us)
        self._sent += 1
        return ack

    # -- main loop -----------------------------------------------------------
    def run(self) -> RunStop:
        """Run the plan to its end, an abort or a failure (module contract); return the
        :class:`~tsa_bench.rundocs.RunStop` every consumer also got. Device faults and a lost
        connection end the run "failed" rather than raise."""
        wall0 = time.monotonic()
        plan = self.plan
        summary = plan.summary()
        ident = self.ident
        start = RunStart(
            plan_name=plan.name, protocol_text=plan.source_text, protocol_path=plan.path,
            bench_text=self.bench.source_text, bench_path=self.bench.path, backend=self.backend,
            port=self.port_name, firmware=f"{ident.fw_major}.{ident.fw_minor}.{ident.fw_patch}",
            identity=ident._asdict(), n_segments=len(plan.segments),
            estimated_duration_s=summary.duration_s, metadata=dict(self.metadata),
            extra_attrs=self.resume.attributes() if self.resume is not None else {},
            extra_columns=TRACKING_COLUMNS if self._tracking else {})
        status, reason = "success", "all segments done"
        installed_here = self.interrupts.install()
        self.client.on_wait = self.interrupts.check
        if self._keepalive is not None:
            self._keepalive.start()
        try:
            try:
                self._emit("on_start", start)
                self._setup()
                self._pacing.allowed = True
                while self._oldest < len(plan.segments):
                    self._feed()
                    self._pump()
                self._pacing.stop_batching()
                self._teardown()
                self.interrupts.stopping()
                if self.interrupts.requested:  # asked to stop before the file closed: honour it
                    status, reason = "aborted", "interrupted by the user after all segments were done"
                    self._safe_stop()
            except KeyboardInterrupt:
                status, reason = "aborted", (f"interrupted by the user ({self._signal_name()}); "
                                             "motor stopped, heater off")
                self._safe_stop()
            except StorageFull as exc:
                status, reason = "failed", str(exc)
                self._safe_stop()
            except (RunFailed, DeviceError, OperatorAbsent) as exc:
                status, reason = "failed", str(exc)
                self._safe_stop()
            except Exception as exc:  # a consumer or host bug: never leave the motor or heater running
                status, reason = "failed", f"host error: {type(exc).__name__}: {exc}"
                self._safe_stop()
            try:
                self._flush_rows()
                self._close_open_segments()
            except StorageFull as exc:
                if status != "aborted":
                    status = "failed"
                reason = str(exc) if status == "failed" and reason == "all segments done" else f"{reason}; then {exc}"
            except Exception as exc:
                status, reason = "failed", f"{reason}; then host error: {type(exc).__name__}: {exc}"
            stop = RunStop(status, reason, self._t(self._now_us), self.samples, self.samples_lost,
                           self._segments_done, time.monotonic() - wall0, attrs=self._clocks.attrs())
            for consumer in self.consumers:  # every consumer gets to close, even if another fails
                try:
                    consumer.on_stop(stop)
                except Exception:
                    pass
            return stop
        finally:
            if self._keepalive is not None:
                self._keepalive.stop()
            self.client.on_wait = None
            if installed_here:
                self.interrupts.restore()

    def _attended(self) -> AbstractContextManager:
        """A wait for a person: the keepalive goes on however long it takes."""
        return self._keepalive.attended() if self._keepalive is not None else nullcontext()

    def _signal_name(self) -> str:
        sig = self.interrupts.last_signal
        return "SIGTERM" if sig == signal.SIGTERM else "Ctrl-C"

    def _setup(self) -> None:
        self._fault_at_start_ok = True
        self._command(msg.Heartbeat())
        while self._t0_us is None:          # QUEUE_STATUS gives the device clock at run start
            self._pump()
        if self._last_status.fault:         # latched before this run (a host that left while it sampled)
            self._clear_fault_at_start(self._last_status)
        self._fault_at_start_ok = False
        try:                                # moves need a known twist zero
            with self.interrupts.immediate(), self._attended():   # a person may take minutes
                settle_position(self.client, self.operator, self._last_status, self.spt, self._event)
        except PositionUnknown as exc:
            raise RunFailed(str(exc)) from None
        if self.simulated and plan_load_known(self._load_g):
            self._command(msg.SimSetLoad(load_mg(self._load_g)))
        r = self.resume
        period_s = self.plan.sampling_period_s if r is None else r.sampling_period_s
        self._queued(msg.SetSampling(NO_SEGMENT, round(period_s * 1e6)), "set sampling")
        if r is not None:   # the state the plan had at the resumed segment
            self._event("resume", r.describe())
            self._queued(msg.MoveTo(NO_SEGMENT, round(r.turns * self.spt), max(1, round(r.rate_turns_per_s * self.spt)),
                                    max(1, round(r.accel_turns_per_s2 * self.spt))), "the move to the resumed twist")
            if r.heater_V:
                self._queued(msg.SetHeater(NO_SEGMENT, round(r.heater_V * 1000)), "the resumed heater voltage")

    def _clear_fault_at_start(self, status: msg.QueueStatus) -> None:
        """Say what is latched, then CLEAR_QUEUE; RunFailed when the fault stays."""
        what = latched_text(status, self.ident)
        self.operator.tell(f"tsa-bench: {what}. Clearing it now (CLEAR_QUEUE) before the run starts.")
        self._event("fault_at_start", f"{fault_name(status.fault)} latched before the run: CLEAR_QUEUE sent")
        self._command(msg.ClearQueue())
        self._last_status = None
        self._command(msg.Heartbeat())
        while self._last_status is None:
            self._pump()
        if self._last_status.fault:
            raise RunFailed(f"the device keeps fault {fault_name(self._last_status.fault)} latched after "
                             f"CLEAR_QUEUE: its cause is still there; {RECOVERY.get(fault_name(status.fault), '')}")

    def _teardown(self) -> None:
        self._queued(msg.SetHeater(NO_SEGMENT, 0), "heater off")
        self._queued(msg.SetSampling(NO_SEGMENT, 0), "sampling off")
        for m in self.client.poll():       # samples taken up to the end
            self._handle(m)

    def _queued(self, message: NamedTuple, what: str) -> None:
        self.interrupts.check()
        ack = self._command(message)
        while ack.status == msg.Status.QUEUE_FULL:
            self._pump()
            ack = self._command(message)
        if ack.status != msg.Status.OK:
            raise RunFailed(f"device refused {what}: {msg.Status(ack.status).name.lower()}"
                            f"{refusal_reason(message, ack.status, self.bench.baud)}")
        self._free = ack.queue_free

    def _safe_stop(self) -> None:
        """STOP (always sent, retransmitted until acknowledged or the budget ends), then
        what the device said meanwhile, unless a second signal asks to hurry."""
        self.interrupts.stopping()
        try:
            self._pacing.stop_batching()
            self.client.stop()
            self._event("stop_sent", "STOP sent: motor halted, heater off, queue cleared")
            if self.interrupts.hurry:
                return
            for m in self.client.poll():
                try:
                    self._handle(m)
                except RunFailed as exc:  # already stopping; keep it as an event
                    self._event("fault", str(exc))
        except (DeviceError, KeyboardInterrupt):
            pass
        except StorageFull:
            pass  # the writer already said so; the device has been stopped

    def _feed(self) -> None:
        """Send plan segments while the device has room; handle a prompt when idle. What
        one call sends is a burst (runner/underrun.py)."""
        try:
            self._feed_burst()
        finally:
            self._bursts.end(self._oldest)

    def _feed_burst(self) -> None:
        segs = self.plan.segments
        while self._next < len(segs) and self._free > 0:
            self.interrupts.check()
            seg = segs[self._next]
            if isinstance(seg.action, Prompt):
                if self._oldest < self._next:
                    return                 # the device must finish what it has first
                self._do_prompt(seg)
                continue
            if isinstance(seg.action, Settle):
                if not self._feed_settle(seg):
                    return
                continue
            if isinstance(seg.action, TrackLength):
                if not self._tracking.feed(self, seg):  # type: ignore[union-attr]
                    return
                continue
            if not self._to_send:          # a long hold is several DWELLs
                self._to_send = device_commands(seg, self.spt)
                self._parts[self._next] = len(self._to_send)
            if not self._accepted(self._command(self._to_send[0]), seg, self._to_send[0]):
                return
            self._to_send.pop(0)
            if not self._to_send:
                self._next += 1

    def _accepted(self, ack: msg.Ack, seg: Segment, command: NamedTuple | None = None) -> bool:
        """Bookkeeping of a queued command's ACK: False when the queue was full (nothing
        was queued, send it again later); RunFailed when the device refused it."""
        if ack.status == msg.Status.QUEUE_FULL:
            self._free = 0
            return False
        if ack.status == msg.Status.BAD_STATE:
            self._explain_bad_state()
        if ack.status != msg.Status.OK:
            raise RunFailed(f"device refused segment {seg.index} ({seg.kind}, {seg.source}): "
                            f"{msg.Status(ack.status).name.lower()}{refusal_reason(command, ack.status, self.bench.baud)}")
        self._free = ack.queue_free
        self._last_sent_wire = seg.index % WIRE_SEGMENTS
        self._bursts.accepted(seg.index)
        return True

    def _feed_settle(self, seg: Segment) -> bool:
        """Queue the next DWELL of a settling hold, or end its sending once it has
        settled; False when nothing more can be sent now."""
        st = self._settle
        if st is None or st.index != seg.index:
            st = self._settle = SettleHold(seg.index, seg.action)  # type: ignore[arg-type]
            self._settle_done_t = None
        if st.verdict() is not None:
            self._settle_outcome[seg.index] = st.outcome()
            self._event("settled" if st.settled else "not_settled",
                        f"segment {seg.index}: " + st.describe(self._t(self._now_us) - (st.t_start or 0.0)))
            self._next += 1
            if self._settle_done_t is not None and self._parts_done[seg.index] >= self._parts[seg.index]:
                self._finish_segment(seg.index, float(self._t_start[seg.index]), self._settle_done_t, True)
            return True
        if self._parts[seg.index] - self._parts_done[seg.index] >= IN_FLIGHT:
            return False
        chunk_s = st.next_chunk_s()
        if not self._accepted(self._command(msg.Dwell(seg.index % WIRE_SEGMENTS, round(chunk_s * 1e6))), seg):
            return False
        self._parts[seg.index] += 1
        st.sent_s += chunk_s
        return True

    def _explain_bad_state(self) -> None:
        """A refusal for bad state means a latched fault: report the fault itself (its
        EVENT may still be waiting in the inbox, else QUEUE_STATUS names it)."""
        for m in self.client.poll():
            self._handle(m)
        self._command(msg.Heartbeat())
        for m in self.client.poll():
            self._handle(m)

    def _do_prompt(self, seg: Segment) -> None:
        a: Prompt = seg.action  # type: ignore[assignment]
        self._flush_rows()
        t_start = self._t(self._now_us)
        self._prompt_segment = seg.index
        self._event("prompt", a.text)
        with self.interrupts.immediate(), self._attended():  # a person may take minutes: Ctrl-C must not wait
            self.operator.answer(a.text, a.load_g)
        if a.load_g is not None:
            self._load_g = float(a.load_g)
            if self.simulated:
                self._command(msg.SimSetLoad(load_mg(a.load_g)))
            self._event("load", f"load now {a.load_g:g} g ({a.load_g * G_N_PER_G:.4g} N)")
        self._prompt_segment = None
        self._finish_segment(seg.index, t_start, self._t(self._now_us), True)
        self._next += 1

    def _pump(self) -> None:
        """Read and handle what the device sent; heartbeat; detect silence."""
        self.interrupts.check()
        pacing = self._pacing
        if pacing.device_clock:   # before the read (after _feed's commands): it is the read that runs the device
            self._heartbeat_if_due(time.monotonic())
        pacing.update(self._oldest, self._next)
        messages = self.client.poll()
        wall = time.monotonic()
        if messages:
            self._last_rx_wall = wall
            sample, on_sample, handle = msg.Sample, self._on_sample, self._handle
            for m in messages:
                if type(m) is sample:
                    on_sample(m)
                else:
                    handle(m)
        elif wall - self._last_rx_wall > self._silence_s:
            raise RunFailed(f"lost connection: the device on {self.port_name} has been silent for "
                            f"{wall - self._last_rx_wall:.1f} s")
        if len(self._rows) >= self.block_samples:
            while len(self._rows) >= self.block_samples:   # whole blocks: the writer's chunks stay aligned
                self._flush_rows(self.block_samples)
        elif self._rows and wall - self._last_block_wall >= BLOCK_WALL_S:
            self._flush_rows()
        if not pacing.device_clock:
            self._heartbeat_if_due(wall)

    def _heartbeat_if_due(self, wall: float) -> None:
        if self._pacing.heartbeat_due(self._pacing.device_now_us(self._now_us), self._last_tx_dev_us, wall):
            self._command(msg.Heartbeat())
            self._sent_at_heartbeat = self._sent

    # -- incoming messages -----------------------------------------------------
    def _handle(self, m: NamedTuple) -> None:
        if isinstance(m, msg.Sample):
            self._on_sample(m)
        elif isinstance(m, msg.Event):
            self._on_event(m)
        elif isinstance(m, msg.QueueStatus):
            self._last_status = m
            self._clocks.on_status(m, self.client.take_round_trips())
            self._now_us = max(self._now_us, m.t_us)
            if self._t0_us is None:
                self._t0_us = m.t_us
            if self._sent == self._sent_at_heartbeat:
                # it answers the last heartbeat, and no command's ACK since says more
                # (a stale count would only cost a refused, resent command)
                self._free = m.queue_free
            if m.fault and not self._fault_at_start_ok:
                raise RunFailed(f"device fault latched: {fault_name(m.fault)}; {CLEARS}")
            if (not m.executing and m.queue_free == self.ident.queue_slots and self._oldest < self._next
                    and m.segment == self._last_sent_wire):
                # idle with an empty queue after the last segment sent: whatever was sent
                # is done, even if a SEGMENT_DONE event was lost on the line (a status
                # produced before the last send names an older segment and is ignored)
                for idx in range(self._oldest, self._next):
                    if not self._done[idx] and not isinstance(self.plan.segments[idx].action, Prompt):
                        start = self._t_start[idx]
                        t_end = self._t(m.t_us)
                        self._finish_segment(idx, t_end if math.isnan(start) else float(start), t_end, True)
        elif isinstance(m, msg.Ack):
            self._free = m.queue_free
        elif isinstance(m, msg.Boot):
            raise RunFailed("the device rebooted during the run (power or reset?); data so far kept")

    def _on_sample(self, s: msg.Sample) -> None:
        counter, t_us, step_position, position_raw, resistance_raw, adc_flags, heater_mV, motor_moving, wire = s
        last = self._last_counter
        if last is not None and counter != (last + 1) & 0xFFFFFFFF:   # not simply the next one
            # signed distance on the wrapping u32 counter: <= 0 is a repeat or out of order
            step = (counter - last + COUNTER_MOD // 2) % COUNTER_MOD - COUNTER_MOD // 2
            if step <= 0:
                self.samples_discarded += 1
                return
            gap = step - 1
            self.samples_lost += gap
            self._event("sample_gap", f"{gap} sample(s) lost before counter {counter}", t_us)
        if t_us > self._now_us:
            self._now_us = t_us
        t_us = self._clocks.stamp(counter, t_us)   # the sensor fit's time while sampling continuously
        self._last_counter = counter
        if self._prompt_segment is not None:
            seg = self._prompt_segment
        elif wire == NO_SEGMENT:      # self._unwrap(wire), inline (once per sample)
            seg = -1
        else:
            oldest = self._oldest
            seg = oldest + (wire - oldest + _HALF_WIRE) % WIRE_SEGMENTS - _HALF_WIRE
            if seg >= self._n_segments or seg < 0:
                seg = -1
        # a row for sample_block (runner/samples.py row(), inline: once per sample)
        self._rows.append((t_us, step_position, position_raw, resistance_raw, adc_flags, heater_mV, motor_moving, seg,
                           counter, self._load_g))
        self.samples += 1
        if self._tracking is not None:
            self._tracking.on_sample(self._t(s.t_us), resistance_ohm(self.bench, s.resistance_raw, s.adc_flags),
                                     bool(s.motor_moving), s.step_position / self.spt, seg)
        st = self._settle
        if st is not None and st.index == seg and st.settled is None:
            st.add(self._t(s.t_us), length_mm(self.bench, s.position_raw, s.adc_flags),
                   resistance_ohm(self.bench, s.resistance_raw, s.adc_flags))

    def _on_event(self, e: msg.Event) -> None:
        self._now_us = max(self._now_us, e.t_us)
        kind = e.kind
        if kind == _SEGMENT_STARTED:
            self._free = min(self._free + 1, self.ident.queue_slots)
            idx = self._unwrap(e.segment)
            if 0 <= idx < len(self._t_start):
                self._finish_before(idx, e.t_us)
                if math.isnan(self._t_start[idx]):  # the first of its device commands
                    self._t_start[idx] = self._t(e.t_us)
                    if self._settle is not None and self._settle.index == idx:
                        self._settle.t_start = self._t(e.t_us)
        elif kind == _SEGMENT_DONE:
            idx = self._unwrap(e.segment)
            if 0 <= idx < len(self._done) and not self._done[idx]:
                self._finish_before(idx, e.t_us)
                self._parts_done[idx] += 1
                if self._settle is not None and self._settle.index == idx:
                    self._settle_done_t = self._t(e.t_us)
                if idx < self._next and self._parts_done[idx] >= self._parts[idx]:  # its last command
                    start = self._t_start[idx]
                    t_end = self._t(e.t_us)
                    self._finish_segment(idx, t_end if math.isnan(start) else float(start), t_end, True)
        elif kind == _FAULT:
            raise RunFailed(f"device fault: {fault_name(e.code)} ({self._segment_named(e.segment)}); "
                            f"{RECOVERY.get(fault_name(e.code), '')}; {CLEARS}")
        elif kind == _QUEUE_EMPTY:
            # An underrun: the device ran dry after the last command of a burst (runner/underrun.py)
            # of a plan segment that is followed by more device work. Not one: set-up and
            # tear-down commands (NO_SEGMENT; over a real link their QUEUE_EMPTY arrives after
            # the first plan segment was sent), an instant command finished before the next
            # of its burst arrived, and the wait before an operator prompt.
            idx = self._unwrap(e.segment)
            segs = self.plan.segments
            if (0 <= idx < len(segs) - 1 and not isinstance(segs[idx + 1].action, Prompt)
                    and self._bursts.ran_dry_after(idx, max(1, self._parts_done[idx]))):
                self._event("queue_underrun", f"device ran out of queued commands after segment {idx} "
                                              "before the plan ended", e.t_us)
        else:
            name = msg.EventKind(kind).name.lower() if kind in msg.EventKind._value2member_map_ else str(kind)
            self._event(name, f"{self._segment_named(e.segment)} code {e.code} value {e.value}", e.t_us)

    def _finish_before(self, idx: int, t_us: int) -> None:
        """The device runs segments in order: any earlier one still open is done by now
        (its SEGMENT_DONE was lost on the line)."""
        for j in range(self._oldest, idx):
            if not self._done[j] and not isinstance(self.plan.segments[j].action, Prompt):
                start = self._t_start[j]
                t = self._t(t_us)
                self._finish_segment(j, t if math.isnan(start) else float(start), t, True)

    def _finish_segment(self, idx: int, t_start: float, t_end: float, completed: bool) -> None:
        seg = self.plan.segments[idx]
        self._done[idx] = True
        self._segments_done += completed
        while self._oldest < len(self._done) and self._done[self._oldest]:
            self._oldest += 1
        params = seg.params()
        params.update(self._settle_outcome.pop(idx, {}))
        # consumers get the samples up to a segment end before the segment
        self._emit_later("on_segment", SegmentRecord(idx, seg.kind, t_start, t_end, params, seg.source,
                                                     seg.cycle, completed))

    def _close_open_segments(self) -> None:
        """Record the segment(s) cut short by an abort or failure as not completed."""
        for idx in range(self._oldest, min(self._next + 1, len(self._done))):  # + the one being sent (settle, track)
            if not self._done[idx] and not math.isnan(self._t_start[idx]):
                self._finish_segment(idx, float(self._t_start[idx]), self._t(self._now_us), False)

    def _flush_rows(self, limit: int | None = None) -> None:
        """Emit the pending samples (the first ``limit`` of them) as one block, then the
        documents that came after them and before the samples still pending."""
        n = len(self._rows) if limit is None else min(limit, len(self._rows))
        later = self._later
        k = 0
        while k < len(later) and later[k][0] <= n:
            k += 1
        docs = later[:k]
        self._later = [(at - n, name, doc) for at, name, doc in later[k:]]
        outside = None
        if n:
            rows, self._rows = self._rows[:n], self._rows[n:]
            self._last_block_wall = time.monotonic()
            try:
                block = sample_block(rows, self.bench, self.spt, self._t0_us or 0)
                outside = segments_outside_plan(block, len(self._done))
                if self._tracking is not None:
                    self._tracking.annotate(block)
                self._emit("on_samples", block)
            except BaseException:
                self._later[:0] = [(0, nm, d) for _, nm, d in docs]  # still emitted by the closing flush
                raise
        for i, (_, name, doc) in enumerate(docs):
            try:
                self._emit(name, doc)
            except BaseException:
                self._later[:0] = [(0, nm, d) for _, nm, d in docs[i + 1:]]  # still emitted by the closing flush
                raise
        if outside:
            raise RunFailed(f"host bug: {outside}")
