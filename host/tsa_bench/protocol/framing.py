"""Frame layer: COBS-encoded, 0x00-delimited frames with a CRC-16/CCITT-FALSE.

A frame before stuffing is::

    version:u8 | seq:u16 | msg_id:u8 | payload (0..MAX_PAYLOAD bytes) | crc:u16

all little-endian, the CRC covering header and payload. The stuffed frame is followed
by a single 0x00 delimiter. Contract of :class:`FrameDecoder`: bytes may arrive in any
chunking; garbage, truncated or corrupt frames are counted and dropped, and decoding
resynchronises at the very next 0x00, so a valid frame that follows a bad one is never
lost, and no bad frame ever yields a message.
"""

from __future__ import annotations

import binascii
import struct
from typing import NamedTuple

from cobs import cobs

from tsa_bench.protocol.catalogue import MAX_PAYLOAD, PROTOCOL_VERSION

HEADER = struct.Struct("<BHB")
CRC = struct.Struct("<H")
#: Longest stuffed frame without its delimiter: header + payload + CRC + COBS overhead.
MAX_STUFFED = HEADER.size + MAX_PAYLOAD + CRC.size + 2


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no xor-out)."""
    return binascii.crc_hqx(data, 0xFFFF)


class FrameError(ValueError):
    """A frame that cannot be accepted; ``reason`` is a short machine-readable tag."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


class RawFrame(NamedTuple):
    """A frame that passed COBS, length, version and CRC checks."""

    version: int
    seq: int
    msg_id: int
    payload: bytes


def encode_raw(msg_id: int, seq: int, payload: bytes, version: int = PROTOCOL_VERSION) -> bytes:
    """Stuff one frame and append the 0x00 delimiter."""
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} B exceeds MAX_PAYLOAD {MAX_PAYLOAD}")
    body = HEADER.pack(version, seq & 0xFFFF, msg_id) + payload
    body += CRC.pack(crc16_ccitt_false(body))
    return cobs.encode(body) + b"\x00"


def decode_raw(stuffed: bytes) -> RawFrame:
    """Check and unstuff one frame given without its delimiter; raise FrameError."""
    if len(stuffed) > MAX_STUFFED:
        raise FrameError("too_long", f"{len(stuffed)} stuffed bytes > {MAX_STUFFED}")
    try:
        body = cobs.decode(stuffed)
    except cobs.DecodeError as exc:
        raise FrameError("cobs", str(exc)) from None
    if len(body) < HEADER.size + CRC.size:
        raise FrameError("short", f"{len(body)} bytes is shorter than header + CRC")
    (crc,) = CRC.unpack_from(body, len(body) - CRC.size)
    if crc16_ccitt_false(body[:-CRC.size]) != crc:
        raise FrameError("crc", f"CRC mismatch (frame says 0x{crc:04X})")
    version, seq, msg_id = HEADER.unpack_from(body)
    if version != PROTOCOL_VERSION:
        raise FrameError("version", f"protocol version {version}, expected {PROTOCOL_VERSION}")
    return RawFrame(version, seq, msg_id, body[HEADER.size:-CRC.size])


class FrameDecoder:
    """Streaming splitter: feed bytes, get the raw frames that were complete and valid.

    ``errors`` counts rejected frames by reason. The pending buffer never grows past
    one maximal frame: an over-long run without a delimiter is discarded up to the
    next 0x00.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._overflow = False
        self.errors: dict[str, int] = {}

    def _reject(self, reason: str) -> None:
        self.errors[reason] = self.errors.get(reason, 0) + 1

    def feed(self, data: bytes) -> list[RawFrame]:
        frames: list[RawFrame] = []
        if not data:
            return frames
        parts = data.split(b"\x00")
        # every part but the last was terminated by a delimiter
        for i, part in enumerate(parts):
            last = i == len(parts) - 1
            if last:
                if self._overflow:
                    return frames
                self._buf += part
                if len(self._buf) > MAX_STUFFED:
                    self._buf.clear()
                    self._overflow = True
                    self._reject("too_long")
                return frames
            if self._overflow:
                self._overflow = False
                continue
            if self._buf:
                self._buf += part
                chunk = bytes(self._buf)
                self._buf.clear()
            else:
                chunk = part
            if not chunk:
                continue  # back-to-back delimiters are idle fill, not an error
            try:
                frames.append(decode_raw(chunk))
            except FrameError as exc:
                self._reject(exc.reason)
        return frames
