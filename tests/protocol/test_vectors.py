"""The codec against the golden vectors shared with the firmware's test suite."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tsa_bench.protocol import FrameError, crc16_ccitt_false, decode, decode_raw, encode, encode_raw, msg
from tsa_bench.protocol.catalogue import MESSAGES

VECTORS = json.loads((Path(__file__).resolve().parents[2] / "protocol" / "vectors.json").read_text())
BY_NAME = {s.name: s for s in MESSAGES.values()}


def reference_cobs_decode(data: bytes) -> bytes:
    """Independent, deliberately naive COBS decoder to cross-check the library."""
    out, i = bytearray(), 0
    while i < len(data):
        code = data[i]
        assert code != 0
        out += data[i + 1:i + code]
        i += code
        if code != 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


def test_crc_check_value():
    assert crc16_ccitt_false(b"123456789") == 0x29B1
    assert VECTORS["crc16_ccitt_false_check"]["crc"] == "0x29B1"


def test_vectors_match_this_catalogue():
    assert VECTORS["catalogue_hash"] == f"0x{msg.CATALOGUE_HASH:08X}"
    assert {v["name"] for v in VECTORS["messages"]} == set(BY_NAME), "every message id has a vector"


@pytest.mark.parametrize("vec", VECTORS["messages"], ids=lambda v: v["name"])
def test_message_vector(vec):
    spec = BY_NAME[vec["name"]]
    fields = dict(vec["fields"])
    if spec.entry_cls is not None:   # a variable-length message: its entries as JSON lists
        fields["entries"] = tuple(spec.entry_cls(*e) for e in fields["entries"])
    message = spec.cls(**fields)
    frame = bytes.fromhex(vec["frame"])
    assert encode(message, vec["seq"]) == frame
    assert frame.count(0) == 1 and frame[-1] == 0
    decoded = decode(decode_raw(frame[:-1]))
    assert decoded.seq == vec["seq"] and decoded.message == message
    body = reference_cobs_decode(frame[:-1])
    assert body[0] == msg.PROTOCOL_VERSION and body[3] == spec.id
    assert int.from_bytes(body[1:3], "little") == vec["seq"]
    assert int.from_bytes(body[-2:], "little") == crc16_ccitt_false(body[:-2])


@pytest.mark.parametrize("vec", VECTORS["frames"], ids=lambda v: v["case"])
def test_frame_vector(vec):
    frame = bytes.fromhex(vec["frame"])
    assert encode_raw(vec["msg_id"], vec["seq"], bytes.fromhex(vec["payload"])) == frame
    raw = decode_raw(frame[:-1])
    assert (raw.msg_id, raw.seq, raw.payload.hex()) == (vec["msg_id"], vec["seq"], vec["payload"])


@pytest.mark.parametrize("vec", VECTORS["invalid"], ids=lambda v: v["case"])
def test_invalid_vector(vec):
    with pytest.raises(FrameError) as info:
        decode_raw(bytes.fromhex(vec["stuffed"]))
    assert info.value.reason == vec["reason"]


def test_payload_over_maximum_refused():
    with pytest.raises(ValueError, match="MAX_PAYLOAD"):
        encode_raw(0x10, 0, bytes(msg.MAX_PAYLOAD + 1))


def test_field_out_of_range_refused():
    with pytest.raises(ValueError, match="SET_HEATER"):
        encode(msg.SetHeater(0, 70_000), 1)
