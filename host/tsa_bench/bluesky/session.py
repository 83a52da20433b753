"""One open rig, driven from one worker thread: what the ophyd-async device awaits.

Units: twist in turns, rates in turns/s and turns/s^2, heater in V, load in g (hanging
mass), lengths in mm, resistance in ohm, times in s of device time since the session
opened (``t_s``) unless a name says ``wall``.

Contract: :class:`RigSession` owns a :class:`~tsa_bench.rig.link.RigLink` (the device
client and protocol of every other command: no second wire implementation) and touches
it only from its own worker thread, one job at a time, in the order submitted
(:meth:`RigSession.submit` returns a :class:`concurrent.futures.Future`). Between jobs,
on a port with a device in another process (a serial line, ``sim-serve`` or the native
firmware behind a pty) the worker reads and heartbeats every 1/16 of the device's
watchdog, so the device never falls silent between the steps of a plan; a ``sim://``
device in this process runs only while it is read, so it is left alone (its virtual
time does not run on while a plan thinks, and a scan made step by step sees the
device exactly as a protocol queued at once does).

Each job sends its commands queued, under a segment number of its own, and returns
once the device says that segment is done (its SEGMENT_DONE, or an idle device with
an empty queue that last ran it): a move has ended, a heater change is applied, an
acquisition window has passed. :meth:`RigSession.request_stop` may be called from any
thread: the job under way and any waiting job end with :class:`RigStopped`, and the
worker sends STOP (motor halted, heater off, queue cleared) before anything else. A
latched device fault ends the job with :class:`RigFault`; a refused command with
:class:`~tsa_bench.device.CommandRefused`-like :class:`RigRefused` naming the reason.
Host-side limits are checked before a command is sent (:meth:`RigSession.check_twist`,
:meth:`RigSession.check_heater`); the device checks its own again.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any, NamedTuple

from tsa_bench.benchdata import BenchConfig
from tsa_bench.device import DeviceError
from tsa_bench.motion.trapezoid import TrapezoidProfile
from tsa_bench.protocol import msg
from tsa_bench.rig.link import RigError, RigLink, open_link
from tsa_bench.plan import Plan
from tsa_bench.rundocs import RunStop, SampleBlock
from tsa_bench.runner.commands import NO_SEGMENT, WIRE_SEGMENTS, load_mg
from tsa_bench.runner.engine import Runner
from tsa_bench.runner.samples import length_mm, resistance_ohm
from tsa_bench.units import G_N_PER_G

#: Default sampling period while staged (s) and acquisition window (s): five samples a window.
DEFAULT_PERIOD_S = 0.1
DEFAULT_WINDOW_S = 0.5
#: Wall-time margin (s) added to every wait for the device, over what the command should take.
WAIT_MARGIN_S = 10.0


class RigStopped(RuntimeError):
    """A stop was requested (RunEngine abort, pause or stop): STOP was sent, heater off."""


class RigFault(RuntimeError):
    """The device latched a fault (watchdog, twist or heater limit, sensor); it stopped."""


class RigRefused(RuntimeError):
    """The device or the bench's limits refused a command; the message says which and why."""


class PositionUnknown(RuntimeError):
    """The device does not know the motor's twist; nothing moved. The message says how to declare it."""


@dataclass(frozen=True)
class Acquisition:
    """The samples of one acquisition window, reduced to one reading per quantity.

    ``length_mm`` and ``resistance_ohm`` are means over the window's samples that hold a
    value (NaN when none does: the heater was on, the sense current settling, the position
    read failed); ``turns``, ``step_position`` and ``t_s`` are those of the window's last
    sample; ``heater_V`` is the mean applied voltage; ``load_g`` the declared load (NaN:
    none declared). ``wall_time`` is the POSIX time the window was read (the Bluesky
    reading timestamp)."""

    t_s: float
    samples: int
    length_mm: float
    resistance_ohm: float
    turns: float
    step_position: int
    heater_V: float
    load_g: float
    wall_time: float


class _LoadTracker:
    """A run consumer remembering the load (N) of the last sample."""

    load_N = math.nan

    def on_start(self, start: Any) -> None: ...
    def on_segment(self, segment: Any) -> None: ...
    def on_event(self, event: Any) -> None: ...
    def on_stop(self, stop: Any) -> None: ...

    def on_samples(self, block: SampleBlock) -> None:
        if len(block):
            self.load_N = float(block.columns["load"][-1])


def _mean(values: list[float]) -> float:
    finite = [v for v in values if v == v]
    return math.fsum(finite) / len(finite) if finite else math.nan


class RigSession:
    """One rig on one port, driven from a worker thread (see the module contract).

    ``port``: a serial device path, ``sim://...`` or any URL the port policy lets through;
    ``bench``: the bench file read and checked (its limits, calibration, timeouts)."""

    def __init__(self, port: str, bench: BenchConfig, *, boot_timeout_s: float | None = None,
                 label: str | None = None) -> None:
        self.port = port
        self.label = label or port     # the port as the user gave it, for messages
        self.bench = bench
        self.boot_timeout_s = boot_timeout_s
        self.link: RigLink | None = None
        self.sampling_period_s = 0.0         # 0: sampling off
        self.load_g = math.nan               # declared hanging mass; NaN: not declared
        self.heater_V = 0.0                  # last heater voltage the device applied
        self.position_steps = 0              # last step position the device reported
        self.stopped = False                 # a STOP went out since the last move began
        self._jobs: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._stack = ExitStack()
        self._wire = -1
        self._awaited: int | None = None      # the segment a job waits for
        self._done: set[int] = set()
        self._window: list[msg.Sample] | None = None
        self._interrupts: Any = None          # the running protocol's (request() stops it)
        self._position_checked = False        # ensure_position found the twist zero known
        self._keep_alive = False
        self._thread = threading.Thread(target=self._work, name=f"tsa-bench rig {port}", daemon=True)
        self._thread.start()

    # -- the worker ----------------------------------------------------------
    def submit(self, fn: Callable[..., Any], *args: Any) -> Future:
        """Run ``fn(*args)`` on the worker thread after the jobs before it; its Future."""
        fut: Future = Future()
        if not self._thread.is_alive():
            fut.set_exception(RigError(f"the session on {self.label} is closed"))
            return fut
        self._jobs.put((fut, fn, args))
        return fut

    def _work(self) -> None:
        while True:
            try:
                job = self._jobs.get(timeout=self._beat_s() if self._keep_alive else None)
            except queue.Empty:
                self._idle_pump()
                continue
            if job is None:
                return
            fut, fn, args = job
            if not fut.set_running_or_notify_cancel():
                continue
            try:
                fut.set_result(fn(*args))
            except BaseException as exc:  # handed to whoever awaits the job
                fut.set_exception(exc)

    def _beat_s(self) -> float:
        link = self.link
        return 0.5 if link is None else max(0.05, link.identity.watchdog_ms / 16000.0)

    def _idle_pump(self) -> None:
        link = self.link
        if link is None:
            return
        try:
            link.pump()
        except (DeviceError, RigError):
            self._keep_alive = False   # the port failed: the next job says so

    # -- opening and closing -------------------------------------------------
    def open(self) -> msg.Identity:
        """(Worker) open the port and handshake; RigError saying why when it cannot."""
        link = self._stack.enter_context(open_link(self.port, self.bench, boot_timeout_s=self.boot_timeout_s))
        link.on_message = self._on_message
        self.link = link
        self.position_steps = link.last_status.step_position if link.last_status else 0
        self._keep_alive = link.client.device_now_us is None   # a device in another process
        return link.identity

    def close(self) -> None:
        """(Any thread) STOP, sampling off, the next reset armed, port closed; the worker ends."""
        if threading.current_thread() is self._thread:
            raise RuntimeError("close() is called from outside the session's worker")
        if self._thread.is_alive():
            self.submit(self._close).result(timeout=WAIT_MARGIN_S + 5)
            self._jobs.put(None)
            self._thread.join(WAIT_MARGIN_S)

    def _close(self) -> None:
        self._keep_alive = False
        self.link = None
        self._stack.close()   # RigLink.close: STOP, sampling off, ARM_RESET; then the port

    @property
    def open_link(self) -> RigLink:
        if self.link is None:
            raise RigError(f"the rig on {self.label} is not connected (connect it first: "
                           "`with init_devices(): rig = TsaRig(...)`, or `await rig.connect()`)")
        return self.link

    # -- what arrives ----------------------------------------------------------
    def _on_message(self, m: NamedTuple) -> None:
        kind = type(m)
        if kind is msg.Sample:
            self.position_steps = m.step_position
            self.heater_V = m.heater_mV / 1000.0
            if self._window is not None and m.segment == self._awaited:
                self._window.append(m)
        elif kind is msg.Event:
            if m.kind in (msg.EventKind.SEGMENT_DONE, msg.EventKind.STOPPED, msg.EventKind.FAULT):
                self.position_steps = m.value
            if m.kind == msg.EventKind.SEGMENT_DONE:
                self._done.add(m.segment)
        elif kind is msg.QueueStatus:
            self.position_steps = m.step_position
            link = self.link
            if (link is not None and not m.executing and m.queue_free == link.identity.queue_slots
                    and m.segment == self._awaited):
                self._done.add(m.segment)   # idle after it: done, even if its SEGMENT_DONE was lost

    # -- stopping --------------------------------------------------------------
    def request_stop(self) -> Future:
        """(Any thread) End the job under way and those waiting with :class:`RigStopped`;
        the worker sends STOP (motor halted, heater off, queue cleared). The Future is
        done once STOP went out."""
        self._stop.set()
        running = self._interrupts
        if running is not None:
            running.request()      # the protocol's runner STOPs at its next safe point
        return self.submit(self._send_stop)

    def _send_stop(self) -> None:
        link = self.link
        if link is not None:
            link.stop()
            self.stopped = True
            self.heater_V = 0.0
        self._stop.clear()

    def _check_stop(self) -> None:
        if self._stop.is_set():
            raise RigStopped("stopped on request")

    def _guarded(self, what: str, body: Callable[[], Any]) -> Any:
        """Run ``body`` with the stop request watched while it waits; on a stop, STOP first."""
        link = self.open_link
        link.client.on_wait = self._check_stop
        try:
            self._check_stop()
            return body()
        except RigStopped:
            link.client.on_wait = None   # the STOP's own ACK wait must not be broken by the request
            link.stop()
            self.stopped = True
            self.heater_V = 0.0
            raise RigStopped(f"{what} stopped on request: STOP sent (motor halted, heater off)") from None
        except DeviceError as exc:
            raise RigError(f"{what}: {exc}") from None
        finally:
            link.client.on_wait = None
            self._awaited = None
            self._window = None

    # -- commands (worker) -----------------------------------------------------
    def _next_wire(self) -> int:
        self._wire = (self._wire + 1) % WIRE_SEGMENTS     # never NO_SEGMENT (0xFFFF)
        return self._wire

    def _queue(self, message: NamedTuple, what: str) -> None:
        """Queue one command; RigRefused when the device refuses it (its reason)."""
        try:
            self.open_link.queued(message, what)
        except RigError as exc:
            raise RigRefused(str(exc)) from None

    def _run(self, make: Callable[[int], NamedTuple], what: str, expected_s: float) -> None:
        """Queue the command ``make(segment)`` and wait until the device has done it."""
        link = self.open_link
        wire = self._next_wire()
        self._done.discard(wire)
        self._awaited = wire
        self._queue(make(wire), what)
        deadline = time.monotonic() + expected_s * 2 + WAIT_MARGIN_S
        while wire not in self._done:
            link.pump()
            self._check_stop()
            if link.fault:
                raise RigFault(f"{what}: device fault {msg.Fault(link.fault).name.lower()} "
                               "(the device stopped the motor and the heater)")
            if time.monotonic() > deadline:
                raise RigError(f"{what}: the device on {self.label} did not finish within "
                               f"{expected_s * 2 + WAIT_MARGIN_S:g} s")

    def check_twist(self, turns: float, rate: float, accel: float) -> None:
        """RigRefused when the move breaks the bench's (or the device's) limits."""
        lim, ident, spt = self.bench.limits, self.open_link.identity, self.open_link.steps_per_turn
        if not math.isfinite(turns):
            raise RigRefused(f"twist {turns!r}: not a finite number of turns")
        lo = max(ident.min_twist_steps / spt, lim.min_twist_turns if lim.min_twist_turns is not None else -math.inf)
        hi = min(ident.max_twist_steps / spt, lim.max_twist_turns if lim.max_twist_turns is not None else math.inf)
        if not lo <= turns <= hi:
            raise RigRefused(f"twist {turns:g} turns is outside the limits {lo:g}..{hi:g} turns "
                             f"({self.bench.path or 'the bench file'} and the device); nothing moved")
        max_rate = min(ident.max_rate_steps_per_s / spt, lim.max_rate_turns_per_s or math.inf)
        max_accel = min(ident.max_accel_steps_per_s2 / spt, lim.max_accel_turns_per_s2 or math.inf)
        if not 0 < rate <= max_rate:
            raise RigRefused(f"twist rate {rate:g} turns/s is outside 0..{max_rate:g} turns/s; nothing moved")
        if not 0 < accel <= max_accel:
            raise RigRefused(f"twist acceleration {accel:g} turns/s^2 is outside 0..{max_accel:g} turns/s^2; "
                             "nothing moved")

    def check_heater(self, volts: float) -> None:
        """RigRefused when the voltage breaks the bench's heater limit (or is negative)."""
        top = self.bench.limits.max_heater_voltage_V
        if not (math.isfinite(volts) and volts >= 0):
            raise RigRefused(f"heater {volts!r} V: give a voltage >= 0")
        if top is not None and volts > top:
            raise RigRefused(f"heater {volts:g} V is above the bench's limit of {top:g} V "
                             f"({self.bench.path or 'the bench file'}); the heater was not switched")

    def move(self, turns: float, rate: float, accel: float) -> float:
        """(Worker) twist to ``turns`` and wait for the move to end; the twist reached (turns)."""
        def body() -> float:
            self.check_twist(turns, rate, accel)
            if not self._position_checked:
                self.ensure_position()
            spt = self.open_link.steps_per_turn
            self.stopped = False
            distance = turns - self.position_steps / spt
            expected = TrapezoidProfile(distance, rate, accel).duration if distance else 0.0
            self._run(lambda wire: msg.MoveTo(wire, round(turns * spt), max(1, round(rate * spt)),
                                              max(1, round(accel * spt))), f"the move to {turns:g} turns", expected)
            return self.position_steps / spt
        return self._guarded(f"the move to {turns:g} turns", body)

    def heat(self, volts: float) -> float:
        """(Worker) set the heater to ``volts`` and wait until the device applies it; the voltage set."""
        def body() -> float:
            self.check_heater(volts)
            self._run(lambda wire: msg.SetHeater(wire, round(volts * 1000)), f"heater {volts:g} V", 0.0)
            self.heater_V = volts
            return volts
        return self._guarded(f"heater {volts:g} V", body)

    def set_sampling(self, period_s: float) -> None:
        """(Worker) sample every ``period_s`` (0: off); the device refuses a period its
        sensors or line cannot keep (RigRefused with its reason)."""
        return self._guarded("the sampling period", lambda: self._sampling(period_s))

    def _sampling(self, period_s: float) -> None:
        self._queue(msg.SetSampling(NO_SEGMENT, round(period_s * 1e6)), f"sampling every {period_s:g} s")
        self.sampling_period_s = period_s

    def declare_load(self, load_g: float) -> None:
        """(Worker) the hanging mass now (g); a simulated device hangs it on its plant."""
        link = self.open_link
        if load_g == load_g and link.simulated:
            ack = link.client.command(msg.SimSetLoad(load_mg(load_g)), check=False)
            if ack.status != msg.Status.OK:
                raise RigRefused(f"the simulated device refused load {load_g:g} g: "
                                 f"{msg.Status(ack.status).name.lower()}")
        self.load_g = load_g

    def acquire(self, window_s: float) -> Acquisition:
        """(Worker) the samples of the next ``window_s`` of device time (a DWELL of that
        length), reduced (:class:`Acquisition`). With sampling off it is switched on at
        :data:`DEFAULT_PERIOD_S` for the window and off again."""
        def body() -> Acquisition:
            temporary = self.sampling_period_s == 0
            if temporary:
                self._sampling(min(DEFAULT_PERIOD_S, window_s / 2))
            try:
                self._window = []
                self._run(lambda wire: msg.Dwell(wire, max(1, round(window_s * 1e6))),
                          f"the {window_s:g} s acquisition", window_s)
                samples, self._window = self._window, None
            finally:
                if temporary:
                    self._sampling(0.0)
            if not samples:
                raise RigError(f"no samples arrived in the {window_s:g} s acquisition window (sampling every "
                               f"{self.sampling_period_s or DEFAULT_PERIOD_S:g} s): make the window longer than "
                               "one sampling period")
            return self._reduce(samples)
        return self._guarded("the acquisition", body)

    def _reduce(self, samples: list[msg.Sample]) -> Acquisition:
        link, bench = self.open_link, self.bench
        last = samples[-1]
        return Acquisition(
            t_s=link.t_s(last.t_us), samples=len(samples),
            length_mm=_mean([length_mm(bench, s.position_raw, s.adc_flags) for s in samples]),
            resistance_ohm=_mean([resistance_ohm(bench, s.resistance_raw, s.adc_flags) for s in samples]),
            turns=last.step_position / link.steps_per_turn, step_position=last.step_position,
            heater_V=_mean([s.heater_mV / 1000.0 for s in samples]), load_g=self.load_g, wall_time=time.time())

    # -- a whole protocol --------------------------------------------------------
    def run_protocol(self, plan: Plan, consumers: list, operator: Any, interrupts: Any,
                     metadata: dict, final_load_g: float) -> RunStop:
        """(Worker) run a compiled protocol with the project's :class:`~tsa_bench.runner.Runner`
        on this session's client; its documents go to ``consumers``; ``interrupts.request()``
        (:meth:`request_stop` calls it) stops it at a safe point. Afterwards the sampling the
        rig had is restored; the declared load is the protocol's last."""
        link = self.open_link
        self.ensure_position()
        tracker = _LoadTracker()
        self._interrupts = interrupts
        try:
            self._check_stop()
            runner = Runner(link.client, plan, self.bench, [*consumers, tracker], operator,
                            backend="sim" if link.simulated else "serial", port_name=self.label,
                            interrupts=interrupts, metadata=metadata)
            stop = runner.run()
        finally:
            self._interrupts = None
            link.client.on_wait = None
        self.heater_V = 0.0     # the runner's teardown (or its STOP) switched the heater off
        self.load_g = tracker.load_N / G_N_PER_G if tracker.load_N == tracker.load_N else final_load_g
        try:
            link.status()
            if self.sampling_period_s:
                self._sampling(self.sampling_period_s)
        except (DeviceError, RigError, RigRefused):
            pass   # the next job says what is wrong
        return stop

    # -- position --------------------------------------------------------------
    def ensure_position(self) -> str | None:
        """(Worker) make sure the device knows its twist. A simulated device that does not
        is told 0 (its plant starts untwisted; the note returned says so); a real one
        raises :class:`PositionUnknown`: nothing asks on a terminal. None: it was known."""
        link = self.open_link
        status = link.status()
        self.position_steps = status.step_position
        if status.fault:
            raise RigFault(f"the device on {self.label} has a fault latched "
                           f"({msg.Fault(status.fault).name.lower()}): see what tripped it, then clear it "
                           "(rig.clear_fault() or `tsa-bench zero`); nothing moved")
        if not status.state & msg.DeviceState.POSITION_UNKNOWN:
            self._position_checked = True
            return None
        if not link.simulated:
            raise PositionUnknown(
                f"the device on {self.label} does not know the motor's twist (it powered up, reset while moving, "
                "or released the motor). Hang the TSA untwisted and declare the zero from Python with "
                "`rig.declare_twist(0)` (or `tsa-bench zero`), or `rig.declare_twist(N)` when you know it "
                "holds N turns; then stage again. Nothing moved.")
        self.declare_twist(0.0)
        self._position_checked = True
        return "the simulated device did not know its position: its untwisted start is the twist zero"

    def declare_twist(self, turns: float) -> None:
        """(Worker) SET_POSITION: the motor is at ``turns`` now (the operator's word)."""
        try:
            steps = self.open_link.set_position(turns)
        except RigError as exc:
            raise RigRefused(str(exc)) from None
        self.position_steps = steps

    def clear_fault(self) -> None:
        """(Worker) CLEAR_QUEUE: drop waiting commands and clear a latched fault."""
        link = self.open_link
        link.client.command(msg.ClearQueue(), check=False)
        link.fault = 0
        link.status()
