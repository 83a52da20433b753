// CommandQueue: fixed FIFO of cfg::QUEUE_SLOTS accepted queued commands (MOVE_TO,
// MOVE_BY, DWELL, SET_HEATER, SET_SAMPLING), already validated. The executing
// command has been popped and is not counted. No allocation; not shared with ISRs.
#pragma once
#include <stdint.h>

#include "config.h"

namespace fw {

struct QueuedCommand {
    uint8_t msg_id;
    uint16_t segment;
    int32_t steps;   // MOVE_TO target, MOVE_BY delta
    uint32_t value;  // move rate (step/s), DWELL duration (us), heater (mV), period (us)
    uint32_t accel;  // moves only (step/s^2)
};

class CommandQueue {
public:
    CommandQueue() : head_(0), count_(0) {}
    bool push(const QueuedCommand& c);
    bool pop(QueuedCommand& out);
    void clear() { head_ = count_ = 0; }
    uint8_t count() const { return count_; }
    uint8_t free() const { return static_cast<uint8_t>(cfg::QUEUE_SLOTS - count_); }
    bool empty() const { return count_ == 0; }
    // Whether a MOVE_TO or MOVE_BY waits in the queue.
    bool has_move() const;

private:
    QueuedCommand slots_[cfg::QUEUE_SLOTS];
    uint8_t head_;
    uint8_t count_;
};

}  // namespace fw
