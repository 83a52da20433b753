"""Scripted exchanges run against every device backend (the simulated device, the
firmware core built natively, the firmware ELF in simavr), with the observations that
must agree between them: replies normalised to what the protocol promises, never
times, sensor values or versions.

A backend is any pyserial-like port. ``Exchange.replies`` collects what arrives
within ``settle_s`` of wall time (0: one read; the simulated device answers at once);
with ``first_reply_s`` it first waits up to that long for a reply, then until
``settle_s`` passes quietly (an emulated CPU's speed depends on the host's load).
An exchange that ``follows`` another (the same scenario already run on the simulated
device) waits instead on a condition: as many replies as the reference got at that
step, with a generous deadline, so a busy machine only makes it slower; a reply too
many shows up in the next step's comparison.
"""

from __future__ import annotations

import time
from typing import Callable

from tsa_bench.protocol import MessageDecoder, encode, encode_raw, msg
from tsa_bench.protocol.blocks import ADS1115_CONVERSION_US, expand

NOT_MEASURED = int(msg.AdcFlags.RESISTANCE_NOT_MEASURED)


def normalise(m):
    """What must agree between firmware and simulation (not times, sensors, versions or
    the hardware error counters)."""
    if isinstance(m, msg.Ack):
        return ("ACK", m.acked_id, msg.Status(m.status).name, m.queue_free)
    if isinstance(m, msg.Identity):
        return ("IDENTITY", m.protocol_version, m.catalogue_hash, m.steps_per_turn, m.min_twist_steps,
                m.max_twist_steps, m.max_rate_steps_per_s, m.max_accel_steps_per_s2, m.max_heater_mV,
                m.queue_slots, m.watchdog_ms, m.min_sample_period_us, m.fault_release_ms)
    if isinstance(m, msg.QueueStatus):
        return ("QUEUE_STATUS", m.queue_free, m.executing, m.segment, m.fault, m.state)
    if isinstance(m, msg.Event):
        return ("EVENT", msg.EventKind(m.kind).name, m.segment, m.code)
    return (type(m).__name__,)


class Exchange:
    """Sends host frames to a device port and collects its replies."""

    def __init__(self, port, settle_s: float, first_reply_s: float = 0.0, follows: "Exchange | None" = None,
                 deadline_s: float = 30.0):
        self.port, self.settle_s, self.first_reply_s = port, settle_s, first_reply_s
        self.follows, self.deadline_s = follows, deadline_s
        self.counts: list[int] = []       # replies per step (what a following exchange waits for)
        self.decoder = MessageDecoder()
        self.seq = 100
        self.samples: list[msg.Sample] = []
        self.events: list[msg.Event] = []
        self.received: list = []          # every message, in order
        self.blocks = 0                   # SAMPLE_BLOCK frames (their samples are in samples)

    def _read_some(self) -> list:
        data = self.port.read(self.port.in_waiting or 1) if self.settle_s else self.port.read(4096)
        frames = [f.message for f in self.decoder.feed(data)]
        self.blocks += sum(isinstance(m, msg.SampleBlock) for m in frames)
        out = expand(frames)
        self.samples += [m for m in out if isinstance(m, msg.Sample)]
        self.events += [m for m in out if isinstance(m, msg.Event)]
        self.received += out
        return out

    def replies(self) -> list:
        if self.follows is not None:
            want = self.follows.counts[len(self.counts)] if len(self.counts) < len(self.follows.counts) else 0
            out, deadline = [], time.monotonic() + self.deadline_s
            while len(out) < want and time.monotonic() < deadline:
                out += [m for m in self._read_some() if not isinstance(m, (msg.Sample, msg.Boot))]
            self.counts.append(len(out))
            return [normalise(m) for m in out]
        out, now = [], time.monotonic()
        deadline = now + max(self.settle_s, self.first_reply_s)
        while True:
            got = [m for m in self._read_some() if not isinstance(m, (msg.Sample, msg.Boot))]
            out += got
            if got and self.first_reply_s:
                deadline = time.monotonic() + self.settle_s   # then until it goes quiet
            if time.monotonic() >= deadline:
                break
        self.counts.append(len(out))
        return [normalise(m) for m in out]

    def send(self, message=None, *, raw: bytes | None = None, seq: int | None = None) -> list:
        if seq is None:
            self.seq += 1
            seq = self.seq
        self.port.write(raw if raw is not None else encode(message, seq))
        return self.replies()

    def send_for(self, message, kind: type, timeout_s: float = 10.0):
        """Send ``message`` and return the first reply of type ``kind`` (e.g. HEARTBEAT
        -> QUEUE_STATUS), unnormalised."""
        start = len(self.received)
        self.send(message)
        deadline = time.monotonic() + timeout_s
        while True:
            found = [m for m in self.received[start:] if isinstance(m, kind)]
            if found:
                return found[0]
            if time.monotonic() > deadline:
                raise AssertionError(f"no {kind.__name__} after {message}")
            self._read_some()

    def wait_for(self, predicate: Callable[[object], bool], timeout_s: float, heartbeat: bool = True,
                 since: int | None = None) -> None:
        """Read until a message matches ``predicate``, sending a HEARTBEAT every 0.2 s of
        wall time unless ``heartbeat`` is False (their replies are dropped); EVENTs go
        to :attr:`events`, SAMPLEs to :attr:`samples`. With ``since`` (an index into
        :attr:`received`) a match already received from there on counts: a fast device
        (simavr runs ahead of the host) may have sent it among an earlier command's
        replies. Fails after ``timeout_s``."""
        deadline, beat = time.monotonic() + timeout_s, time.monotonic()
        unanswered: set[int] = set()
        statuses_owed = 0                 # QUEUE_STATUS answers to our heartbeats not read yet
        found = since is not None and any(predicate(m) for m in self.received[since:])
        while time.monotonic() < deadline:
            if heartbeat and not found and time.monotonic() - beat > 0.2:
                self.seq += 1
                self.port.write(encode(msg.Heartbeat(), self.seq))
                unanswered.add(self.seq)
                statuses_owed += 1
                beat = time.monotonic()
            for m in self._read_some():
                if isinstance(m, msg.Ack):
                    unanswered.discard(m.acked_seq)
                elif isinstance(m, msg.QueueStatus):
                    statuses_owed -= 1
                found = found or predicate(m)
            if found and not unanswered and statuses_owed <= 0:
                # every heartbeat's QUEUE_STATUS is in: none leaks into the next exchange
                return
        raise AssertionError(f"nothing matching arrived within {timeout_s} s; events {self.events[-5:]}")

    def wait_device_s(self, seconds: float, timeout_s: float = 60.0) -> None:
        """Keep the session alive until SAMPLEs show ``seconds`` more of device time (counted
        from the first sample when none came yet: how much device time the handshake took
        depends on the machine's load, not on the device)."""
        if not self.samples:
            self.wait_for(lambda m: isinstance(m, msg.Sample), timeout_s)
        target = self.samples[-1].t_us + seconds * 1e6
        self.wait_for(lambda m: isinstance(m, msg.Sample) and m.t_us >= target, timeout_s)


def handshake(ex: Exchange) -> list:
    """HELLO, then the twist zero (the device boots with its position unknown)."""
    return ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH)) + ex.send(msg.SetPosition(0))


def every_command_and_refusal(ex: Exchange) -> list:
    """A session touching every message and every refusal; returns all replies."""
    log = []
    log.append(ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH ^ 1)))
    log.append(ex.send(msg.Hello(msg.PROTOCOL_VERSION, msg.CATALOGUE_HASH)))
    log.append(ex.send(msg.Heartbeat()))
    log.append(ex.send(raw=encode_raw(0x7E, 5, b"\x01\x02")))                  # unknown id
    log.append(ex.send(raw=encode_raw(0x10, 6, b"\x01\x02\x03")))             # bad length
    log.append(ex.send(msg.Heartbeat()))                                      # state: position unknown
    log.append(ex.send(msg.MoveTo(1, 1000, 1000, 1000)))                      # refused: position unknown
    log.append(ex.send(msg.ArmReset()))                                       # refused: position unknown
    log.append(ex.send(msg.SetPosition(10_000_000)))                          # beyond the twist limits
    log.append(ex.send(msg.SetPosition(0)))                                   # the twist zero
    log.append(ex.send(msg.ArmReset()))                                       # at rest: armed
    log.append(ex.send(msg.MoveTo(1, 10_000_000, 1000, 1000)))                # beyond max twist
    log.append(ex.send(msg.MoveTo(1, 1000, 0, 1000)))                         # zero rate
    log.append(ex.send(msg.MoveTo(1, 1000, 10**6, 1000)))                     # rate beyond max
    log.append(ex.send(msg.MoveBy(1, -10**6, 1000, 1000)))                    # projected below min
    log.append(ex.send(msg.SetHeater(1, 60_000)))                             # heater beyond max
    log.append(ex.send(msg.SetSampling(1, 500)))                              # period too short
    log.append(ex.send(msg.SetSampling(1, ADS1115_CONVERSION_US - 1)))        # below one ADS1115 conversion
    log.append(ex.send(msg.SetSampling(1, ADS1115_CONVERSION_US + 1)))        # between conversions: never rounded
    log.append(ex.send(msg.Dwell(2, 60_000_000), seq=4000))                   # starts at once
    log.append(ex.send(msg.Dwell(2, 60_000_000), seq=4000))                   # duplicate: same ACK again
    for i in range(17):                                                        # fill the queue, then one more
        log.append(ex.send(msg.Dwell(3 + i, 60_000_000)))
    log.append(ex.send(msg.ClearQueue()))
    log.append(ex.send(msg.Heartbeat()))
    log.append(ex.send(msg.Stop()))
    log.append(ex.send(msg.Heartbeat()))
    return log


def corrupt_frames(ex: Exchange) -> list:
    """Corrupt, truncated and garbage frames get no answer and cost no valid frame."""
    log = [handshake(ex)]
    good = encode(msg.Heartbeat(), 300)
    bad_crc = bytearray(good)
    bad_crc[2] ^= 0x40                                                         # payload bit flipped
    log.append(ex.send(raw=bytes(bad_crc)))
    log.append(ex.send(raw=good[:4] + b"\x00"))                               # truncated
    log.append(ex.send(raw=b"\x13\x37\xff\xfe\x00"))                          # garbage
    log.append(ex.send(raw=b"\x55" * 40 + b"\x00" + encode(msg.Heartbeat(), 301)))  # garbage, then valid
    log.append(ex.send(msg.Heartbeat()))
    return log


def _counters_continuous(samples: list) -> bool:
    return all(b.counter == a.counter + 1 for a, b in zip(samples, samples[1:]))


def stop_during_move(ex: Exchange) -> dict:
    """STOP while the motor turns: halted where it was, queue empty, no SEGMENT_DONE."""
    start = len(ex.received)
    log = [handshake(ex), ex.send(msg.SetSampling(1, 20_000)), ex.send(msg.MoveTo(2, 32_000, 3_200, 32_000))]
    ex.wait_for(lambda m: isinstance(m, msg.Sample) and m.motor_moving and m.step_position > 1600, 30, since=start)
    log.append(ex.send(msg.SetPosition(0)))                                   # refused: a move runs
    log.append(ex.send(msg.Stop()))
    stop_at = len(ex.samples)
    ex.wait_device_s(0.3)
    after = ex.samples[stop_at + 2:]
    log.append(ex.send(msg.Heartbeat()))
    stopped = [e for e in ex.events if e.kind == msg.EventKind.STOPPED]
    return {"log": log,
            "stopped_mid_move": len(stopped) == 1 and 1600 < stopped[0].value < 32_000,
            "frozen_after": len({s.step_position for s in after}) == 1 and not any(s.motor_moving for s in after),
            "segment_done": any(e.kind == msg.EventKind.SEGMENT_DONE and e.segment == 2 for e in ex.events)}


def watchdog_trip(ex: Exchange) -> dict:
    """A silent host: motor and heater stop, fault latched until CLEAR_QUEUE."""
    start = len(ex.received)
    log = [handshake(ex), ex.send(msg.SetSampling(1, 20_000)), ex.send(msg.SetHeater(2, 3000)),
           ex.send(msg.Dwell(3, 60_000_000))]
    ex.wait_for(lambda m: isinstance(m, msg.Event) and m.kind == msg.EventKind.FAULT, 60, heartbeat=False,
                since=start)
    fault_at = len(ex.samples)
    ex.wait_device_s(0.2)
    log.append(ex.send(msg.Dwell(4, 1_000_000)))       # refused: fault latched
    log.append(ex.send(msg.ClearQueue()))              # clears it
    log.append(ex.send(msg.Heartbeat()))
    faults = [normalise(e) for e in ex.events if e.kind == msg.EventKind.FAULT]
    return {"log": log, "faults": faults,
            "heater_off_after": all(s.heater_mV == 0 for s in ex.samples[fault_at + 1:]),
            "heater_on_before": any(s.heater_mV > 0 for s in ex.samples[:fault_at])}


def heater_sense_interlock(ex: Exchange) -> dict:
    """The sense current is never on with the heater: samples while heating say
    resistance_not_measured; afterwards the resistance returns once the CS5513 settles,
    and no sample slot is lost on the way."""
    log = [handshake(ex), ex.send(msg.SetSampling(1, 20_000))]
    ex.wait_device_s(0.6)
    log.append(ex.send(msg.SetHeater(2, 4000)))
    ex.wait_device_s(0.4)
    log.append(ex.send(msg.SetHeater(3, 0)))
    ex.wait_device_s(0.6)
    got = ex.samples
    heated = [s for s in got if s.heater_mV > 0]
    i_off = max(i for i, s in enumerate(got) if s.heater_mV > 0) + 1
    back = next(i for i in range(i_off, len(got)) if not got[i].adc_flags & NOT_MEASURED) - i_off
    i_on = min(i for i, s in enumerate(got) if s.heater_mV > 0)
    # past the settling after sampling started; the last one before heating may have
    # had its conversion aborted when the heater came on (resistance_not_measured)
    before = got[8:i_on - 1]
    return {"log": log, "continuous": _counters_continuous(got),
            "heated_not_measured": bool(heated) and all(s.adc_flags & NOT_MEASURED for s in heated),
            "measured_before_heating": bool(before) and all(not s.adc_flags & NOT_MEASURED for s in before),
            "samples_until_resistance_back": back}


def short_period(ex: Exchange) -> dict:
    """A 10 ms period, shorter than a CS5513 conversion: every slot still has its sample
    (no counter gap); about half carry a resistance word."""
    log = [handshake(ex), ex.send(msg.SetSampling(1, 10_000))]
    ex.wait_device_s(1.5)
    settled = ex.samples[20:]
    measured = sum(not s.adc_flags & NOT_MEASURED for s in settled) / len(settled)
    return {"log": log, "continuous": _counters_continuous(ex.samples), "measured_fraction": measured}


def continuous_sampling(ex: Exchange, seconds: float = 1.0) -> dict:
    """The shortest period, one ADS1115 conversion (1163 us): samples at the ADS1115's
    860 per second in SAMPLE_BLOCK frames, no counter gap, resistance words at the
    CS5513's own rate (one in several samples) once its filter has settled."""
    log = [handshake(ex), ex.send(msg.SetSampling(1, ADS1115_CONVERSION_US))]
    ex.wait_device_s(seconds)
    log.append(ex.send(msg.SetSampling(2, 0)))
    samples = ex.samples
    span_s = (samples[-1].t_us - samples[0].t_us) / 1e6
    settled = [s for s in samples if s.t_us - samples[0].t_us > 200_000]
    words = sum(not s.adc_flags & NOT_MEASURED for s in settled)
    settled_s = (settled[-1].t_us - settled[0].t_us) / 1e6
    return {"log": log, "continuous": _counters_continuous(samples), "blocks": ex.blocks,
            "samples": len(samples), "rate_per_s": (len(samples) - 1) / span_s,
            "resistance_per_s": words / settled_s}


def stop_at_speed(ex: Exchange) -> dict:
    """STOP while cruising at the top rate (16,000 steps/s): the motor decelerates at the
    device's acceleration limit (320,000 steps/s^2: 400 steps, 50 ms) to the position
    EVENT stopped announces at once, instead of stopping dead (and losing steps)."""
    start = len(ex.received)
    log = [handshake(ex), ex.send(msg.SetSampling(1, 10_000)), ex.send(msg.MoveTo(2, 160_000, 16_000, 320_000))]
    ex.wait_for(lambda m: isinstance(m, msg.Sample) and m.step_position > 16_000, 30, since=start)
    before = ex.samples[-1]
    log.append([r for r in ex.send(msg.Stop()) if r[0] != "EVENT"])           # ACK (the EVENT may trail it)
    ex.wait_device_s(0.3)
    stopped = [e for e in ex.events if e.kind == msg.EventKind.STOPPED]
    log.append(ex.send(msg.Heartbeat()))
    if stopped:  # the position when the STOP was acted on: the last sample before it
        before = [s for s in ex.samples if s.t_us <= stopped[0].t_us][-1]
    after = [s for s in ex.samples if s.t_us > before.t_us]
    rest = stopped[0].value if stopped else None
    moving_after = [s for s in after if s.motor_moving]
    return {"log": log, "stopped_once": len(stopped) == 1, "rest": rest,
            "coasted_steps": (rest - before.step_position) if rest is not None else None,
            "ends_at_rest_value": bool(after) and after[-1].step_position == rest and not after[-1].motor_moving,
            "decelerated_for_s": (moving_after[-1].t_us - before.t_us) * 1e-6 if moving_after else 0.0}


HEATER_REQUESTS_MV = (2000, 1000, 3300, 7777, 12000, 300)


def heater_applied(ex: Exchange) -> dict:
    """Each SAMPLE reports the heater voltage the PWM applies for a request (the duty
    rounding, never the request itself)."""
    log = [handshake(ex), ex.send(msg.SetSampling(1, 20_000))]
    reported = []
    for i, mV in enumerate(HEATER_REQUESTS_MV):
        log.append(ex.send(msg.SetHeater(2 + i, mV)))
        ex.wait_device_s(0.1)
        reported.append(ex.samples[-1].heater_mV)
    log.append(ex.send(msg.SetHeater(20, 0)))
    ex.wait_device_s(0.1)
    return {"log": log, "reported_mV": reported, "off_mV": ex.samples[-1].heater_mV}


def fault_release_with_heater(ex: Exchange, timeout_s: float = 120.0) -> dict:
    """A host that vanishes while sampling with the heater on: fault watchdog after
    watchdog_ms (heater off), and fault_release_ms later the motor is released, sampling
    and the sense current go off, the position is unknown; CLEAR_QUEUE energizes the
    motor again."""
    start = len(ex.received)
    log = [handshake(ex), ex.send(msg.SetSampling(1, 20_000)), ex.send(msg.SetHeater(2, 3000))]
    ex.wait_for(lambda m: isinstance(m, msg.Event) and m.kind == msg.EventKind.MOTOR_RELEASED, timeout_s,
                heartbeat=False, since=start)
    released = [e for e in ex.events if e.kind == msg.EventKind.MOTOR_RELEASED][0]
    fault = [e for e in ex.events if e.kind == msg.EventKind.FAULT][0]
    last_sample_us = max(s.t_us for s in ex.samples)
    log.append(ex.send(msg.Heartbeat()))
    log.append(ex.send(msg.SetPosition(0)))                                   # refused: motor released
    log.append(ex.send(msg.ClearQueue()))
    log.append(ex.send(msg.Heartbeat()))
    log.append(ex.send(msg.SetPosition(0)))
    log.append(ex.send(msg.Heartbeat()))
    return {"log": log, "fault_code": fault.code, "released_code": released.code, "fault_t_s": fault.t_us * 1e-6,
            "release_after_fault_s": (released.t_us - fault.t_us) * 1e-6,
            "samples_after_release": last_sample_us > released.t_us}
