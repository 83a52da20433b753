"""Property tests: round trips for every message, and resynchronisation after garbage."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from tsa_bench.protocol import MessageDecoder, encode
from tsa_bench.protocol.catalogue import MESSAGES

RANGES = {"B": (0, 2**8 - 1), "H": (0, 2**16 - 1), "I": (0, 2**32 - 1), "Q": (0, 2**64 - 1),
          "b": (-(2**7), 2**7 - 1), "h": (-(2**15), 2**15 - 1), "i": (-(2**31), 2**31 - 1),
          "q": (-(2**63), 2**63 - 1)}


def field_strategy(code: str):
    if code == "f":  # values exactly representable in float32
        return st.floats(width=32, allow_nan=False)
    lo, hi = RANGES[code]
    return st.integers(lo, hi)


@st.composite
def messages(draw):
    spec = draw(st.sampled_from(list(MESSAGES.values())))
    codes = spec.struct.format.lstrip("<")
    fields = [draw(field_strategy(c)) for c in codes]
    if spec.entry_struct is None:
        return spec.cls(*fields)
    n = draw(st.integers(0, spec.max_entries))   # a variable-length message: its count field says n
    fields[spec.count_index] = n
    ecodes = spec.entry_struct.format.lstrip("<")
    entries = tuple(spec.entry_cls(*(draw(field_strategy(c)) for c in ecodes)) for _ in range(n))
    return spec.cls(*fields, entries)


@given(messages(), st.integers(0, 0xFFFF))
def test_round_trip_every_message(message, seq):
    frames = MessageDecoder().feed(encode(message, seq))
    assert len(frames) == 1
    assert frames[0].seq == seq and frames[0].message == message


@settings(max_examples=300)
@given(st.lists(st.tuples(st.sampled_from(["valid", "garbage", "truncated"]), messages(),
                          st.binary(max_size=90)), max_size=25),
       st.lists(st.integers(1, 64), min_size=1, max_size=8))
def test_garbage_never_yields_wrong_message_nor_loses_the_next(items, chunk_sizes):
    stream = bytearray()
    expected = []
    seq = 0
    for kind, message, junk in items:
        seq += 1
        frame = encode(message, seq)
        if kind == "valid":
            stream += frame
            expected.append((seq, message))
        elif kind == "garbage":
            stream += junk  # may or may not contain delimiters
        else:  # a frame cut short: its tail never arrives
            stream += frame[: max(1, len(frame) // 2)]
        # A frame is only guaranteed after a delimiter; garbage without one merges into
        # the next frame, so the contract is checked where a delimiter precedes the frame.
        if kind != "valid":
            stream += b"\x00"
    decoder = MessageDecoder()
    got = []
    pos, i = 0, 0
    while pos < len(stream):
        n = chunk_sizes[i % len(chunk_sizes)]
        got += [(f.seq, f.message) for f in decoder.feed(bytes(stream[pos:pos + n]))]
        pos += n
        i += 1
    # every valid frame arrives, in order; anything else decoded must be a real message
    # that garbage happened to spell exactly (CRC-checked), never a corrupted valid one
    it = iter(got)
    for want in expected:
        assert want in it, f"valid frame {want} lost"
    # anything else decoded must be spelled verbatim, delimiter to delimiter, in the stream
    # (garbage that happens to form a CRC-valid frame), never a corrupted valid frame
    delimited = set(bytes(stream).split(b"\x00"))
    for seq_msg in got:
        if seq_msg not in expected:
            assert encode(seq_msg[1], seq_msg[0])[:-1] in delimited
