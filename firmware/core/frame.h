// Frame layer: COBS(version:u8 | seq:u16 | msg_id:u8 | payload | crc16:u16) 0x00.
// Contract of FrameParser: fed one byte at a time with its arrival time; returns true
// when that byte (a 0x00) completed a valid frame, whose fields stay readable until
// the next feed. Rejected frames are counted by reason (as the host's FrameDecoder:
// too_long, cobs, short, crc, version; plus timeout, a half frame abandoned because the
// next byte came more than cfg::FRAME_TIMEOUT_US later). A stuffed run longer than
// MAX_STUFFED is dropped up to the next 0x00 without buffering; empty frames (idle
// 0x00s) are ignored. Fixed 72-byte buffer, decoded in place.
#pragma once
#include <stdint.h>

namespace fw {

static const uint8_t FRAME_HEADER_BYTES = 4;
static const uint8_t FRAME_CRC_BYTES = 2;
// Longest stuffed frame without delimiter: header + 64 payload + CRC + COBS overhead.
static const uint8_t MAX_STUFFED = 72;
// Longest encoded frame including the delimiter (payload <= 64).
static const uint8_t MAX_WIRE_FRAME = MAX_STUFFED + 1;
// Bytes one frame takes on the wire, known before encoding: header 4 + payload + CRC 2,
// COBS 1 (every frame body is under 254 bytes), delimiter 1.
inline uint16_t frame_wire_bytes(uint8_t payload_len) { return static_cast<uint16_t>(payload_len + 8); }

struct FrameErrors {
    uint16_t too_long;
    uint16_t cobs;
    uint16_t short_frame;
    uint16_t crc;
    uint16_t version;
    uint16_t timeout;
    uint16_t total() const {
        return static_cast<uint16_t>(too_long + cobs + short_frame + crc + version + timeout);
    }
};

class FrameParser {
public:
    FrameParser();
    bool feed(uint8_t byte, uint32_t now_us);  // now_us: the low 32 bits of the clock suffice (time-out 20 ms)
    // Forget a partial frame (not counted).
    void reset();

    uint16_t seq() const { return seq_; }
    uint8_t msg_id() const { return msg_id_; }
    const uint8_t* payload() const { return buf_ + FRAME_HEADER_BYTES; }
    uint8_t payload_len() const { return payload_len_; }
    const FrameErrors& errors() const { return errors_; }
    uint32_t frames() const { return frames_; }

private:
    bool finish();

    uint8_t buf_[MAX_STUFFED];
    uint8_t len_;
    bool overflow_;
    uint32_t last_us_;
    uint16_t seq_;
    uint8_t msg_id_;
    uint8_t payload_len_;
    FrameErrors errors_;
    uint32_t frames_;
};

// Builds a complete wire frame (with delimiter) into out, which must hold
// MAX_WIRE_FRAME bytes; payload_len <= 64. Returns the number of bytes written.
uint8_t frame_encode(uint8_t msg_id, uint16_t seq, const uint8_t* payload, uint8_t payload_len,
                     uint8_t* out);

}  // namespace fw
