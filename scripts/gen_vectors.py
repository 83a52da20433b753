#!/usr/bin/env python3
"""Write protocol/vectors.json: golden encoded frames shared by the Python and C++ suites.

Run once when the catalogue changes on purpose (the golden file is then reviewed and
committed); tests compare both codecs against it, so a codec change that alters bytes
on the wire fails loudly instead of silently regenerating the vectors.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "host"))

from tsa_bench.protocol import encode, encode_raw, msg  # noqa: E402
from tsa_bench.protocol.catalogue import MAX_PAYLOAD, MESSAGES  # noqa: E402

EXAMPLES = {
    "HELLO": msg.Hello(1, msg.CATALOGUE_HASH),
    "HEARTBEAT": msg.Heartbeat(),
    "STOP": msg.Stop(),
    "CLEAR_QUEUE": msg.ClearQueue(),
    "SIM_SET_LOAD": msg.SimSetLoad(550_000),
    "SET_POSITION": msg.SetPosition(-12_800),
    "MOVE_TO": msg.MoveTo(12, 80_000, 10_667, 160_000),
    "MOVE_BY": msg.MoveBy(13, -6_400, 10_667, 160_000),
    "DWELL": msg.Dwell(14, 180_000_000),
    "SET_HEATER": msg.SetHeater(15, 10_000),
    "SET_SAMPLING": msg.SetSampling(0, 100_000),
    "BOOT": msg.Boot(0, 1, 0, 2),
    "IDENTITY": msg.Identity(1, 0, 2, 0, msg.CATALOGUE_HASH, 3200, -32_000, 320_000, 16_000, 320_000, 12_000, 16, 2000,
                             0, 3000, 10_000),
    "ACK": msg.Ack(0x1234, 0x10, 0, 15),
    "SAMPLE": msg.Sample(123_456, 9_000_000_000, 80_000, 21_345, -262_144, 4, 0, 1, 11_920),
    "EVENT": msg.Event(42_000_000, 3, 7, 1, 0),
    "QUEUE_STATUS": msg.QueueStatus(1_000_000, 16, 0, 0, 0, 1 | 8, -6_400, 2, 300, 1, 65_535, 4_210, 1_162_791, 3),
    "SAMPLE_BLOCK": msg.SampleBlock(7_000, 12_000_000_000, -1_600, 32_000, 2 | 4, 0, 11_921, 1, 524_287, 2,
                                    (msg.SampleBlockEntry(1_163, 19, 1_500, 2), msg.SampleBlockEntry(1_162, -3, -120, 3))),
    "ARM_RESET": msg.ArmReset(),
}


def main() -> int:
    missing = {s.name for s in MESSAGES.values()} - set(EXAMPLES)
    if missing:
        print(f"no example for {sorted(missing)}", file=sys.stderr)
        return 1
    messages = []
    for i, (name, m) in enumerate(EXAMPLES.items()):
        seq = (i * 4099 + 1) & 0xFFFF
        messages.append({"name": name, "seq": seq, "fields": m._asdict(), "frame": encode(m, seq).hex()})
    # edge cases at the frame layer (header fields given explicitly)
    frames = [
        {"case": "payload all 0x00 (every byte stuffed)", "msg_id": 0x10, "seq": 0, "payload": "00" * 14},
        {"case": "maximum payload", "msg_id": 0x7F, "seq": 0xFFFF, "payload": bytes(range(1, MAX_PAYLOAD + 1)).hex()},
        {"case": "empty payload, seq with zero bytes", "msg_id": 0x02, "seq": 0x0100, "payload": ""},
        {"case": "payload of 0xFF", "msg_id": 0x83, "seq": 0x00FF, "payload": "ff" * 28},
    ]
    for f in frames:
        f["frame"] = encode_raw(f["msg_id"], f["seq"], bytes.fromhex(f["payload"])).hex()
    good = bytes.fromhex(messages[0]["frame"][:-2])
    bad_crc = bytearray(good)
    bad_crc[-2] ^= 0x01 if bad_crc[-2] != 0x01 else 0x03
    invalid = [
        {"case": "CRC corrupted", "stuffed": bytes(bad_crc).hex(), "reason": "crc"},
        {"case": "truncated (last byte missing)", "stuffed": good[:-1].hex(), "reason": "cobs"},
        {"case": "too short for header and CRC", "stuffed": "04010203", "reason": "short"},
        {"case": "wrong protocol version",
         "stuffed": encode_raw(0x02, 1, b"", version=9)[:-1].hex(), "reason": "version"},
        {"case": "longer than the longest frame", "stuffed": "ff" * 80, "reason": "too_long"},
    ]
    out = {
        "crc16_ccitt_false_check": {"input": "123456789", "crc": "0x29B1"},
        "protocol_version": msg.PROTOCOL_VERSION,
        "catalogue_hash": f"0x{msg.CATALOGUE_HASH:08X}",
        "messages": messages,
        "frames": frames,
        "invalid": invalid,
    }
    path = ROOT / "protocol" / "vectors.json"
    path.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {path.relative_to(ROOT)}: {len(messages)} messages, {len(frames)} frames, {len(invalid)} invalid")
    return 0


if __name__ == "__main__":
    sys.exit(main())
