// FrameWriter: numbers, encodes and writes device frames through Board::serial_write,
// only ever whole frames, only when serial_tx_free() fits them.
// Contract. Urgent messages (ACK, EVENT, IDENTITY, QUEUE_STATUS, BOOT) go through a
// fixed FIFO outbox and are never dropped while it has room: callers check
// outbox_free() before producing them (Device keeps a reserve), and a push into a full
// outbox is counted in urgent_lost() (a bug if ever non-zero). A slot can be reserved
// and filled later, so an ACK goes out before the events its command caused although
// its contents are known only afterwards. SAMPLEs bypass the outbox: written at once
// when nothing urgent is waiting and the TX ring fits the frame, otherwise dropped and
// counted (the caller's sample counter still advances: the host sees the gap). The
// device's running seq is assigned when a frame is encoded, so seq follows wire order.
#pragma once
#include <stdint.h>

#include "board.h"
#include "frame.h"

namespace fw {

class FrameWriter {
public:
    static const uint8_t SLOTS = 16;
    static const uint8_t SLOT_PAYLOAD = 40;  // IDENTITY, the largest urgent message
    static const uint8_t NO_SLOT = 0xFF;

    explicit FrameWriter(Board& board);

    bool send(uint8_t msg_id, const uint8_t* payload, uint8_t len);
    uint8_t reserve();
    void fill(uint8_t slot, uint8_t msg_id, const uint8_t* payload, uint8_t len);
    bool send_droppable(uint8_t msg_id, const uint8_t* payload, uint8_t len);
    // As send_droppable, but a frame that does not fit now is neither sent nor counted:
    // the caller keeps it and tries again (SAMPLE_BLOCKs, device_continuous.cpp). The
    // room is checked before encoding, so a frame is encoded once, when it goes.
    bool try_send_sample(uint8_t msg_id, const uint8_t* payload, uint8_t len);
    // Writes waiting urgent frames, oldest first, while the TX ring fits them.
    void flush();

    uint8_t outbox_free() const { return static_cast<uint8_t>(SLOTS - count_); }
    bool idle() const { return count_ == 0 && wire_len_ == 0; }
    uint16_t next_seq() const { return seq_; }
    uint32_t dropped() const { return dropped_; }
    uint32_t urgent_lost() const { return urgent_lost_; }

private:
    struct Slot {
        uint8_t msg_id;
        uint8_t len;
        bool ready;
        uint8_t payload[SLOT_PAYLOAD];
    };

    Board& board_;
    Slot slots_[SLOTS];
    uint8_t head_;
    uint8_t count_;
    uint8_t wire_[MAX_WIRE_FRAME];  // the oldest urgent frame, encoded, not yet written
    uint8_t wire_len_;
    uint16_t seq_;
    uint32_t dropped_;
    uint32_t urgent_lost_;
};

}  // namespace fw
