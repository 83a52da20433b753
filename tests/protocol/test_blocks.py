"""SAMPLE_BLOCK: samples -> blocks -> wire -> samples is the identity, blocks close by
their rules, and the device's check of a sampling period names the reason."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from tsa_bench.protocol import MessageDecoder, encode, msg
from tsa_bench.protocol.blocks import (
    ADS1115_CONVERSION_US, FULL_BLOCK_BYTES, NO_RESISTANCE, SAMPLES_PER_BLOCK, BlockBuilder, expand, refusal_reason,
    sample_line_bytes_per_s, sampling_refusal,
)

NOT_MEASURED = int(msg.AdcFlags.RESISTANCE_NOT_MEASURED)
S = msg.Status


@st.composite
def sample_runs(draw):
    """Consecutive samples as a continuous sampler makes them (counter +1, time +dt)."""
    n = draw(st.integers(1, 40))
    counter = draw(st.integers(0, 2**32 - 1))
    t = draw(st.integers(0, 2**40))
    steps = draw(st.integers(-(2**30), 2**30))
    out = []
    for i in range(n):
        word = draw(st.booleans())
        flags = 0 if word else NOT_MEASURED
        if word:
            flags |= draw(st.sampled_from([0, 1, 2, 3]))          # OF / OD bits of the word
        flags |= draw(st.sampled_from([0, 0, 0, int(msg.AdcFlags.POSITION_INVALID)]))
        out.append(msg.Sample((counter + i) & 0xFFFFFFFF, t, steps, draw(st.integers(-32768, 32767)),
                              draw(st.integers(-(2**19), 2**19 - 1)) if word else 0, flags,
                              draw(st.sampled_from([0, 0, 0, 4000])), draw(st.integers(0, 1)),
                              draw(st.sampled_from([7, 7, 7, 8]))))
        t += draw(st.integers(1, 70_000))
        steps += draw(st.integers(-40_000, 40_000))
    return out


def _through_the_wire(samples):
    b = BlockBuilder()
    blocks = [blk for s in samples if (blk := b.add(s)) is not None]
    blocks.append(b.flush())
    dec = MessageDecoder()
    got = [f.message for f in dec.feed(b"".join(encode(blk, i) for i, blk in enumerate(blocks)))]
    assert not dec.errors and got == blocks
    return blocks, expand(got)


@given(sample_runs())
def test_samples_survive_blocks_and_the_wire(samples):
    blocks, back = _through_the_wire(samples)
    assert back == samples
    for blk in blocks:
        assert 1 + blk.more <= SAMPLES_PER_BLOCK
        members = [s for s in samples if 0 <= (s.counter - blk.counter) % 2**32 <= blk.more]
        assert len({(s.heater_mV, s.segment) for s in members}) == 1     # one heater voltage and segment
        assert sum(not s.adc_flags & NOT_MEASURED for s in members) <= 1  # at most one CS5513 word


def test_a_steady_stream_fills_blocks_of_six_in_72_bytes():
    samples = [msg.Sample(i, 1_000 + i * ADS1115_CONVERSION_US, 3 * i, 100 - i, 0,
                          0 if i == 9 else NOT_MEASURED, 0, 1, 2) for i in range(30)]
    blocks, back = _through_the_wire(samples)
    assert back == samples
    assert [1 + b.more for b in blocks] == [6] * 5
    assert [len(encode(b, 0)) for b in blocks] == [FULL_BLOCK_BYTES] * 5 == [72] * 5
    assert [b.resistance_at for b in blocks] == [NO_RESISTANCE, 3, NO_RESISTANCE, NO_RESISTANCE, NO_RESISTANCE]
    assert 12 * 6 == FULL_BLOCK_BYTES          # 12 B a sample, where a SAMPLE frame takes 36


def test_a_gap_in_the_counter_closes_the_block():
    samples = [msg.Sample(c, 1_000 * c, 0, 0, 0, NOT_MEASURED, 0, 0, 0) for c in (1, 2, 5, 6)]
    blocks, back = _through_the_wire(samples)
    assert back == samples and [b.counter for b in blocks] == [1, 5]


def test_sampling_refusals_say_why():
    assert sampling_refusal(0, 9600) is None
    assert sampling_refusal(ADS1115_CONVERSION_US, 250_000) is None          # 860 samples/s fit 250 kbaud
    status, why = sampling_refusal(ADS1115_CONVERSION_US - 1, 250_000)
    assert status == S.TOO_FAST_FOR_SENSOR and "ADS1115" in why
    status, why = sampling_refusal(ADS1115_CONVERSION_US, 115_200)
    assert status == S.TOO_FAST_FOR_LINE and "115200 baud" in why
    assert sampling_refusal(2 * ADS1115_CONVERSION_US, 115_200) is None      # every second conversion fits
    assert abs(sample_line_bytes_per_s(ADS1115_CONVERSION_US) - 860 * 12) < 1e-6
    assert sample_line_bytes_per_s(3000) == 12_000                          # one SAMPLE frame every 3 ms
    reason = refusal_reason(msg.SetSampling(1, 100), S.TOO_FAST_FOR_SENSOR)
    assert "shorter than one ADS1115 conversion" in reason
    assert "faster line" in refusal_reason(msg.SetSampling(1, 1163), S.TOO_FAST_FOR_LINE, 115_200)
    assert refusal_reason(msg.SetHeater(1, 100), S.TOO_FAST_FOR_LINE) == ""
