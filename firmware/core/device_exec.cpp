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
        if (!starting_) seg_t_us_ = now;  // after a stop: reset when the motor is at rest
        starting_ = true;
        start_segments();
    }
}

// Starts queued segments in order at seg_t_us_: instantaneous ones (SET_HEATER,
// SET_SAMPLING, zero moves and dwells) end at once, the first lasting one stays
// executing; QUEUE_EMPTY when the queue runs dry. Waits (starting_ stays set) while
// the outbox lacks room for the events or a controlled stop is still decelerating.
void Device::start_segments() {
    while (starting_ && !stopping_ && writer_.outbox_free() >= SEGMENT_ROOM) {
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
        reset_armed_ = false;  // the host armed a reset at rest, not this
        board_.position_record(start, false, false);  // a reset mid-move leaves it unknown
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
    if (stopping_) {
        feed_steps();
        if (planner_.finished() && !board_.step_busy()) {
            stopping_ = false;
            record_position(board_.step_position());
            if (starting_) seg_t_us_ = now;
        }
    }
    if (writer_.outbox_free() >= SEGMENT_ROOM) {
        if (exec_ == EXEC_MOVE) {
            feed_steps();
            if (planner_.finished() && !board_.step_busy()) {
                record_position(board_.step_position());
                finish_segment(now);
            }
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
    if (exec_ != EXEC_MOVE && !stopping_) return;
    // Bounded, so a long ramp never starves the sampler and the serial port; poll()
    // calls this twice per pass. A ramp step is one ring entry (the ring holds ~16 ms
    // of them at the top rate), a cruise of up to 255 steps is one entry, so cruising
    // costs the loop almost nothing. No division per step (StepPlanner).
    const uint64_t now = board_.now_us();
    if (!board_.step_busy()) {  // (re)starting from idle: the lead starts from nothing
        burst_us_ = now;
        fed_ticks_ = 0;
    }
    const uint32_t elapsed = static_cast<uint32_t>(now - burst_us_) * (STEP_TICK_HZ / 1000000UL);
    const uint32_t max_run_q8 = STEP_MAX_RUN_INTERVAL_TICKS << 8;
    for (uint8_t n = 0; n < FEED_RUNS_PER_CALL && !planner_.finished() && board_.step_space() > 0; ++n) {
        if (static_cast<int32_t>(fed_ticks_ - elapsed) >= static_cast<int32_t>(STEP_LOOKAHEAD_US * (STEP_TICK_HZ / 1000000UL)))
            break;
        uint32_t q8 = 0;
        int16_t add = 0;
        uint8_t count = planner_.next_run(q8, add, 255);
        // Slow steps (longer than the generator takes in a run) go one at a time: the
        // board chains each over several timer periods.
        if (count > 1 && (q8 > max_run_q8 || static_cast<int32_t>(q8) + static_cast<int32_t>(add) * (count - 1) >
                                                  static_cast<int32_t>(max_run_q8))) {
            planner_.rewind(count - 1u);
            count = 1;
            add = 0;
        }
        if (!board_.step_push(move_dir_, q8, add, count, planner_.finished())) {
            planner_.rewind(count);  // no room for its chain yet: again on a later pass
            break;
        }
        last_run_q8_ = q8;
        // the run's time: count q8 + add count (count - 1) / 2, in whole ticks
        if (count == 1) {
            fed_ticks_ += q8 >> 8;
        } else {
            const uint16_t pairs = static_cast<uint16_t>((static_cast<uint16_t>(count) * (count - 1)) >> 1);
            fed_ticks_ += static_cast<uint32_t>(static_cast<int32_t>(q8 >> 8) * count +
                                                ((static_cast<int32_t>(add) * pairs) >> 8));
        }
    }
}

// STOP and the host watchdog: queue cleared, heater off, the running move (if any)
// decelerates at the device's limit; rest_steps_ is where the motor ends up.
void Device::controlled_stop() {
    queue_.clear();
    starting_ = false;
    set_heater(0);
    if (exec_ == EXEC_MOVE) {
        int32_t rest = 0;
        // keep about STOP_KEEP_US of steps at the present speed (the last run's interval)
        const uint32_t ticks = last_run_q8_ >> 8;
        uint32_t keep = ticks ? cfg::STOP_KEEP_US * (STEP_TICK_HZ / 1000000UL) / ticks : 0;
        keep = keep < cfg::STOP_KEEP_STEPS ? cfg::STOP_KEEP_STEPS : keep > cfg::STOP_KEEP_MAX_STEPS ? cfg::STOP_KEEP_MAX_STEPS : keep;
        const uint32_t dropped = board_.step_truncate(static_cast<uint8_t>(keep), rest);
        planner_.rewind(dropped);
        const uint32_t left = planner_.stop(cfg::MAX_ACCEL_STEPS_PER_S2);
        // Slow enough to stop at once: the steps kept end the train, and its running dry
        // is no underrun (it was reported as one).
        if (left == 0) board_.step_end_train();
        rest_steps_ = rest + (move_dir_ > 0 ? static_cast<int32_t>(left) : -static_cast<int32_t>(left));
        // The dropped steps' time is gone from the ring: feed the deceleration at once.
        fed_ticks_ = static_cast<uint32_t>(board_.now_us() - burst_us_) * (STEP_TICK_HZ / 1000000UL);
        stopping_ = true;
        exec_ = EXEC_NONE;
        feed_steps();
    } else if (!stopping_) {
        exec_ = EXEC_NONE;
        rest_steps_ = board_.step_position();
    }
    projected_ = rest_steps_;
}

// Instant halt (a planner or driver bug): steps may be lost at speed, so a move cut
// short leaves the position unknown.
void Device::halt_now() {
    const bool was_moving = exec_ == EXEC_MOVE || stopping_;
    board_.step_halt();
    planner_.abort();
    exec_ = EXEC_NONE;
    stopping_ = false;
    starting_ = false;
    queue_.clear();
    set_heater(0);
    rest_steps_ = projected_ = board_.step_position();
    if (was_moving) position_known_ = false;
    record_position(rest_steps_);
}

void Device::clear_queue() {
    queue_.clear();
    projected_ = exec_ == EXEC_MOVE ? move_target_ : (stopping_ ? rest_steps_ : board_.step_position());
}

void Device::trip(uint8_t code, uint64_t now, bool controlled) {
    if (controlled) {
        controlled_stop();
    } else {
        halt_now();
    }
    fault_ = code;
    fault_since_us_ = now;
    send_event_value(now, proto::event_kind::FAULT, code, rest_steps_);
}

// A fault outlasted cfg::FAULT_RELEASE_MS: de-energize the motor (the strings may turn
// it: position unknown), stop sampling and the sense current.
void Device::release_motor(uint64_t now) {
    board_.motor_enable(false);
    motor_released_ = true;
    position_known_ = false;
    reset_armed_ = false;
    record_position(board_.step_position());
    set_sampling(0, now);
    abort_resistance();
    sense_off();
    send_event(now, proto::event_kind::MOTOR_RELEASED, fault_);
}

void Device::set_heater(uint16_t mV) {
    // Never rely on the driver's interlock alone: the sense current goes off first.
    if (mV > 0) abort_resistance();
    heater_mV_ = board_.heater_set_mV(mV);
}

void Device::set_position(int32_t steps) {
    board_.step_set_position(steps);
    position_known_ = true;
    position_suspect_ = false;
    projected_ = rest_steps_ = steps;
    record_position(steps);
}

void Device::check_safety(uint64_t now) {
    if (exec_ == EXEC_MOVE || stopping_) {
        // Unreachable with validated targets; guards against a planner or driver bug.
        int32_t pos = board_.step_position();
        if ((move_dir_ > 0 && pos > cfg::MAX_TWIST_STEPS) || (move_dir_ < 0 && pos < cfg::MIN_TWIST_STEPS)) {
            trip(proto::fault::TWIST_LIMIT, now, false);
        }
    }
    if (!fault_ && watchdog_armed() && now - last_host_us_ >= static_cast<uint64_t>(cfg::WATCHDOG_MS) * 1000U) {
        trip(proto::fault::WATCHDOG, now, true);
    }
    if (fault_ && !motor_released_ && !stopping_ && cfg::FAULT_RELEASE_MS > 0 &&
        now - fault_since_us_ >= static_cast<uint64_t>(cfg::FAULT_RELEASE_MS) * 1000U) {
        release_motor(now);
    }
    if (heater_mV_ > 0 && sense_on_) abort_resistance();
}

}  // namespace fw
