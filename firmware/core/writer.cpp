#include "writer.h"

#include <string.h>

namespace fw {

FrameWriter::FrameWriter(Board& board)
    : board_(board), head_(0), count_(0), wire_len_(0), seq_(0), dropped_(0), urgent_lost_(0) {}

uint8_t FrameWriter::reserve() {
    if (count_ >= SLOTS) {
        ++urgent_lost_;
        return NO_SLOT;
    }
    uint8_t slot = static_cast<uint8_t>((head_ + count_) % SLOTS);
    slots_[slot].ready = false;
    ++count_;
    return slot;
}

void FrameWriter::fill(uint8_t slot, uint8_t msg_id, const uint8_t* payload, uint8_t len) {
    if (slot >= SLOTS) return;
    if (len > SLOT_PAYLOAD) len = SLOT_PAYLOAD;
    Slot& s = slots_[slot];
    s.msg_id = msg_id;
    s.len = len;
    if (len) memcpy(s.payload, payload, len);
    s.ready = true;
}

bool FrameWriter::send(uint8_t msg_id, const uint8_t* payload, uint8_t len) {
    uint8_t slot = reserve();
    if (slot == NO_SLOT) return false;
    fill(slot, msg_id, payload, len);
    flush();
    return true;
}

void FrameWriter::flush() {
    for (;;) {
        if (wire_len_ == 0) {
            if (count_ == 0 || !slots_[head_].ready) return;
            const Slot& s = slots_[head_];
            wire_len_ = frame_encode(s.msg_id, seq_++, s.payload, s.len, wire_);
            head_ = static_cast<uint8_t>((head_ + 1) % SLOTS);
            --count_;
        }
        if (board_.serial_tx_free() < wire_len_) return;
        board_.serial_write(wire_, wire_len_);
        wire_len_ = 0;
    }
}

bool FrameWriter::try_send_sample(uint8_t msg_id, const uint8_t* payload, uint8_t len) {
    flush();
    // Room first, from the size the frame will have: it is encoded once, when it goes.
    if (!idle() || board_.serial_tx_free() < frame_wire_bytes(len)) return false;
    uint8_t frame[MAX_WIRE_FRAME];
    const uint8_t n = frame_encode(msg_id, seq_++, payload, len, frame);
    board_.serial_write(frame, n);
    return true;
}

bool FrameWriter::send_droppable(uint8_t msg_id, const uint8_t* payload, uint8_t len) {
    flush();
    if (!idle()) {
        ++dropped_;
        return false;
    }
    uint8_t frame[MAX_WIRE_FRAME];
    uint8_t n = frame_encode(msg_id, seq_, payload, len, frame);
    if (board_.serial_tx_free() < n) {
        ++dropped_;
        return false;
    }
    ++seq_;
    board_.serial_write(frame, n);
    return true;
}

}  // namespace fw
