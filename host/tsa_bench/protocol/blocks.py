"""SAMPLE_BLOCK: several samples of the continuous sampler in one frame, and what a
sampling period costs the line.

Units: time in us, positions in steps, sensor values in counts, line use in bytes/s.

Contract. Below ``SINGLE_SHOT_MIN_PERIOD_US`` the device runs the ADS1115 in
continuous mode (a conversion every 1/860 s, paced by the chip's ALERT/RDY pin) and
sends its samples in SAMPLE_BLOCK frames of up to ``SAMPLES_PER_BLOCK``: the first
sample in full, each next one as deltas (time, step position, position counts modulo
65536, flags). Every sample of a block has the same heater voltage and segment; a
block holds at most one CS5513 word (``resistance_at`` says which sample it belongs
to). A builder closes a block when it is full, when the heater voltage or segment
changes, when a second resistance word comes, or when the device has to send
something else first. :func:`expand_block` turns a block back into the SAMPLE
messages it stands for, so everything after the link layer sees samples only: a
sample without a resistance word says ``resistance_not_measured`` with
``resistance_raw`` 0, as a SAMPLE does when no conversion finished for it.

:func:`sampling_refusal` is the device's check of a SET_SAMPLING period (the
simulated device and the firmware apply the same rule, firmware/config.h mirrors
the constants): shorter than one ADS1115 conversion -> ``too_fast_for_sensor``; below
``SINGLE_SHOT_MIN_PERIOD_US`` not a whole number of conversions (1163 or 2326 us) ->
``between_conversions`` (never rounded); sample frames needing more than
``LINE_BUDGET`` of the line -> ``too_fast_for_line``.
"""

from __future__ import annotations

from collections.abc import Iterable

from tsa_bench.protocol import catalogue as msg

#: Samples in one SAMPLE_BLOCK at most (the first plus its entries).
SAMPLES_PER_BLOCK = 1 + msg.MESSAGES[0x86].max_entries
#: ``resistance_at`` of a block without a CS5513 word.
NO_RESISTANCE = 255
#: ADS1115 at its fastest data rate (DR = 111), data sheet SBAS444: 860 samples/s.
ADS1115_SPS = 860
#: One conversion at 860 SPS, rounded up (us): the shortest sampling period.
ADS1115_CONVERSION_US = -(-1_000_000 // ADS1115_SPS)   # 1163
#: Periods from here up are single-shot conversions on the device's own grid, one SAMPLE frame each.
SINGLE_SHOT_MIN_PERIOD_US = 3000
#: Share of the line's bytes sample frames may use; the rest carries ACK, EVENT, QUEUE_STATUS.
LINE_BUDGET = 0.8
#: 8N1: ten bits on the line per byte.
BITS_PER_BYTE = 10

_F = msg.SampleFlags
_A = msg.AdcFlags
_NOT_MEASURED = int(_A.RESISTANCE_NOT_MEASURED)
# the flags as plain ints: an enum flag's & costs a Python call, and expand_block runs per sample
_F_POSITION_INVALID, _F_MOTOR_MOVING = int(_F.POSITION_INVALID), int(_F.MOTOR_MOVING)
_F_RES_OVERRANGE, _F_RES_OSCILLATION = int(_F.RESISTANCE_OVERRANGE), int(_F.RESISTANCE_OSCILLATION)
_A_POSITION_INVALID = int(_A.POSITION_INVALID)
_A_RES_OVERRANGE, _A_RES_OSCILLATION = int(_A.RESISTANCE_OVERRANGE), int(_A.RESISTANCE_OSCILLATION)


def frame_bytes(payload_bytes: int) -> int:
    """Bytes one frame takes on the wire: header 4 + payload + CRC 2, COBS 1 (bodies
    under 254 bytes: every catalogue message), delimiter 1."""
    body = payload_bytes + 6
    return body + 1 + body // 254 + 1


#: Wire bytes of a full SAMPLE_BLOCK and of one SAMPLE.
FULL_BLOCK_BYTES = frame_bytes(msg.MESSAGES[0x86].struct.size
                               + (SAMPLES_PER_BLOCK - 1) * msg.MESSAGES[0x86].entry_struct.size)  # type: ignore[union-attr]
SAMPLE_BYTES = frame_bytes(msg.MESSAGES[0x83].struct.size)


def conversions_per_sample(period_us: int) -> int:
    """Continuous mode: a sample is every this many ADS1115 conversions (>= 1)."""
    return max(1, period_us // ADS1115_CONVERSION_US)


def continuous_periods_us() -> list[int]:
    """The periods the continuous sampler keeps: whole conversions below the single-shot minimum."""
    return list(range(ADS1115_CONVERSION_US, SINGLE_SHOT_MIN_PERIOD_US, ADS1115_CONVERSION_US))


def sample_line_bytes_per_s(period_us: int) -> float:
    """Line use of the sample frames at a sampling period (bytes/s)."""
    if period_us <= 0:
        return 0.0
    if period_us >= SINGLE_SHOT_MIN_PERIOD_US:
        return SAMPLE_BYTES * 1e6 / period_us
    per_sample_us = conversions_per_sample(period_us) * 1e6 / ADS1115_SPS
    return FULL_BLOCK_BYTES / SAMPLES_PER_BLOCK * 1e6 / per_sample_us


def sampling_refusal(period_us: int, baud: int) -> tuple[int, str] | None:
    """Why the device refuses a sampling period (status, reason), or None when it carries it."""
    if period_us == 0:
        return None
    if period_us < ADS1115_CONVERSION_US:
        return (int(msg.Status.TOO_FAST_FOR_SENSOR),
                f"{period_us} us is shorter than one ADS1115 conversion ({ADS1115_CONVERSION_US} us at "
                f"{ADS1115_SPS} samples/s)")
    if period_us < SINGLE_SHOT_MIN_PERIOD_US and period_us % ADS1115_CONVERSION_US:
        return (int(msg.Status.BETWEEN_CONVERSIONS), _between(period_us))
    need = sample_line_bytes_per_s(period_us)
    have = LINE_BUDGET * baud / BITS_PER_BYTE
    if need > have:
        return (int(msg.Status.TOO_FAST_FOR_LINE),
                f"samples every {period_us} us need {need:,.0f} bytes/s, more than {LINE_BUDGET:.0%} of the "
                f"{baud} baud line ({have:,.0f} bytes/s)")
    return None


def _between(period_us: int) -> str:
    kept = " or ".join(f"{p} us" for p in continuous_periods_us())
    return (f"{period_us} us is not a whole number of ADS1115 conversions; below "
            f"{SINGLE_SHOT_MIN_PERIOD_US} us the device samples every conversion or every other one: use {kept}, "
            f"or {SINGLE_SHOT_MIN_PERIOD_US} us and up")


def refusal_reason(command: object, status: int, baud: int | None = None) -> str:
    """For a SET_SAMPLING refused for its period: ' (why)', else ''."""
    if not isinstance(command, msg.SetSampling):
        return ""
    p = command.period_us
    if status == msg.Status.TOO_FAST_FOR_SENSOR:
        return (f" ({p} us is shorter than one ADS1115 conversion, {ADS1115_CONVERSION_US} us at "
                f"{ADS1115_SPS} samples/s: use a longer sampling period)")
    if status == msg.Status.BETWEEN_CONVERSIONS:
        return f" ({_between(p)})"
    if status == msg.Status.TOO_FAST_FOR_LINE:
        line = f" at {baud} baud" if baud else ""
        return (f" (samples every {p} us need {sample_line_bytes_per_s(p):,.0f} bytes/s, more than the serial "
                f"line carries{line}: use a longer sampling period or a faster line)")
    return ""


def expand_block(block: msg.SampleBlock) -> list[msg.Sample]:
    """The SAMPLE messages a block stands for, in order."""
    at = block.resistance_at
    res_flags = 0
    if block.flags & _F_RES_OVERRANGE:
        res_flags |= _A_RES_OVERRANGE
    if block.flags & _F_RES_OSCILLATION:
        res_flags |= _A_RES_OSCILLATION
    out: list[msg.Sample] = []
    sample, counter, heater_mV, segment = msg.Sample, block.counter, block.heater_mV, block.segment
    t, steps, pos, flags = block.t_us, block.step_position, block.position_raw, block.flags
    for i in range(1 + len(block.entries)):
        if i:
            dt_us, step_delta, position_delta, flags = block.entries[i - 1]
            t += dt_us
            steps += step_delta
            pos = ((pos + position_delta + 0x8000) & 0xFFFF) - 0x8000
        adc = _A_POSITION_INVALID if flags & _F_POSITION_INVALID else 0
        if i == at:
            adc |= res_flags
            raw = block.resistance_raw
        else:
            adc |= _NOT_MEASURED
            raw = 0
        out.append(sample((counter + i) & 0xFFFFFFFF, t, steps, pos, raw, adc, heater_mV,
                          1 if flags & _F_MOTOR_MOVING else 0, segment))
    return out


def expand(messages: Iterable) -> list:
    """Messages with every SAMPLE_BLOCK replaced by its samples."""
    out: list = []
    for m in messages:
        if type(m) is msg.SampleBlock:
            out += expand_block(m)
        else:
            out.append(m)
    return out


class BlockBuilder:
    """Collects continuous-mode samples into SAMPLE_BLOCKs (the rules in the module contract).

    :meth:`add` takes one sample (as a SAMPLE message: its resistance word is there
    when ``resistance_not_measured`` is not set) and returns the block it closed, if
    any, before taking the sample in; :meth:`flush` closes the block under way.
    """

    def __init__(self) -> None:
        self._samples: list[msg.Sample] = []
        self._at = NO_RESISTANCE

    def __len__(self) -> int:
        return len(self._samples)

    def add(self, s: msg.Sample) -> msg.SampleBlock | None:
        has_word = not s.adc_flags & _NOT_MEASURED
        closed = None
        if self._samples:
            first, last = self._samples[0], self._samples[-1]
            if (len(self._samples) >= SAMPLES_PER_BLOCK or s.heater_mV != first.heater_mV
                    or s.segment != first.segment or (has_word and self._at != NO_RESISTANCE)
                    or s.counter != (last.counter + 1) & 0xFFFFFFFF or s.t_us - last.t_us > 0xFFFF or not -0x8000 <= s.step_position - last.step_position <= 0x7FFF):
                closed = self.flush()
        if has_word:
            self._at = len(self._samples)
        self._samples.append(s)
        return closed

    def flush(self) -> msg.SampleBlock | None:
        if not self._samples:
            return None
        first = self._samples[0]
        at = self._at
        flags = _sample_flags(first)
        resistance = 0
        if at != NO_RESISTANCE:
            word = self._samples[at]
            resistance = word.resistance_raw
            if word.adc_flags & _A.RESISTANCE_OVERRANGE:
                flags |= int(_F.RESISTANCE_OVERRANGE)
            if word.adc_flags & _A.RESISTANCE_OSCILLATION:
                flags |= int(_F.RESISTANCE_OSCILLATION)
        entries = []
        prev = first
        for s in self._samples[1:]:
            entries.append(msg.SampleBlockEntry(s.t_us - prev.t_us, s.step_position - prev.step_position,
                                                ((s.position_raw - prev.position_raw + 0x8000) & 0xFFFF) - 0x8000,
                                                _sample_flags(s)))
            prev = s
        self._samples = []
        self._at = NO_RESISTANCE
        return msg.SampleBlock(first.counter, first.t_us, first.step_position, first.position_raw, flags,
                               first.heater_mV, first.segment, at, resistance, len(entries), tuple(entries))


def _sample_flags(s: msg.Sample) -> int:
    flags = int(_F.POSITION_INVALID) if s.adc_flags & _A.POSITION_INVALID else 0
    return flags | (int(_F.MOTOR_MOVING) if s.motor_moving else 0)
