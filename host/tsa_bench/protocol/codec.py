"""Message layer: typed catalogue messages <-> frames.

``encode(message, seq)`` gives the bytes to write (frame plus delimiter);
``decode(raw)`` turns a checked :class:`RawFrame` into the catalogue's NamedTuple.
:class:`MessageDecoder` combines both for a byte stream. Unknown message ids and
payloads of the wrong length raise :class:`MessageError`; a stream decoder counts
them instead of raising.
"""

from __future__ import annotations

import struct
from typing import NamedTuple

from tsa_bench.protocol.catalogue import MESSAGES, SPEC_BY_CLASS, MessageSpec
from tsa_bench.protocol.framing import FrameDecoder, RawFrame, encode_raw


class MessageError(ValueError):
    """A valid frame whose content is not a catalogue message."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


class Frame(NamedTuple):
    """A decoded message with the sequence number of the frame that carried it."""

    seq: int
    message: NamedTuple


def spec_of(message: NamedTuple) -> MessageSpec:
    """The catalogue entry of a message instance."""
    try:
        return SPEC_BY_CLASS[type(message)]
    except KeyError:
        raise TypeError(f"{type(message).__name__} is not a catalogue message") from None


def encode(message: NamedTuple, seq: int) -> bytes:
    """Frame one message; raise ValueError when a field does not fit its wire type."""
    spec = spec_of(message)
    try:
        payload = spec.struct.pack(*message)
    except struct.error as exc:
        raise ValueError(f"{spec.name}: {exc} (fields {message})") from None
    return encode_raw(spec.id, seq, payload)


def decode(raw: RawFrame) -> Frame:
    spec = MESSAGES.get(raw.msg_id)
    if spec is None:
        raise MessageError("unknown_message", f"message id 0x{raw.msg_id:02X}")
    if len(raw.payload) != spec.struct.size:
        raise MessageError("bad_length", f"{spec.name} payload {len(raw.payload)} B, expected {spec.struct.size}")
    return Frame(raw.seq, spec.cls._make(spec.struct.unpack(raw.payload)))


class MessageDecoder:
    """Byte stream -> decoded frames. ``errors`` counts every rejected frame by reason."""

    def __init__(self) -> None:
        self._frames = FrameDecoder()
        self.errors = self._frames.errors

    def feed(self, data: bytes) -> list[Frame]:
        out: list[Frame] = []
        for raw in self._frames.feed(data):
            try:
                out.append(decode(raw))
            except MessageError as exc:
                self.errors[exc.reason] = self.errors.get(exc.reason, 0) + 1
        return out
