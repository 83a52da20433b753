"""Wire protocol: generated catalogue (messages, enums) plus framing and codec."""

from tsa_bench.protocol import catalogue as msg
from tsa_bench.protocol.codec import Frame, MessageDecoder, MessageError, decode, encode, spec_of
from tsa_bench.protocol.framing import FrameDecoder, FrameError, RawFrame, crc16_ccitt_false, decode_raw, encode_raw

__all__ = [
    "msg", "Frame", "MessageDecoder", "MessageError", "decode", "encode", "spec_of",
    "FrameDecoder", "FrameError", "RawFrame", "crc16_ccitt_false", "decode_raw", "encode_raw",
]
