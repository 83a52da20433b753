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


def pack_payload(message: NamedTuple) -> bytes:
    """A message's payload (a variable-length one: its fixed fields, then its entries);
    raise ValueError when a field does not fit its wire type or the entries do not
    match their count field."""
    spec = spec_of(message)
    try:
        if spec.entry_struct is None:
            return spec.struct.pack(*message)
        entries = message[-1]
        if len(entries) != message[spec.count_index] or len(entries) > spec.max_entries:
            raise ValueError(f"{spec.name}: {len(entries)} entries, count field says {message[spec.count_index]} "
                             f"(at most {spec.max_entries})")
        return spec.struct.pack(*message[:-1]) + b"".join(spec.entry_struct.pack(*e) for e in entries)
    except struct.error as exc:
        raise ValueError(f"{spec.name}: {exc} (fields {message})") from None


def encode(message: NamedTuple, seq: int) -> bytes:
    """Frame one message; raise ValueError when a field does not fit its wire type."""
    return encode_raw(spec_of(message).id, seq, pack_payload(message))


def unpack_payload(spec: MessageSpec, payload: bytes) -> NamedTuple:
    """The message a payload holds; MessageError ``bad_length`` when its length is not
    the message's (for a variable-length one: its fixed fields plus as many entries as
    its count field says)."""
    size = spec.struct.size
    if spec.entry_struct is None:
        if len(payload) != size:
            raise MessageError("bad_length", f"{spec.name} payload {len(payload)} B, expected {size}")
        return spec.cls._make(spec.struct.unpack(payload))
    if len(payload) < size:
        raise MessageError("bad_length", f"{spec.name} payload {len(payload)} B, shorter than its {size} B of fixed fields")
    fixed = spec.struct.unpack_from(payload)
    n = fixed[spec.count_index]
    esize = spec.entry_struct.size
    if n > spec.max_entries or len(payload) != size + n * esize:
        raise MessageError("bad_length", f"{spec.name} payload {len(payload)} B, expected {size} + {n} x {esize} "
                                         f"(at most {spec.max_entries} entries)")
    entries = tuple(spec.entry_cls._make(e) for e in spec.entry_struct.iter_unpack(payload[size:]))  # type: ignore[union-attr]
    return spec.cls._make((*fixed, entries))


def decode(raw: RawFrame) -> Frame:
    spec = MESSAGES.get(raw.msg_id)
    if spec is None:
        raise MessageError("unknown_message", f"message id 0x{raw.msg_id:02X}")
    return Frame(raw.seq, unpack_payload(spec, raw.payload))


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
