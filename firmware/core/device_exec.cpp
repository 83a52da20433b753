// Device, part 2: the segment executor, motion and safety (see device.h).
#include "config.h"
#include "device.h"

namespace fw {

namespace {
// Outbox room needed to start or end a segment: SEGMENT_DONE / SEGMENT_STARTED /
// QUEUE_EMPTY, plus one slot kept for a FAULT.
const uint8_t SEGMENT_ROOM = 4;
}  // namespace

void Device::push(const QueuedCommand& c, uint64_t now) {
    queue_.push(c);
    if (c.msg_id == proto::MoveTo::ID) {
        projected_ = c.steps;
    } else if (c.msg_id == proto::MoveBy::ID) {
        projected_ += c.steps;
    }
    if (exec_ == EXEC_NONE) {
        if (!starting_) seg_t_us_ = now;
        starting_ = true;
        start_segments();
    }
}

// Starts queued segments in order at seg_t_us_: instantaneous ones (SET_HEATER,
// SET_SAMPLING, zero moves and dwells) end at once, the first lasting one stays
// executing; QUEUE_EMPTY when the queue runs dry. Waits (starting_ stays set) while
// the outbox lacks room for the events.
void Device::start_segments() {
    while (starting_ && writer_.outbox_free() >= SEGMENT_ROOM) {
        QueuedCommand c;
        if (!queue_.pop(c)) {
            starting_ = false;
            send_event(seg_t_us_, proto::event_kind::QUEUE_EMPTY, 0);
            return;
        }
        segment_ = c.segment;
        send_event(seg_t_us_, proto::event_kind::SEGMENT_STARTED, 0);
        if (begin(c)) {
            starting_ = false;
            return;
        }
        send_event(seg_t_us_, proto::event_kind::SEGMENT_DONE, 0);
    }
}

bool Device::begin(const QueuedCommand& c) {
    switch (c.msg_id) {
    case proto::MoveTo::ID:
    case proto::MoveBy::ID: {
        int32_t start = board_.step_position();
        int32_t target = c.msg_id == proto::MoveTo::ID ? c.steps : start + c.steps;
        if (target == start) return false;
        move_target_ = target;
        move_dir_ = target > start ? 1 : -1;
        uint32_t distance = target > start ? static_cast<uint32_t>(target - start)
                                           : static_cast<uint32_t>(start - target);
        planner_.begin(distance, c.value, c.accel);
        exec_ = EXEC_MOVE;
        feed_steps();
        return true;
    }
    case proto::Dwell::ID:
        if (c.value == 0) return false;
        dwell_us_ = c.value;
        exec_ = EXEC_DWELL;
        return true;
    case proto::SetHeater::ID:
        set_heater(static_cast<uint16_t>(c.value));
        return false;
    default:  // SET_SAMPLING
        set_sampling(c.value, seg_t_us_);
        return false;
    }
}

void Device::run_executor(uint64_t now) {
    if (writer_.outbox_free() >= SEGMENT_ROOM) {
        if (exec_ == EXEC_MOVE) {
            feed_steps();
            if (planner_.finished() && !board_.step_busy()) finish_segment(now);
        } else if (exec_ == EXEC_DWELL && now - seg_t_us_ >= dwell_us_) {
            // Timed from the scheduled start, so consecutive dwells never drift.
            finish_segment(seg_t_us_ + dwell_us_);
        }
    }
    start_segments();
}

void Device::finish_segment(uint64_t t_us) {
    exec_ = EXEC_NONE;
    seg_t_us_ = t_us;
    send_event(t_us, proto::event_kind::SEGMENT_DONE, 0);
    starting_ = true;
}

void Device::feed_steps() {
    if (exec_ != EXEC_MOVE) return;
    // Bounded: near the top rate a ramp step costs about as much CPU as it lasts, the
    // ring never fills and an unbounded loop would starve the sampler and the serial
    // port for a whole deceleration (found in simavr: a lost sample slot at 16,000
    // steps/s). poll() calls this twice per pass.
    for (uint8_t n = 0; n < FEED_STEPS_PER_CALL && !planner_.finished() && board_.step_space() > 0; ++n) {
        board_.step_push(move_dir_, planner_.next_interval());
    }
}

void Device::halt() {
    board_.step_halt();
    planner_.abort();
    exec_ = EXEC_NONE;
    starting_ = false;
    queue_.clear();
    set_heater(0);
    projected_ = board_.step_position();
}

void Device::clear_queue() {
    queue_.clear();
    projected_ = exec_ == EXEC_MOVE ? move_target_ : board_.step_position();
}

void Device::trip(uint8_t code, uint64_t now) {
    halt();
    fault_ = code;
    send_event(now, proto::event_kind::FAULT, code);
}

void Device::set_heater(uint16_t mV) {
    // Never rely on the driver's interlock alone: the sense current goes off first.
    if (mV > 0) abort_resistance();
    board_.heater_set_mV(mV);
    heater_mV_ = mV;
}

void Device::check_safety(uint64_t now) {
    if (exec_ == EXEC_MOVE) {
        // Unreachable with validated targets; guards against a planner or driver bug.
        int32_t pos = board_.step_position();
        if ((move_dir_ > 0 && pos > cfg::MAX_TWIST_STEPS) || (move_dir_ < 0 && pos < cfg::MIN_TWIST_STEPS)) {
            trip(proto::fault::TWIST_LIMIT, now);
        }
    }
    if (active() && now - last_host_us_ >= static_cast<uint64_t>(cfg::WATCHDOG_MS) * 1000U) {
        trip(proto::fault::WATCHDOG, now);
    }
    if (heater_mV_ > 0 && sense_on_) abort_resistance();
}

}  // namespace fw
