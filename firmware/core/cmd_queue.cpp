#include "cmd_queue.h"

#include "protocol_catalogue.h"

namespace fw {

bool CommandQueue::push(const QueuedCommand& c) {
    if (count_ >= cfg::QUEUE_SLOTS) return false;
    slots_[(head_ + count_) % cfg::QUEUE_SLOTS] = c;
    ++count_;
    return true;
}

bool CommandQueue::pop(QueuedCommand& out) {
    if (count_ == 0) return false;
    out = slots_[head_];
    head_ = static_cast<uint8_t>((head_ + 1) % cfg::QUEUE_SLOTS);
    --count_;
    return true;
}

bool CommandQueue::has_move() const {
    for (uint8_t i = 0; i < count_; ++i) {
        const uint8_t id = slots_[(head_ + i) % cfg::QUEUE_SLOTS].msg_id;
        if (id == proto::MoveTo::ID || id == proto::MoveBy::ID) return true;
    }
    return false;
}

}  // namespace fw
