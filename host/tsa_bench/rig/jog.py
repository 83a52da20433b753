"""`tsa-bench jog`: move the motor and switch the heater by hand, every step recorded.

Units: twist in turns, rates in turns/s and turns/s^2, voltage in V, time in s of
device time.

Contract: a :class:`JogSession` runs :class:`JogCommand` s one at a time on a
connected :class:`~tsa_bench.rig.link.RigLink` and records the session as a run file
(plan name "jog"): every sample, each command as a segment (``move``, ``heater``,
``hold`` for a wait; index = command number, source ``jog:N``) and events (STOP,
heater interlock). A move runs to its end unless ``stop_requested`` says otherwise
(a key pressed): then STOP at once (motor halted, heater off). Heater interlock: a
voltage above the bench limit is refused; the heater is switched on only while the
motor is at rest and goes off on STOP, on quit, on any error and after
``heater_timeout_s`` of device time (the device's watchdog and duty limit stay in
force). :func:`parse_command` reads the script form (one command per line), which
is also what the interactive keys are turned into::

    +2 | -0.5          twist by that many turns      to 10     twist to 10 turns
    rate 2             set the rate (turns/s)         heater 3  heater on at 3 V
    heater off         heater off                     wait 5    hold 5 s, sampling
    stop               STOP                           quit      end the session
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tsa_bench.protocol import msg
from tsa_bench.rig.link import RigError, RigLink
from tsa_bench.runner.commands import WIRE_SEGMENTS
from tsa_bench.rundocs import EventRecord, RunStart, RunStop, SegmentRecord
from tsa_bench.runner.samples import row, sample_block

KINDS = ("move_by", "move_to", "rate", "heater", "wait", "stop", "quit")


class JogError(ValueError):
    """A command that cannot be run as written; the message says why."""


@dataclass(frozen=True)
class JogCommand:
    kind: str
    value: float | None = None


def parse_command(line: str) -> JogCommand | None:
    """One script line -> a command (None for a blank or comment line); JogError if malformed."""
    text = line.split("#", 1)[0].strip().lower()
    if not text:
        return None
    words = text.split()
    head = words[0]
    try:
        if head[0] in "+-" and len(words) == 1:
            return JogCommand("move_by", float(head))
        if head in ("to", "move_to") and len(words) == 2:
            return JogCommand("move_to", float(words[1]))
        if head in ("by", "move_by") and len(words) == 2:
            return JogCommand("move_by", float(words[1]))
        if head == "rate" and len(words) == 2:
            return JogCommand("rate", float(words[1]))
        if head == "heater" and len(words) == 2:
            return JogCommand("heater", 0.0 if words[1] in ("off", "0") else float(words[1].rstrip("v")))
        if head == "wait" and len(words) == 2:
            return JogCommand("wait", float(words[1].rstrip("s")))
        if head in ("stop", "quit", "q", "exit") and len(words) == 1:
            return JogCommand("stop" if head == "stop" else "quit")
    except ValueError:
        pass
    raise JogError(f"{line.strip()!r} is not a jog command (+N, -N, to N, rate N, heater V|off, wait S, stop, quit)")


class JogSession:
    """A recorded jog session (module contract)."""

    def __init__(self, link: RigLink, consumers: list, *, rate_turns_per_s: float = 1.0,
                 accel_turns_per_s2: float = 10.0, heater_timeout_s: float = 30.0, period_s: float = 0.1,
                 backend: str = "serial", say: Callable[[str], None] = print) -> None:
        self.link, self.consumers = link, consumers
        self.bench = link.bench
        self.rate, self.accel = rate_turns_per_s, accel_turns_per_s2
        self.heater_timeout_s = heater_timeout_s
        self.period_s = period_s
        self.backend = backend
        self.say = say
        self.index = 0
        self.heater_V = 0.0
        self._heater_on_t: float | None = None
        self._rows: list[tuple] = []
        self._last: msg.Sample | None = None
        self.target_turns = 0.0
        self.samples = 0
        link.on_message = self._on_message

    # -- recording ---------------------------------------------------------
    def _emit(self, name: str, doc) -> None:
        for c in self.consumers:
            getattr(c, name)(doc)

    def _on_message(self, m) -> None:
        if isinstance(m, msg.Sample):
            self._last = m
            seg = m.segment if m.segment < WIRE_SEGMENTS else -1
            self._rows.append(row(m, seg, float("nan")))
            self.samples += 1
            if len(self._rows) >= 256:
                self.flush()
        elif isinstance(m, msg.Event) and m.kind in (msg.EventKind.FAULT, msg.EventKind.STOPPED,
                                                     msg.EventKind.LIMIT_HIT):
            self.event(msg.EventKind(m.kind).name.lower(), f"code {m.code}, position {m.value} steps")

    def now(self) -> float:
        return self.link.t_s(self.link.now_us)

    def event(self, kind: str, detail: str) -> None:
        self._emit("on_event", EventRecord(self.now(), kind, detail))

    def flush(self) -> None:
        if self._rows:
            rows, self._rows = self._rows, []
            self._emit("on_samples", sample_block(rows, self.bench, self.link.steps_per_turn, self.link.t0_us or 0))

    def start(self) -> None:
        ident = self.link.identity
        self._emit("on_start", RunStart(
            plan_name="jog", protocol_text="# tsa-bench jog: a hand-driven session; each command is a segment\n",
            protocol_path=None, bench_text=self.bench.source_text, bench_path=self.bench.path, backend=self.backend,
            port=self.link.port_name, firmware=f"{ident.fw_major}.{ident.fw_minor}.{ident.fw_patch}",
            identity=ident._asdict(), n_segments=0, estimated_duration_s=0.0, metadata={"session": "jog"}))
        self.link.set_sampling(self.period_s)
        self.link.samples(2 * self.period_s)      # where the motor is: from the first samples
        self.target_turns = self._position_now()

    def finish(self, status: str, reason: str) -> RunStop:
        self.heater_off("session ended")
        self.link.stop()
        for _ in range(3):
            self.link.pump()
        self.flush()
        stop = RunStop(status, reason, self.now(), self.samples, 0, self.index, 0.0)
        for c in self.consumers:
            try:
                c.on_stop(stop)
            except Exception:
                pass
        return stop

    def _segment(self, kind: str, t0: float, params: dict, completed: bool = True) -> None:
        self.flush()
        self._emit("on_segment", SegmentRecord(self.index, kind, t0, self.now(), params, f"jog:{self.index + 1}",
                                               None, completed))
        self.index += 1

    # -- state shown to the operator -------------------------------------------
    def state(self) -> str:
        s = self._last
        if s is None:
            return "no sample yet"
        turns = s.step_position / self.link.steps_per_turn
        length = "n/a" if s.adc_flags & msg.AdcFlags.POSITION_INVALID else \
            f"{self.bench.position.length_mm(s.position_raw):.2f} mm"
        if s.adc_flags & msg.AdcFlags.RESISTANCE_NOT_MEASURED:
            resistance = "not measured (heater on)" if s.heater_mV else "not measured"
        else:
            resistance = f"{self.bench.resistance.resistance_ohm(s.resistance_raw):.4f} ohm"
        return (f"twist {turns:.3f} turns  length {length}  resistance {resistance}  heater {s.heater_mV / 1000:g} V"
                f"  rate {self.rate:g} turns/s")

    # -- commands --------------------------------------------------------------
    def heater_off(self, why: str) -> None:
        if self.heater_V > 0:
            try:
                self.link.set_heater(0.0)
            except RigError:
                self.link.stop()
            self.heater_V = 0.0
            self._heater_on_t = None
            self.event("heater_off", why)

    def idle(self) -> None:
        """Keep the link fed between commands; the heater interlock's time-out."""
        self.link.pump()
        if self._heater_on_t is not None and self.now() - self._heater_on_t >= self.heater_timeout_s:
            self.heater_off(f"interlock: on for {self.heater_timeout_s:g} s")
            self.say(f"heater off (on for {self.heater_timeout_s:g} s, the interlock's limit)")

    def execute(self, cmd: JogCommand, stop_requested: Callable[[], bool] = lambda: False) -> bool:
        """Run one command; False once the session should end (quit)."""
        if cmd.kind == "quit":
            return False
        if cmd.kind == "stop":
            self.link.stop()
            self.heater_V, self._heater_on_t = 0.0, None
            self.event("stop", "STOP by the operator: motor halted, heater off")
            return True
        if cmd.kind == "rate":
            limit = self.bench.limits.max_rate_turns_per_s
            if cmd.value is None or not cmd.value > 0 or (limit is not None and cmd.value > limit):
                raise JogError(f"rate must be > 0 and at most {limit:g} turns/s (bench limit)")
            self.rate = cmd.value
            return True
        if cmd.kind == "heater":
            return self._heater(cmd.value or 0.0)
        if cmd.kind == "wait":
            return self._wait(cmd.value or 0.0, stop_requested)
        target = cmd.value + self.target_turns if cmd.kind == "move_by" else cmd.value
        return self._move(float(target), stop_requested)

    def _heater(self, voltage: float) -> bool:
        limit = self.bench.limits.max_heater_voltage_V
        if voltage < 0 or (limit is not None and voltage > limit):
            raise JogError(f"heater {voltage:g} V is outside 0..{limit:g} V (bench limit)")
        t0 = self.now()
        self.link.set_heater(voltage, self.index % WIRE_SEGMENTS)
        self.heater_V = voltage
        self._heater_on_t = t0 if voltage > 0 else None
        self.link.samples(self.period_s)   # the state shown next is after the change
        self._segment("heater", t0, {"voltage_V": voltage})
        return True

    def _move(self, target: float, stop_requested: Callable[[], bool]) -> bool:
        lim = self.bench.limits
        if (lim.max_twist_turns is not None and target > lim.max_twist_turns) or \
                (lim.min_twist_turns is not None and target < lim.min_twist_turns):
            raise JogError(f"{target:g} turns is outside the bench's twist limits "
                           f"{lim.min_twist_turns:g}..{lim.max_twist_turns:g} turns")
        self.heater_off("interlock: the heater is off while the motor moves")
        t0 = self.now()
        self.link.move_to(target, self.rate, self.accel, self.index % WIRE_SEGMENTS)
        done = self.link.wait_idle(3600.0, stop_requested)
        if not done:
            self.link.stop()
            self.event("stop", "STOP by the operator during a move: motor halted")
        self.link.samples(self.period_s)
        self.target_turns = target if done else self._position_now()
        self._segment("move", t0, {"target_turns": target, "rate_turns_per_s": self.rate,
                                   "accel_turns_per_s2": self.accel}, completed=done)
        return True

    def _position_now(self) -> float:
        for _ in range(3):
            self.link.pump()
        s = self._last
        return s.step_position / self.link.steps_per_turn if s is not None else self.target_turns

    def _wait(self, seconds: float, stop_requested: Callable[[], bool]) -> bool:
        if not 0 < seconds <= 86400:
            raise JogError("wait must be 0..86400 s")
        t0 = self.now()
        completed = True
        while self.now() - t0 < seconds:
            self.idle()
            if stop_requested():
                completed = False
                break
        self._segment("hold", t0, {"duration_s": float(np.round(self.now() - t0, 6))}, completed)
        return True
