#include "cmd_queue.h"

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

}  // namespace fw
