"""The simulated bench device: the protocol's executable specification.

Units: virtual time in s (float) inside, reported on the wire as integer us since
boot; positions in microsteps; heater in mV; load in g (mg on the wire).

Contract: pure and deterministic for a given seed - no I/O, no wall clock. Bytes from
the host go in with :meth:`SimDevice.receive` and are handled at the current virtual
time; :meth:`SimDevice.advance` moves virtual time forward event by event (segment
ends, samples, the watchdog); device frames (with the device's own running seq)
accumulate for :meth:`SimDevice.take_output`. A device made with ``frames=True`` keeps
them as decoded :class:`~tsa_bench.protocol.Frame` objects instead (for an in-process
host: no framing, CRC or decoding on either side; :meth:`take_frames` gives them with
their size on the wire, :meth:`receive_frame` takes a host message), with exactly the
same sequence of frames, sizes and timing; ``take_output`` still gives the bytes. Protocol behaviour, as the firmware
implements it:

* HELLO answers IDENTITY and resets the duplicate filter; a protocol version or
  catalogue hash mismatch answers ACK ``bad_argument`` instead. Commands before HELLO
  are accepted.
* It boots as from power-on (BOOT reason power_on) with its step position unknown
  (QUEUE_STATUS.state position_unknown): MOVE_TO/MOVE_BY are refused ``bad_state`` until
  SET_POSITION declares the position (refused ``bad_state`` while a move runs, waits or
  the motor is stopping or released, ``limit_exceeded`` outside the twist limits).
  ARM_RESET is accepted at rest with the position known (``bad_state`` otherwise, as the
  firmware); a simulated device never resets, so it changes nothing else.
* Every other command gets ACK(acked_seq, acked_id, status, queue_free) before any
  EVENT it causes; HEARTBEAT is also answered with QUEUE_STATUS. A frame repeating the
  seq and id of the last *accepted* command is not executed again: the stored ACK is
  re-sent (plus a fresh QUEUE_STATUS for HEARTBEAT). A refused command had no effect,
  so its repetition is simply evaluated again (a QUEUE_FULL retry can succeed).
* Queued commands are checked in this order: latched fault or (moves) position
  unknown -> ``bad_state``; zero rate/accel -> ``bad_argument``; a sampling period
  shorter than an ADS1115 conversion -> ``too_fast_for_sensor``, below the single-shot
  minimum not a whole number of conversions -> ``between_conversions``, or whose sample
  frames the line (the bench's baud) cannot carry -> ``too_fast_for_line``
  (:func:`tsa_bench.protocol.blocks.sampling_refusal`); rate, accel,
  heater, MOVE_TO target or MOVE_BY projected target beyond the limits ->
  ``limit_exceeded``; no free slot -> ``queue_full``.
* STOP: heater off, queue cleared (the running segment gets no SEGMENT_DONE), and the
  motor decelerates at ``max_accel_steps_per_s2`` from its present speed (or finishes
  the move when that comes sooner); EVENT STOPPED at once, its value the position the
  motor comes to rest at; commands queued meanwhile start when it is at rest.
  CLEAR_QUEUE drops waiting commands and clears a latched fault (EVENT FAULT_CLEARED,
  code = the fault), re-energizing a released motor. Watchdog: while
  :attr:`SimDevice.watchdog_armed` (a segment executing or queued, the heater on, a stop
  under way, or sampling on), ``watchdog_ms`` of virtual time without a valid host frame stops
  like STOP and latches fault WATCHDOG (EVENT FAULT, value = the rest position). A fault
  still latched ``fault_release_ms`` later releases the motor: position unknown,
  sampling and the sense current off, EVENT MOTOR_RELEASED (code = the fault).
* SAMPLE every sampling period on a grid anchored where SET_SAMPLING ran, first one
  period later, stamped with its grid time (the simulated conversions start on time);
  ``heater_mV`` is the voltage the PWM applies (:mod:`tsa_bench.sim.heater`, the
  firmware's rounding), which also heats the plant; sampling survives STOP and faults
  (until the motor release). The resistance is there only when
  the CS5513 has a settled word in time (:class:`~tsa_bench.sim.sensors.ResistanceTiming`:
  not while the heater is on, not in the ~80 ms after the sense current comes on unless
  the period leaves time, not at periods shorter than a conversion); otherwise the
  sample keeps its slot and says resistance_not_measured.
* Periods below ``SINGLE_SHOT_MIN_PERIOD_US`` (3 ms) sample continuously, as the
  firmware's ADS1115 in continuous mode: a sample every ``period // 1163`` conversions
  of 1/860 s, sent in SAMPLE_BLOCK frames (:mod:`tsa_bench.protocol.blocks`; a block
  under way goes out before any other frame), each with the CS5513 word finished
  since the previous sample when there is one (words come at the CS5513's own rate).
* Every EVENT's ``value`` is the step position at that instant (the rest position for
  STOPPED and FAULT); ``code`` is the fault for FAULT, FAULT_CLEARED and MOTOR_RELEASED,
  else 0. QUEUE_STATUS carries the state bits and the position; its error counters
  (step underruns, UART, I2C), ``max_pass_us`` and ``sensor_restarts`` stay 0: the
  simulation has no such hardware; ``sensor_period_ns`` is the simulated ADS1115's
  conversion period (1/860 s) while sampling continuously, else 0.
* ``simulated=False`` (a rehearsal device, ``tsa-bench sim-serve --as-hardware``): IDENTITY
  without the SIMULATED flag and SIM_SET_LOAD answered ``unknown_message``, as the
  firmware; the load changes only through :meth:`SimDevice.set_load_g` (a person's hand).
  :meth:`SimDevice.after_reset` is the device after a DTR reset.
* Undecodable frames are dropped and counted (:attr:`frame_errors`); a valid frame
  with an id this device does not accept gets ``unknown_message``, a wrong payload
  length ``bad_length``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from tsa_bench.benchdata import BenchConfig
from tsa_bench.protocol import catalogue as msg
from tsa_bench.protocol.blocks import (
    ADS1115_SPS, SAMPLES_PER_BLOCK, SINGLE_SHOT_MIN_PERIOD_US, BlockBuilder, conversions_per_sample, frame_bytes, sampling_refusal,
)
from tsa_bench.protocol.codec import Frame, encode
from tsa_bench.protocol.framing import FrameDecoder, RawFrame, encode_raw
from tsa_bench.sim.executor import NO_SEGMENT, QueuedCommand, SegmentExecutor
from tsa_bench.sim.identity import (
    MIN_SAMPLING_PERIOD_US, SIM_FIRMWARE_VERSION, DeviceLimits, device_limits, identity_message,
)
from tsa_bench.sim.plant import Plant, plant_from_config
from tsa_bench.sim.sensors import ResistanceTiming, SimSensors

__all__ = ["SimDevice", "NO_SEGMENT", "MIN_SAMPLING_PERIOD_US"]

_S = msg.Status
_SAMPLE_SPEC = msg.MESSAGES[0x83]
_SAMPLE_PACK = _SAMPLE_SPEC.struct.pack
_NOT_MEASURED = int(msg.AdcFlags.RESISTANCE_NOT_MEASURED)
_QUEUED_TYPES = (msg.MoveTo, msg.MoveBy, msg.Dwell, msg.SetHeater, msg.SetSampling)
_SAMPLE_FRAME_BYTES = _SAMPLE_SPEC.struct.size + 8
_BLOCK_SPEC = msg.MESSAGES[0x86]
_BLOCK_ENTRY_BYTES = _BLOCK_SPEC.entry_struct.size  # type: ignore[union-attr]


_STATE = msg.DeviceState
_Sample = msg.Sample
_new_tuple = tuple.__new__
_STARTED = int(msg.EventKind.SEGMENT_STARTED)
_DONE = int(msg.EventKind.SEGMENT_DONE)
_FRAME_SIZES: dict[type, int] = {}   # message class -> its frame's size on the wire


class SimDevice:
    """A simulated tsa-bench device (see module docstring)."""

    def __init__(self, bench: BenchConfig, plant: Plant | None = None, seed: int | None = None, *,
                 frames: bool = False, simulated: bool = True) -> None:
        self.bench = bench
        self.limits: DeviceLimits = device_limits(bench)
        self.simulated = simulated       # False: passes for hardware (no SIMULATED flag, no SIM_SET_LOAD)
        self.identity = identity_message(self.limits, simulated)
        self.plant: Plant = plant if plant is not None else plant_from_config(bench.plant, seed)
        self.sensors = SimSensors(bench.position, bench.resistance)
        self.resistance_timing = ResistanceTiming()
        self._heater_seen = 0
        self.executor = SegmentExecutor(self.limits.queue_slots, self._emit_event, self._set_sampling)
        self.now_s = 0.0
        self.fault = 0
        self.position_known = False      # power-on: the twist zero must be declared
        self.motor_released = False
        self._fault_since_s = 0.0
        self.duplicates = 0              # repeated commands answered from the filter
        self._watchdog_s = self.limits.watchdog_s
        self._turns_per_step = 1.0 / self.limits.steps_per_turn
        self._framer = FrameDecoder()
        self._out = bytearray()
        self._frames: list[tuple[Frame | bytes, int]] | None = [] if frames else None
        self._produced = 0               # output bytes produced so far (both modes)
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
        self._block = BlockBuilder()     # continuous sampling: samples waiting for their SAMPLE_BLOCK
        self._step_us = 0.0              # continuous sampling: us between samples (ADS1115 conversions)
        #: set by the in-process port while the host decides nothing from samples (see advance)
        self.batch_segment_events = False

    # -- public -----------------------------------------------------------
    @property
    def frame_errors(self) -> dict[str, int]:
        """Dropped host frames by reason (cobs, crc, short, version, too_long)."""
        return self._framer.errors

    @property
    def active(self) -> bool:
        """Commands queued, a segment executing, the heater on or a stop under way."""
        ex = self.executor
        return ex.executing or ex.queued > 0 or ex.heater_mV > 0 or ex.stopping

    @property
    def watchdog_armed(self) -> bool:
        """Active, or sampling (the sense current is on): host silence trips the watchdog."""
        return self.active or self._period_us > 0

    @property
    def state(self) -> int:
        """QUEUE_STATUS.state bits (device_state)."""
        s = 0 if self.position_known else int(_STATE.POSITION_UNKNOWN)
        if self.motor_released:
            s |= int(_STATE.MOTOR_RELEASED)
        if self.executor.stopping:
            s |= int(_STATE.STOPPING)
        return s

    @property
    def sampling_period_us(self) -> int:
        return self._period_us

    @property
    def last_host_s(self) -> float:
        """Virtual time of the last valid host frame (the watchdog counts from it)."""
        return self._last_host_s

    @property
    def has_urgent_output(self) -> bool:
        """The pending output holds something other than SAMPLE frames."""
        return self._urgent

    @property
    def pending_output_bytes(self) -> int:
        return len(self._out) if self._frames is None else sum(n for _, n in self._frames)

    def set_load_g(self, load_g: float) -> None:
        """Change the hanging load, as an operator would (same as SIM_SET_LOAD)."""
        self.plant.set_load(load_g)

    def boot(self, reason: msg.BootReason = msg.BootReason.POWER_ON) -> None:
        """Announce the start: queue BOOT (default reason POWER_ON: a fresh device, position
        unknown), after a lone delimiter, as the firmware does (it ends a frame a reset cut short)."""
        self._put_bytes(b"\x00")
        self._send(msg.Boot(*SIM_FIRMWARE_VERSION, int(reason)))

    def after_reset(self) -> SimDevice:
        """A new device as this one comes out of an external reset (a Mega's DTR pulse when
        its port opens): the same plant (the TSA hangs as it hung), fault, queue, heater and
        sampling gone; the motor where it stood, its position kept only when it was known,
        at rest and the motor held (firmware/README.md, "The twist zero across resets").
        BOOT (reason external_reset) is queued."""
        ex = self.executor
        position, moving = ex.position_at(self.now_s)
        fresh = SimDevice(self.bench, self.plant, frames=self._frames is not None, simulated=self.simulated)
        fresh.executor.set_position(position)
        fresh.position_known = (self.position_known and not moving and not ex.stopping
                                and not self.motor_released)
        fresh.boot(msg.BootReason.EXTERNAL_RESET)
        return fresh

    def receive(self, data: bytes) -> None:
        """Handle bytes from the host at the current virtual time; replies are queued."""
        for raw in self._framer.feed(data):
            self._last_host_s = self.now_s
            self._handle(raw)

    def receive_frame(self, seq: int, message: NamedTuple) -> None:
        """Handle one host message as if its (valid) frame had arrived now."""
        spec = msg.SPEC_BY_CLASS[type(message)]
        self._last_host_s = self.now_s
        self._handle(RawFrame(msg.PROTOCOL_VERSION, seq, spec.id, b""), message)

    def take_output(self) -> bytes:
        """Everything sent since the last call."""
        if self._frames is not None:
            frames, self._frames = self._frames, []
            self._out += b"".join(f if isinstance(f, bytes) else encode(f.message, f.seq) for f, _ in frames)
        out = bytes(self._out)
        self._out.clear()
        self._urgent = False
        return out

    def take_frames(self) -> list[tuple[Frame | bytes, int]]:
        """(frame device mode) Everything sent since the last call: frames, or raw bytes
        (the boot delimiter), each with its size on the wire."""
        assert self._frames is not None, "take_frames needs a device made with frames=True"
        frames, self._frames = self._frames, []
        self._urgent = False
        return frames

    def _put_bytes(self, data: bytes) -> None:
        if self._frames is None:
            self._out += data
        else:
            self._frames.append((data, len(data)))
        self._produced += len(data)

    def advance(self, max_dt_s: float, max_output_bytes: int) -> float:
        """Run virtual time forward event by event; return the time advanced (s).

        Stops once this call has produced a non-SAMPLE frame (ACK, EVENT, ...) or
        ``max_output_bytes`` bytes, or after ``max_dt_s``; when it stops early the time
        rests on the last event handled. Output already pending does not stop it. While
        :attr:`batch_segment_events` is set, SEGMENT_DONE, and SEGMENT_STARTED with more
        commands still waiting in the queue, do not stop it either (they are sent all the
        same, in order): it stops at the start of the last queued command, at QUEUE_EMPTY
        and at every other non-SAMPLE frame, the moments a host that keeps the queue fed
        must act at.
        """
        start = self.now_s
        end = start + max(0.0, max_dt_s)
        ex = self.executor
        limit = self._produced + max_output_bytes
        urgent_before = self._urgent_sent
        release_s = self.limits.fault_release_s
        inf = math.inf
        while self._urgent_sent == urgent_before and self._produced < limit:
            t_seg = ex.end_s
            t_smp = self._next_sample_s
            fault = self.fault
            if fault:
                t_wd = inf
                releasing = not self.motor_released and release_s > 0 and not ex.stopping
                t_rel = self._fault_since_s + release_s if releasing else inf
            else:   # the watchdog runs while watchdog_armed (tested cheapest first)
                t_wd = self._last_host_s + self._watchdog_s if self._period_us > 0 or self.active else inf
                t_rel = inf
            t = t_seg if t_seg < t_smp else t_smp
            if t_wd < t:
                t = t_wd
            if t_rel < t:
                t = t_rel
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
            elif t_rel <= t:
                self._release_motor()
            else:
                self._take_sample()
        return self.now_s - start

    # -- output -----------------------------------------------------------
    def _t_us(self, t_s: float) -> int:
        return round(t_s * 1e6)

    def _send(self, message: NamedTuple, urgent: bool = True) -> None:
        if self._held is not None:
            self._held.append(message)
            return
        if len(self._block):
            self._send_block(self._block.flush())   # samples taken before it go first
        if self._frames is None:
            data = encode(message, self._seq)
            self._out += data
            self._produced += len(data)
        else:
            n = _FRAME_SIZES.get(type(message))
            if n is None:
                n = _FRAME_SIZES[type(message)] = frame_bytes(msg.SPEC_BY_CLASS[type(message)].struct.size)
            self._frames.append((Frame(self._seq, message), n))
            self._produced += n
        self._seq = (self._seq + 1) & 0xFFFF
        if urgent:
            self._urgent = True
            self._urgent_sent += 1

    def _emit_event(self, t_s: float, kind: int, segment: int, value: int, code: int = 0) -> None:
        event = msg.Event(self._t_us(t_s), kind, segment, code, value)
        if self.batch_segment_events and (kind == _DONE or (kind == _STARTED and self.executor.queued > 0)):
            self._send(event, urgent=False)   # more commands wait behind it: the host need not act now
        else:
            self._send(event)

    def _take_sample(self) -> None:
        t = self.now_s
        ex = self.executor
        move = ex._move   # ex.position_at(t) inline (this runs once per sample)
        if move is None:
            steps, moving = ex.position_steps, False
        elif t >= ex.end_s:
            steps, moving = move.target_steps, False
        else:
            steps, moving = move.start_steps + round(move.profile.position(t - move.start_s)), True
        heater_mV = ex.heater_mV
        length_mm, resistance_ohm = self.plant.sample(t, steps * self._turns_per_step, heater_mV * 1e-3, moving)
        position_raw, resistance_raw, flags = self.sensors.convert(length_mm, resistance_ohm, heater_mV)
        timing = self.resistance_timing
        if heater_mV > 0 or ex.heater_switch_ons != self._heater_seen:
            timing.sense_off()       # the heater came on since the last sample: current off
            self._heater_seen = ex.heater_switch_ons
        step_us = self._step_us
        k = self._k
        if step_us:
            t_us = self._anchor_us + round(k * step_us)
            if heater_mV == 0 and not timing.word_since_last(t_us * 1e-6):
                resistance_raw, flags = 0, flags | _NOT_MEASURED
        else:
            period_us = self._period_us
            t_us = self._anchor_us + k * period_us
            if heater_mV == 0 and not timing.measured(t_us * 1e-6, period_us * 1e-6):
                resistance_raw, flags = 0, flags | _NOT_MEASURED
        fields = (self._counter, t_us, steps, position_raw, resistance_raw, flags, heater_mV, 1 if moving else 0,
                  ex.segment)
        if step_us:
            self._send_block(self._block.add(msg.Sample(*fields)))
            if len(self._block) >= SAMPLES_PER_BLOCK:     # full: out at once, as the firmware does
                self._send_block(self._block.flush())
        else:
            seq = self._seq
            if self._frames is None:
                data = encode_raw(0x83, seq, _SAMPLE_PACK(*fields))
                self._out += data
                self._produced += len(data)
            else:   # tuple.__new__: the same Sample and Frame as their constructors make, without their Python frames
                self._frames.append((_new_tuple(Frame, (seq, _new_tuple(_Sample, fields))), _SAMPLE_FRAME_BYTES))
                self._produced += _SAMPLE_FRAME_BYTES
            self._seq = (seq + 1) & 0xFFFF
        self._counter = (self._counter + 1) & 0xFFFFFFFF
        self._k = k = k + 1
        if step_us:
            self._next_sample_s = (self._anchor_us + round(k * step_us)) * 1e-6
        else:
            self._next_sample_s = (t_us + period_us) * 1e-6

    def _send_block(self, block: msg.SampleBlock | None) -> None:
        """Send a closed SAMPLE_BLOCK (a sample frame: not urgent, like SAMPLE)."""
        if block is None:
            return
        if self._frames is None:
            data = encode(block, self._seq)
            self._out += data
            n = len(data)
        else:
            n = frame_bytes(_BLOCK_SPEC.struct.size + len(block.entries) * _BLOCK_ENTRY_BYTES)
            self._frames.append((Frame(self._seq, block), n))
        self._produced += n
        self._seq = (self._seq + 1) & 0xFFFF

    def _set_sampling(self, period_us: int, t_s: float) -> None:
        if len(self._block):
            self._send_block(self._block.flush())
        if period_us == 0:
            self.resistance_timing.sense_off()
        self._period_us = period_us
        self._anchor_us = self._t_us(t_s)
        self._k = 1
        continuous = 0 < period_us < SINGLE_SHOT_MIN_PERIOD_US
        self._step_us = conversions_per_sample(period_us) * 1e6 / ADS1115_SPS if continuous else 0.0
        first_us = round(self._step_us) if continuous else period_us
        self._next_sample_s = (self._anchor_us + first_us) * 1e-6 if period_us else math.inf

    # -- input ------------------------------------------------------------
    def _handle(self, raw: RawFrame, message: NamedTuple | None = None) -> None:
        spec = msg.MESSAGES.get(raw.msg_id)
        if spec is None or spec.direction != "host" or (spec.cls is msg.SimSetLoad and not self.simulated):
            self._answer(raw, _S.UNKNOWN_MESSAGE)
            return
        if message is None:
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
        position, _ = ex.position_at(self.now_s)
        period_ns = round(1e9 / ADS1115_SPS) if self._step_us else 0
        return msg.QueueStatus(self._t_us(self.now_s), ex.queue_free, int(ex.executing), ex.segment, self.fault,
                               self.state, position, 0, 0, 0, 0, 0, period_ns, 0)

    def _check(self, message: NamedTuple) -> msg.Status:
        lim = self.limits
        kind = type(message)
        if kind is msg.SetPosition:
            ex = self.executor
            if ex.move_waiting or ex.stopping or self.motor_released:
                return _S.BAD_STATE
            if not lim.min_twist_steps <= message.position_steps <= lim.max_twist_steps:
                return _S.LIMIT_EXCEEDED
            return _S.OK
        if kind is msg.ArmReset:
            ex = self.executor
            if not self.position_known or ex.move_waiting or ex.stopping \
                    or self.motor_released:
                return _S.BAD_STATE
            return _S.OK
        if not isinstance(message, _QUEUED_TYPES):
            return _S.OK
        if self.fault:
            return _S.BAD_STATE
        if kind is msg.MoveTo or kind is msg.MoveBy:
            if not self.position_known:
                return _S.BAD_STATE
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
            refusal = sampling_refusal(message.period_us, self.bench.baud)
            if refusal is not None:
                return refusal[0]
        if self.executor.queue_free <= 0:
            return _S.QUEUE_FULL
        return _S.OK

    def _apply(self, message: NamedTuple) -> None:
        kind = type(message)
        if kind is msg.Heartbeat:
            self._send(self._queue_status())
        elif kind is msg.Stop:
            rest = self.executor.stop(self.now_s, self.limits.max_accel_steps_per_s2)
            self._emit_event(self.now_s, int(msg.EventKind.STOPPED), self.executor.segment, rest)
        elif kind is msg.SetPosition:
            self.executor.set_position(message.position_steps)
            self.position_known = True
        elif kind is msg.ClearQueue:
            self.executor.clear_queue()
            if self.fault:
                code, self.fault = self.fault, 0
                self.motor_released = False      # energized again; the position stays unknown
                position, _ = self.executor.position_at(self.now_s)
                self._emit_event(self.now_s, int(msg.EventKind.FAULT_CLEARED), self.executor.segment, position,
                                 code)
        elif kind is msg.SimSetLoad:
            self.plant.set_load(message.load_mg * 1e-3)
        elif kind is msg.ArmReset:
            pass    # a simulated device never resets: nothing to keep
        else:
            command: QueuedCommand = message  # type: ignore[assignment]
            self.executor.push(command, self.now_s)

    def inject_fault(self, fault: msg.Fault) -> None:
        """Latch ``fault`` now, exactly as a detected hardware fault would (motor halted
        at once - a move cut short leaves the position unknown -, heater off, queue
        cleared, EVENT fault): for testing how hosts handle faults."""
        ex = self.executor
        moving = ex.position_at(self.now_s)[1]
        position = ex.halt(self.now_s)
        if moving:
            self.position_known = False
        self._latch(fault, position)

    def _trip(self, fault: msg.Fault) -> None:
        """The host watchdog: a controlled stop, then the fault latched."""
        rest = self.executor.stop(self.now_s, self.limits.max_accel_steps_per_s2)
        self._latch(fault, rest)

    def _latch(self, fault: msg.Fault, position: int) -> None:
        self.fault = int(fault)
        self._fault_since_s = self.now_s
        self._emit_event(self.now_s, int(msg.EventKind.FAULT), self.executor.segment, position, int(fault))

    def _release_motor(self) -> None:
        """The fault outlasted ``fault_release_ms``: motor off (position unknown), sampling
        and the sense current off."""
        self.motor_released = True
        self.position_known = False
        self._set_sampling(0, self.now_s)
        position, _ = self.executor.position_at(self.now_s)
        self._emit_event(self.now_s, int(msg.EventKind.MOTOR_RELEASED), self.executor.segment, position,
                         self.fault)
