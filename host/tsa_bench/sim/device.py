"""The simulated bench device: the protocol's executable specification.

Units: virtual time in s (float) inside, reported on the wire as integer us since
boot; positions in microsteps; heater in mV; load in g (mg on the wire).

Contract: pure and deterministic for a given seed - no I/O, no wall clock. Bytes from
the host go in with :meth:`SimDevice.receive` and are handled at the current virtual
time; :meth:`SimDevice.advance` moves virtual time forward event by event (segment
ends, samples, the watchdog); device frames (with the device's own running seq)
accumulate for :meth:`SimDevice.take_output`. Protocol behaviour, as the firmware
implements it:

* HELLO answers IDENTITY and resets the duplicate filter; a protocol version or
  catalogue hash mismatch answers ACK ``bad_argument`` instead. Commands before HELLO
  are accepted.
* Every other command gets ACK(acked_seq, acked_id, status, queue_free) before any
  EVENT it causes; HEARTBEAT is also answered with QUEUE_STATUS. A frame repeating the
  seq and id of the last *accepted* command is not executed again: the stored ACK is
  re-sent (plus a fresh QUEUE_STATUS for HEARTBEAT). A refused command had no effect,
  so its repetition is simply evaluated again (a QUEUE_FULL retry can succeed).
* Queued commands are checked in this order: latched fault -> ``bad_state``; zero
  rate/accel or a sampling period in 1..999 us -> ``bad_argument``; rate, accel,
  heater, MOVE_TO target or MOVE_BY projected target beyond the limits ->
  ``limit_exceeded``; no free slot -> ``queue_full``.
* STOP halts the motor where it is, heater off, queue cleared (the running segment gets
  no SEGMENT_DONE), EVENT STOPPED. CLEAR_QUEUE drops waiting commands and clears a
  latched fault (EVENT FAULT_CLEARED, code = the fault). Watchdog: while
  :attr:`SimDevice.active`, ``watchdog_ms`` of virtual time without a valid host frame
  halts like STOP and latches fault WATCHDOG (EVENT FAULT).
* SAMPLE every sampling period on a grid anchored where SET_SAMPLING ran, first one
  period later; sampling survives STOP and faults. The resistance is there only when
  the CS5513 has a settled word in time (:class:`~tsa_bench.sim.sensors.ResistanceTiming`:
  not while the heater is on, not in the ~80 ms after the sense current comes on unless
  the period leaves time, not at periods shorter than a conversion); otherwise the
  sample keeps its slot and says resistance_not_measured.
* Every EVENT's ``value`` is the step position at that instant; ``code`` is the fault
  for FAULT and FAULT_CLEARED, else 0.
* Undecodable frames are dropped and counted (:attr:`frame_errors`); a valid frame
  with an id this device does not accept gets ``unknown_message``, a wrong payload
  length ``bad_length``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from tsa_bench.bench.config import BenchConfig
from tsa_bench.protocol import catalogue as msg
from tsa_bench.protocol.codec import encode
from tsa_bench.protocol.framing import FrameDecoder, RawFrame, encode_raw
from tsa_bench.sim.executor import NO_SEGMENT, QueuedCommand, SegmentExecutor
from tsa_bench.sim.identity import SIM_FIRMWARE_VERSION, DeviceLimits, device_limits, identity_message
from tsa_bench.sim.plant import Plant, plant_from_config
from tsa_bench.sim.sensors import ResistanceTiming, SimSensors

__all__ = ["SimDevice", "NO_SEGMENT", "MIN_SAMPLING_PERIOD_US"]

#: Shortest nonzero sampling period the device accepts (us).
MIN_SAMPLING_PERIOD_US = 1000

_S = msg.Status
_SAMPLE_SPEC = msg.MESSAGES[0x83]
_SAMPLE_PACK = _SAMPLE_SPEC.struct.pack
_NOT_MEASURED = int(msg.AdcFlags.RESISTANCE_NOT_MEASURED)
_QUEUED_TYPES = (msg.MoveTo, msg.MoveBy, msg.Dwell, msg.SetHeater, msg.SetSampling)


class SimDevice:
    """A simulated tsa-bench device (see module docstring)."""

    def __init__(self, bench: BenchConfig, plant: Plant | None = None, seed: int | None = None) -> None:
        self.bench = bench
        self.limits: DeviceLimits = device_limits(bench)
        self.identity = identity_message(self.limits)
        self.plant: Plant = plant if plant is not None else plant_from_config(bench.plant, seed)
        self.sensors = SimSensors(bench.position, bench.resistance)
        self.resistance_timing = ResistanceTiming()
        self._heater_seen = 0
        self.executor = SegmentExecutor(self.limits.queue_slots, self._emit_event, self._set_sampling)
        self.now_s = 0.0
        self.fault = 0
        self.duplicates = 0              # repeated commands answered from the filter
        self._watchdog_s = self.limits.watchdog_s
        self._turns_per_step = 1.0 / self.limits.steps_per_turn
        self._framer = FrameDecoder()
        self._out = bytearray()
        self._urgent = False             # output holds a non-SAMPLE frame
        self._urgent_sent = 0            # non-SAMPLE frames sent so far
        self._seq = 0
        self._held: list[NamedTuple] | None = None
        self._last_command: tuple[int, int, msg.Ack] | None = None
        self._last_host_s = 0.0
        self._period_us = 0
        self._anchor_us = 0
        self._k = 0
        self._next_sample_s = math.inf
        self._counter = 0

    # -- public -----------------------------------------------------------
    @property
    def frame_errors(self) -> dict[str, int]:
        """Dropped host frames by reason (cobs, crc, short, version, too_long)."""
        return self._framer.errors

    @property
    def active(self) -> bool:
        """Commands queued, a segment executing, or the heater on (the watchdog is armed)."""
        ex = self.executor
        return ex.executing or ex.queued > 0 or ex.heater_mV > 0

    @property
    def sampling_period_us(self) -> int:
        return self._period_us

    @property
    def has_urgent_output(self) -> bool:
        """The pending output holds something other than SAMPLE frames."""
        return self._urgent

    @property
    def pending_output_bytes(self) -> int:
        return len(self._out)

    def set_load_g(self, load_g: float) -> None:
        """Change the hanging load, as an operator would (same as SIM_SET_LOAD)."""
        self.plant.set_load(load_g)

    def boot(self) -> None:
        """Announce a reset: queue BOOT (reason EXTERNAL_RESET, the DTR pulse of opening the port)."""
        self._send(msg.Boot(*SIM_FIRMWARE_VERSION, int(msg.BootReason.EXTERNAL_RESET)))

    def receive(self, data: bytes) -> None:
        """Handle bytes from the host at the current virtual time; replies are queued."""
        for raw in self._framer.feed(data):
            self._last_host_s = self.now_s
            self._handle(raw)

    def take_output(self) -> bytes:
        """Everything sent since the last call."""
        out = bytes(self._out)
        self._out.clear()
        self._urgent = False
        return out

    def advance(self, max_dt_s: float, max_output_bytes: int) -> float:
        """Run virtual time forward event by event; return the time advanced (s).

        Stops once this call has produced a non-SAMPLE frame (ACK, EVENT, ...) or
        ``max_output_bytes`` bytes, or after ``max_dt_s``; when it stops early the time
        rests on the last event handled. Output already pending does not stop it.
        """
        start = self.now_s
        end = start + max(0.0, max_dt_s)
        ex = self.executor
        out = self._out
        limit = len(out) + max_output_bytes
        urgent_before = self._urgent_sent
        while self._urgent_sent == urgent_before and len(out) < limit:
            t_seg = ex.end_s
            t_smp = self._next_sample_s
            armed = ex.executing or ex.queued or ex.heater_mV
            t_wd = self._last_host_s + self._watchdog_s if armed else math.inf
            t = min(t_seg, t_smp, t_wd)
            if t > end or t == math.inf:
                if end != math.inf:
                    self.now_s = end
                break
            if t > self.now_s:
                self.now_s = t
            if t_seg <= t:
                ex.finish()
            elif t_wd <= t:
                self._trip(msg.Fault.WATCHDOG)
            else:
                self._take_sample()
        return self.now_s - start

    # -- output -----------------------------------------------------------
    def _t_us(self, t_s: float) -> int:
        return round(t_s * 1e6)

    def _send(self, message: NamedTuple) -> None:
        if self._held is not None:
            self._held.append(message)
            return
        self._out += encode(message, self._seq)
        self._seq = (self._seq + 1) & 0xFFFF
        self._urgent = True
        self._urgent_sent += 1

    def _emit_event(self, t_s: float, kind: int, segment: int, value: int, code: int = 0) -> None:
        self._send(msg.Event(self._t_us(t_s), kind, segment, code, value))

    def _take_sample(self) -> None:
        t = self.now_s
        ex = self.executor
        steps, moving = ex.position_at(t)
        heater_mV = ex.heater_mV
        reading = self.plant.sample(t, steps * self._turns_per_step, heater_mV * 1e-3, moving)
        position_raw, resistance_raw, flags = self.sensors.convert(
            reading.length_mm, reading.resistance_ohm, heater_mV)
        timing = self.resistance_timing
        if heater_mV > 0 or ex.heater_switch_ons != self._heater_seen:
            timing.sense_off()       # the heater came on since the last sample: current off
            self._heater_seen = ex.heater_switch_ons
        t_us = self._anchor_us + self._k * self._period_us
        if heater_mV == 0 and not timing.measured(t_us * 1e-6, self._period_us * 1e-6):
            resistance_raw, flags = 0, flags | _NOT_MEASURED
        payload = _SAMPLE_PACK(self._counter, t_us, steps, position_raw, resistance_raw, flags, heater_mV,
                               1 if moving else 0, ex.segment)
        self._out += encode_raw(0x83, self._seq, payload)
        self._seq = (self._seq + 1) & 0xFFFF
        self._counter = (self._counter + 1) & 0xFFFFFFFF
        self._k += 1
        self._next_sample_s = (t_us + self._period_us) * 1e-6

    def _set_sampling(self, period_us: int, t_s: float) -> None:
        if period_us == 0:
            self.resistance_timing.sense_off()
        self._period_us = period_us
        self._anchor_us = self._t_us(t_s)
        self._k = 1
        self._next_sample_s = (self._anchor_us + period_us) * 1e-6 if period_us else math.inf

    # -- input ------------------------------------------------------------
    def _handle(self, raw: RawFrame) -> None:
        spec = msg.MESSAGES.get(raw.msg_id)
        if spec is None or spec.direction != "host":
            self._answer(raw, _S.UNKNOWN_MESSAGE)
            return
        if len(raw.payload) != spec.struct.size:
            self._answer(raw, _S.BAD_LENGTH)
            return
        message = spec.cls._make(spec.struct.unpack(raw.payload))
        if type(message) is msg.Hello:
            self._hello(raw, message)
            return
        last = self._last_command
        if last is not None and last[0] == raw.seq and last[1] == raw.msg_id:
            self.duplicates += 1
            self._send(last[2])
            if type(message) is msg.Heartbeat:
                self._send(self._queue_status())
            return
        status = self._check(message)
        self._held = []
        try:
            if status == _S.OK:
                self._apply(message)
        finally:
            held, self._held = self._held, None
        self._answer(raw, status)
        for m in held:
            self._send(m)

    def _answer(self, raw: RawFrame, status: msg.Status) -> None:
        ack = msg.Ack(raw.seq, raw.msg_id, int(status), self.executor.queue_free)
        self._last_command = (raw.seq, raw.msg_id, ack) if status == _S.OK else None
        self._send(ack)

    def _hello(self, raw: RawFrame, hello: msg.Hello) -> None:
        if hello.protocol_version != msg.PROTOCOL_VERSION or hello.catalogue_hash != msg.CATALOGUE_HASH:
            ack = msg.Ack(raw.seq, raw.msg_id, int(_S.BAD_ARGUMENT), self.executor.queue_free)
            self._send(ack)
            return
        self._last_command = None
        self._send(self.identity)

    def _queue_status(self) -> msg.QueueStatus:
        ex = self.executor
        return msg.QueueStatus(self._t_us(self.now_s), ex.queue_free, int(ex.executing), ex.segment, self.fault)

    def _check(self, message: NamedTuple) -> msg.Status:
        if not isinstance(message, _QUEUED_TYPES):
            return _S.OK
        if self.fault:
            return _S.BAD_STATE
        lim = self.limits
        kind = type(message)
        if kind is msg.MoveTo or kind is msg.MoveBy:
            if message.rate_steps_per_s == 0 or message.accel_steps_per_s2 == 0:
                return _S.BAD_ARGUMENT
            if message.rate_steps_per_s > lim.max_rate_steps_per_s \
                    or message.accel_steps_per_s2 > lim.max_accel_steps_per_s2:
                return _S.LIMIT_EXCEEDED
            target = message.target_steps if kind is msg.MoveTo \
                else self.executor.projected_steps + message.delta_steps
            if not lim.min_twist_steps <= target <= lim.max_twist_steps:
                return _S.LIMIT_EXCEEDED
        elif kind is msg.SetHeater:
            if message.voltage_mV > lim.max_heater_mV:
                return _S.LIMIT_EXCEEDED
        elif kind is msg.SetSampling:
            if 0 < message.period_us < MIN_SAMPLING_PERIOD_US:
                return _S.BAD_ARGUMENT
        if self.executor.queue_free <= 0:
            return _S.QUEUE_FULL
        return _S.OK

    def _apply(self, message: NamedTuple) -> None:
        kind = type(message)
        if kind is msg.Heartbeat:
            self._send(self._queue_status())
        elif kind is msg.Stop:
            position = self.executor.halt(self.now_s)
            self._emit_event(self.now_s, int(msg.EventKind.STOPPED), self.executor.segment, position)
        elif kind is msg.ClearQueue:
            self.executor.clear_queue()
            if self.fault:
                code, self.fault = self.fault, 0
                position, _ = self.executor.position_at(self.now_s)
                self._emit_event(self.now_s, int(msg.EventKind.FAULT_CLEARED), self.executor.segment, position,
                                 code)
        elif kind is msg.SimSetLoad:
            self.plant.set_load(message.load_mg * 1e-3)
        else:
            command: QueuedCommand = message  # type: ignore[assignment]
            self.executor.push(command, self.now_s)

    def inject_fault(self, fault: msg.Fault) -> None:
        """Latch ``fault`` now, exactly as a detected hardware fault would (motor halted,
        heater off, queue cleared, EVENT fault): for testing how hosts handle faults."""
        self._trip(fault)

    def _trip(self, fault: msg.Fault) -> None:
        position = self.executor.halt(self.now_s)
        self.fault = int(fault)
        self._emit_event(self.now_s, int(msg.EventKind.FAULT), self.executor.segment, position, int(fault))
