#include "frame.h"

#include <string.h>

#include "cobs.h"
#include "config.h"
#include "crc16.h"
#include "protocol_catalogue.h"

namespace fw {

FrameParser::FrameParser()
    : len_(0), overflow_(false), last_us_(0), seq_(0), msg_id_(0), payload_len_(0), frames_(0) {
    memset(&errors_, 0, sizeof errors_);
}

void FrameParser::reset() {
    len_ = 0;
    overflow_ = false;
}

bool FrameParser::feed(uint8_t byte, uint32_t now_us) {
    if ((len_ > 0 || overflow_) && now_us - last_us_ > cfg::FRAME_TIMEOUT_US) {
        ++errors_.timeout;
        reset();
    }
    last_us_ = now_us;
    if (byte == 0) {
        if (overflow_) {
            overflow_ = false;
            return false;
        }
        if (len_ == 0) return false;  // idle fill between frames
        bool ok = finish();
        len_ = 0;
        return ok;
    }
    if (overflow_) return false;
    if (len_ >= MAX_STUFFED) {
        ++errors_.too_long;
        len_ = 0;
        overflow_ = true;
        return false;
    }
    buf_[len_++] = byte;
    return false;
}

bool FrameParser::finish() {
    int16_t n = cobs_decode(buf_, len_, buf_, sizeof buf_);
    if (n < 0) {
        ++errors_.cobs;
        return false;
    }
    if (n < FRAME_HEADER_BYTES + FRAME_CRC_BYTES) {
        ++errors_.short_frame;
        return false;
    }
    uint8_t body = static_cast<uint8_t>(n - FRAME_CRC_BYTES);
    uint16_t crc = static_cast<uint16_t>(buf_[body] | (buf_[body + 1] << 8));
    if (crc16(buf_, body) != crc) {
        ++errors_.crc;
        return false;
    }
    if (buf_[0] != proto::PROTOCOL_VERSION) {
        ++errors_.version;
        return false;
    }
    seq_ = static_cast<uint16_t>(buf_[1] | (buf_[2] << 8));
    msg_id_ = buf_[3];
    payload_len_ = static_cast<uint8_t>(body - FRAME_HEADER_BYTES);
    ++frames_;
    return true;
}

uint8_t frame_encode(uint8_t msg_id, uint16_t seq, const uint8_t* payload, uint8_t payload_len,
                     uint8_t* out) {
    uint8_t raw[FRAME_HEADER_BYTES + 64 + FRAME_CRC_BYTES];
    if (payload_len > 64) payload_len = 64;
    raw[0] = proto::PROTOCOL_VERSION;
    raw[1] = static_cast<uint8_t>(seq);
    raw[2] = static_cast<uint8_t>(seq >> 8);
    raw[3] = msg_id;
    if (payload_len) memcpy(raw + FRAME_HEADER_BYTES, payload, payload_len);
    uint8_t body = static_cast<uint8_t>(FRAME_HEADER_BYTES + payload_len);
    uint16_t crc = crc16(raw, body);
    raw[body] = static_cast<uint8_t>(crc);
    raw[body + 1] = static_cast<uint8_t>(crc >> 8);
    uint16_t n = cobs_encode(raw, static_cast<uint16_t>(body + FRAME_CRC_BYTES), out);
    out[n] = 0;
    return static_cast<uint8_t>(n + 1);
}

}  // namespace fw
