// Device, part 1: boot, the poll loop, frame dispatch, validation (see device.h).
#include "device.h"

#include "config.h"

namespace fw {

static_assert(FrameWriter::SLOT_PAYLOAD >= proto::Identity::SIZE && FrameWriter::SLOT_PAYLOAD >= proto::QueueStatus::SIZE &&
                  FrameWriter::SLOT_PAYLOAD >= proto::Event::SIZE,
              "every urgent message fits an outbox slot");

namespace {
// Outbox room needed before a host frame is handled: its ACK plus the most events one
// command causes (SEGMENT_STARTED, SEGMENT_DONE, QUEUE_EMPTY), plus a reserve for a
// FAULT raised in the same poll.
const uint8_t RX_ROOM = 6;
// Outbox room needed to report a counter event (underrun, I2C recovery).
const uint8_t COUNTER_ROOM = 8;
// TX ring room kept for sample blocks while sampling continuously: two full blocks.
const uint16_t SAMPLE_TX_RESERVE =
    2 * frame_wire_bytes(proto::SampleBlock::SIZE + proto::SampleBlock::MAX_ENTRIES * proto::SampleBlock::ENTRY_SIZE);
}  // namespace

Device::Device(Board& board)
    : board_(board), writer_(board), sim_load_(0), sim_ctx_(0), has_last_(false), last_seq_(0),
      last_id_(0), duplicates_(0), last_host_us_(0), scan_offset_(0), stop_owed_(false), stop_seq_(0),
      stops_found_(0), burst_us_(0), last_run_q8_(0), fed_ticks_(0), exec_(EXEC_NONE), starting_(false),
      segment_(NO_SEGMENT), projected_(0), move_target_(0), move_dir_(0), seg_t_us_(0), dwell_us_(0),
      heater_mV_(0), fault_(0), fault_since_us_(0), stopping_(false), rest_steps_(0), position_known_(false),
      position_suspect_(false), reset_armed_(false), motor_released_(false), underruns_seen_(0),
      fast_underruns_seen_(0), recoveries_seen_(0), max_pass_us_(0), period_us_(0), next_sample_us_(0),
      counter_(0), samples_missed_(0), sampler_(SAMPLER_IDLE), position_done_(true), resistance_done_(true),
      resistance_started_(false), sense_on_(false), sense_since_us_(0), sample_start_us_(0), conversion_us_(0),
      continuous_(false), continuous_ok_(false), in_outage_(false), sensor_event_owed_(false),
      resume_gap_(false), have_last_stamp_(false), conv_per_sample_(1), sensor_restarts_(0), have_edge_(false),
      edges_seen_(0), period_edges_(0), sensor_period_ns_(0), period_ref_us_(0), last_alive_us_(0), armed_at_us_(0),
      last_stamp_us_(0), word_armed_(false), word_ready_(false), word_counts_(0), word_flags_(0), pending_len_(0),
      pending_samples_(0) {
    last_ack_ = proto::Ack();
    sample_ = proto::Sample();
}

void Device::set_sim_load_handler(SimLoadHandler fn, void* ctx) {
    sim_load_ = fn;
    sim_ctx_ = ctx;
}

void Device::boot() {
    board_.heater_set_mV(0);
    board_.sense_current(false);
    board_.step_halt();
    int32_t kept = 0;
    position_known_ = board_.position_kept(kept);
    board_.step_set_position(position_known_ ? kept : 0);
    projected_ = board_.step_position();
    record_position(projected_);  // the arm was for the reset that just happened: spent
    board_.motor_enable(true);  // holding torque keeps the strings' twist under load
    underruns_seen_ = board_.step_underruns();
    fast_underruns_seen_ = board_.step_fast_underruns();
    recoveries_seen_ = board_.i2c_recoveries();
    last_host_us_ = board_.now_us();
    // A reset can cut a frame short on the wire: a lone delimiter first ends it on the
    // host's side, so the BOOT that follows is not swallowed by it (found in simavr).
    const uint8_t delimiter = 0;
    board_.serial_write(&delimiter, 1);
    proto::Boot m;
    m.fw_major = cfg::FW_MAJOR;
    m.fw_minor = cfg::FW_MINOR;
    m.fw_patch = cfg::FW_PATCH;
    m.reason = board_.boot_reason();
    uint8_t p[proto::Boot::SIZE];
    writer_.send(proto::Boot::ID, p, proto::pack(m, p));
}

void Device::poll() {
    const uint64_t start = board_.now_us();
    board_.kick_hw_watchdog();
    feed_steps();
    read_serial(start);
    uint64_t now = board_.now_us();
    run_executor(now);
    check_safety(now);
    feed_steps();
    run_sampler(now);
    report_counters(now);
    writer_.flush();
    const uint64_t pass = board_.now_us() - start;
    if (pass > max_pass_us_) max_pass_us_ = pass > 0xFFFF ? 0xFFFF : static_cast<uint16_t>(pass);
}

// A host frame may be handled now: the outbox has room for its replies, and while
// sampling continuously no block waits for the line and the TX ring keeps room for two
// blocks, so replies never take the samples' share of the line.
bool Device::host_may_speak() {
    if (writer_.outbox_free() < RX_ROOM) return false;
    if (!continuous_) return true;
    return pending_len_ == 0 && board_.serial_tx_free() >= SAMPLE_TX_RESERVE;
}

void Device::record_position(int32_t steps) { board_.position_record(steps, position_known_, reset_armed_); }

uint8_t Device::state() const {
    uint8_t s = 0;
    if (!position_known_) s |= proto::device_state::POSITION_UNKNOWN;
    if (position_suspect_) s |= proto::device_state::POSITION_SUSPECT;
    if (motor_released_) s |= proto::device_state::MOTOR_RELEASED;
    if (stopping_) s |= proto::device_state::STOPPING;
    return s;
}

void Device::read_serial(uint64_t now) {
    // Host frames wait while the outbox lacks room for their replies, and while a
    // sample block waits for the line: a burst of commands must not crowd the samples
    // off it. A STOP among the waiting bytes is acted on all the same.
    if (!host_may_speak()) {
        scan_for_stop(now);
        return;
    }
    if (stop_owed_) {
        stop_owed_ = false;
        send_ack(writer_.reserve(), stop_seq_, proto::Stop::ID, proto::status::OK);
        send_event_value(now, proto::event_kind::STOPPED, 0, rest_steps_);
    }
    scan_offset_ = 0;
    scanner_.reset();
    uint8_t frames = 0;
    const uint32_t now32 = static_cast<uint32_t>(now);
    for (uint8_t n = 0; n < RX_BUDGET && frames < FRAMES_PER_PASS; ++n) {
        if (!host_may_speak()) return;
        int16_t c = board_.serial_read();
        if (c < 0) return;
        if (parser_.feed(static_cast<uint8_t>(c), now32)) {
            last_host_us_ = now;
            ++frames;
            handle_frame(now, parser_.msg_id(), parser_.seq(), parser_.payload(), parser_.payload_len());
            feed_steps();  // a frame's work may have taken a while: keep the ring fed
        }
    }
}

// The outbox is full, so host bytes wait in the RX ring; a STOP among them must not
// wait. The scanner parses them in place, picking up where it left off.
void Device::scan_for_stop(uint64_t now) {
    const uint32_t now32 = static_cast<uint32_t>(now);
    for (uint8_t n = 0; n < RX_BUDGET; ++n) {
        const int16_t c = board_.serial_peek(scan_offset_);
        if (c < 0) return;
        ++scan_offset_;
        if (!scanner_.feed(static_cast<uint8_t>(c), now32)) continue;
        if (scanner_.msg_id() != proto::Stop::ID || scanner_.payload_len() != 0) continue;
        stop_seq_ = scanner_.seq();
        stop_owed_ = true;
        board_.serial_skip(scan_offset_);  // what came before the STOP never runs
        parser_.reset();
        scanner_.reset();
        scan_offset_ = 0;
        last_host_us_ = now;
        ++stops_found_;
        controlled_stop();
        return;
    }
}

void Device::handle_frame(uint64_t now, uint8_t id, uint16_t seq, const uint8_t* p, uint8_t len) {
    const bool known = id < 0x80 && proto::payload_size(id) >= 0 &&
                       (id != proto::SimSetLoad::ID || sim_load_ != 0);
    if (!known) {
        send_ack(writer_.reserve(), seq, id, proto::status::UNKNOWN_MESSAGE);
        return;
    }
    if (len != proto::payload_size(id)) {
        send_ack(writer_.reserve(), seq, id, proto::status::BAD_LENGTH);
        return;
    }
    if (id == proto::Hello::ID) {
        proto::Hello h;
        proto::unpack(p, h);
        if (h.protocol_version != proto::PROTOCOL_VERSION || h.catalogue_hash != proto::CATALOGUE_HASH) {
            // Not an accepted command: the duplicate filter is left alone.
            proto::Ack a;
            a.acked_seq = seq;
            a.acked_id = id;
            a.status = proto::status::BAD_ARGUMENT;
            a.queue_free = queue_.free();
            uint8_t buf[proto::Ack::SIZE];
            writer_.send(proto::Ack::ID, buf, proto::pack(a, buf));
            return;
        }
        handle_hello();
        return;
    }
    if (has_last_ && last_seq_ == seq && last_id_ == id) {
        ++duplicates_;
        uint8_t buf[proto::Ack::SIZE];
        writer_.send(proto::Ack::ID, buf, proto::pack(last_ack_, buf));
        if (id == proto::Heartbeat::ID) send_queue_status(now);
        return;
    }
    uint8_t status = check(id, p);
    uint8_t slot = writer_.reserve();  // the ACK precedes the events apply() sends
    if (status == proto::status::OK) apply(id, p, now);
    send_ack(slot, seq, id, status);
}

void Device::handle_hello() {
    has_last_ = false;
    proto::Identity m;
    m.protocol_version = proto::PROTOCOL_VERSION;
    m.fw_major = cfg::FW_MAJOR;
    m.fw_minor = cfg::FW_MINOR;
    m.fw_patch = cfg::FW_PATCH;
    m.catalogue_hash = proto::CATALOGUE_HASH;
    m.steps_per_turn = cfg::STEPS_PER_TURN;
    m.min_twist_steps = cfg::MIN_TWIST_STEPS;
    m.max_twist_steps = cfg::MAX_TWIST_STEPS;
    m.max_rate_steps_per_s = cfg::MAX_RATE_STEPS_PER_S;
    m.max_accel_steps_per_s2 = cfg::MAX_ACCEL_STEPS_PER_S2;
    m.max_heater_mV = cfg::MAX_HEATER_MV;
    m.queue_slots = cfg::QUEUE_SLOTS;
    m.watchdog_ms = cfg::WATCHDOG_MS;
    m.flags = sim_load_ ? proto::device_flags::SIMULATED : 0;
    m.min_sample_period_us = cfg::MIN_SAMPLE_PERIOD_US;
    m.fault_release_ms = cfg::FAULT_RELEASE_MS;
    uint8_t buf[proto::Identity::SIZE];
    writer_.send(proto::Identity::ID, buf, proto::pack(m, buf));
}

// Same order as the simulated device: BAD_STATE, BAD_ARGUMENT, LIMIT_EXCEEDED, QUEUE_FULL.
uint8_t Device::check(uint8_t id, const uint8_t* p) const {
    if (id == proto::SetPosition::ID) {
        if (exec_ == EXEC_MOVE || stopping_ || queue_.has_move() || motor_released_) return proto::status::BAD_STATE;
        proto::SetPosition m;
        proto::unpack(p, m);
        if (m.position_steps < cfg::MIN_TWIST_STEPS || m.position_steps > cfg::MAX_TWIST_STEPS)
            return proto::status::LIMIT_EXCEEDED;
        return proto::status::OK;
    }
    if (id == proto::ArmReset::ID) {
        if (!position_known_ || exec_ == EXEC_MOVE || stopping_ || queue_.has_move() || motor_released_)
            return proto::status::BAD_STATE;
        return proto::status::OK;
    }
    if (!proto::is_queued(id)) return proto::status::OK;
    if (fault_) return proto::status::BAD_STATE;
    if (id == proto::MoveTo::ID || id == proto::MoveBy::ID) {
        if (!position_known_) return proto::status::BAD_STATE;
        proto::MoveTo m;  // MOVE_BY has the same layout (delta in target_steps)
        proto::unpack(p, m);
        if (m.rate_steps_per_s == 0 || m.accel_steps_per_s2 == 0) return proto::status::BAD_ARGUMENT;
        if (m.rate_steps_per_s > cfg::MAX_RATE_STEPS_PER_S || m.accel_steps_per_s2 > cfg::MAX_ACCEL_STEPS_PER_S2)
            return proto::status::LIMIT_EXCEEDED;
        int64_t target = m.target_steps;
        if (id == proto::MoveBy::ID) target += projected_;
        if (target < cfg::MIN_TWIST_STEPS || target > cfg::MAX_TWIST_STEPS) return proto::status::LIMIT_EXCEEDED;
    } else if (id == proto::SetHeater::ID) {
        proto::SetHeater m;
        proto::unpack(p, m);
        if (m.voltage_mV > cfg::MAX_HEATER_MV) return proto::status::LIMIT_EXCEEDED;
    } else if (id == proto::SetSampling::ID) {
        proto::SetSampling m;
        proto::unpack(p, m);
        const uint8_t refusal = sampling_refusal(m.period_us, cfg::BAUD);
        if (refusal != proto::status::OK) return refusal;
    }
    if (queue_.free() == 0) return proto::status::QUEUE_FULL;
    return proto::status::OK;
}

void Device::apply(uint8_t id, const uint8_t* p, uint64_t now) {
    switch (id) {
    case proto::Heartbeat::ID:
        send_queue_status(now);
        return;
    case proto::Stop::ID:
        controlled_stop();
        send_event_value(now, proto::event_kind::STOPPED, 0, rest_steps_);
        return;
    case proto::ClearQueue::ID:
        clear_queue();
        if (fault_) {
            uint8_t code = fault_;
            fault_ = 0;
            if (motor_released_) {
                board_.motor_enable(true);
                motor_released_ = false;
            }
            send_event(now, proto::event_kind::FAULT_CLEARED, code);
        }
        return;
    case proto::SimSetLoad::ID: {
        proto::SimSetLoad m;
        proto::unpack(p, m);
        if (sim_load_) sim_load_(sim_ctx_, m.load_mg);
        return;
    }
    case proto::SetPosition::ID: {
        proto::SetPosition m;
        proto::unpack(p, m);
        set_position(m.position_steps);
        return;
    }
    case proto::ArmReset::ID:
        reset_armed_ = true;
        record_position(board_.step_position());
        return;
    default:
        break;
    }
    QueuedCommand c;
    c.msg_id = id;
    c.steps = 0;
    c.value = 0;
    c.accel = 0;
    if (id == proto::MoveTo::ID || id == proto::MoveBy::ID) {
        proto::MoveTo m;
        proto::unpack(p, m);
        c.segment = m.segment;
        c.steps = m.target_steps;
        c.value = m.rate_steps_per_s;
        c.accel = m.accel_steps_per_s2;
    } else if (id == proto::Dwell::ID) {
        proto::Dwell m;
        proto::unpack(p, m);
        c.segment = m.segment;
        c.value = m.duration_us;
    } else if (id == proto::SetHeater::ID) {
        proto::SetHeater m;
        proto::unpack(p, m);
        c.segment = m.segment;
        c.value = m.voltage_mV;
    } else {
        proto::SetSampling m;
        proto::unpack(p, m);
        c.segment = m.segment;
        c.value = m.period_us;
    }
    push(c, now);
}

void Device::send_ack(uint8_t slot, uint16_t seq, uint8_t id, uint8_t status) {
    proto::Ack a;
    a.acked_seq = seq;
    a.acked_id = id;
    a.status = status;
    a.queue_free = queue_.free();
    uint8_t buf[proto::Ack::SIZE];
    writer_.fill(slot, proto::Ack::ID, buf, proto::pack(a, buf));
    writer_.flush();
    // A refused command had no effect, so its repetition is simply evaluated again.
    has_last_ = status == proto::status::OK;
    if (has_last_) {
        last_seq_ = seq;
        last_id_ = id;
        last_ack_ = a;
    }
}

void Device::send_queue_status(uint64_t now) {
    proto::QueueStatus m;
    m.t_us = now;
    m.queue_free = queue_.free();
    m.executing = exec_ != EXEC_NONE ? 1 : 0;
    m.segment = segment_;
    m.fault = fault_;
    m.state = state();
    m.step_position = board_.step_position();
    m.step_underruns = board_.step_underruns();
    m.uart_overruns = board_.uart_overruns();
    m.uart_frame_errors = board_.uart_frame_errors();
    m.i2c_recoveries = board_.i2c_recoveries();
    m.max_pass_us = max_pass_us_;
    max_pass_us_ = 0;
    m.sensor_period_ns = continuous_ ? sensor_period_ns_ : 0;
    m.sensor_restarts = sensor_restarts_;
    uint8_t buf[proto::QueueStatus::SIZE];
    writer_.send(proto::QueueStatus::ID, buf, proto::pack(m, buf));
}

void Device::send_event(uint64_t t_us, uint8_t kind, uint16_t code) {
    send_event_value(t_us, kind, code, board_.step_position());
}

void Device::send_event_value(uint64_t t_us, uint8_t kind, uint16_t code, int32_t value) {
    proto::Event m;
    m.t_us = t_us;
    m.kind = kind;
    m.segment = segment_;
    m.code = code;
    m.value = value;
    uint8_t buf[proto::Event::SIZE];
    writer_.send(proto::Event::ID, buf, proto::pack(m, buf));
}

// Counters the board keeps (step underruns, I2C recoveries) become EVENTs when they
// move; so do the sampler's restarts (once per outage). An underrun above the
// start/stop speed makes the position suspect.
void Device::report_counters(uint64_t now) {
    if (writer_.outbox_free() < COUNTER_ROOM) return;
    const uint16_t underruns = board_.step_underruns();
    if (underruns != underruns_seen_) {
        underruns_seen_ = underruns;
        send_event(now, proto::event_kind::STEP_UNDERRUN, underruns);
    }
    const uint16_t fast = board_.step_fast_underruns();
    if (fast != fast_underruns_seen_) {
        fast_underruns_seen_ = fast;
        position_suspect_ = true;
        send_event(now, proto::event_kind::POSITION_SUSPECT, fast);
    }
    if (sensor_event_owed_) {
        sensor_event_owed_ = false;
        send_event(now, proto::event_kind::SENSOR_RESTARTED, sensor_restarts_);
    }
    const uint16_t recoveries = board_.i2c_recoveries();
    if (recoveries != recoveries_seen_) {
        recoveries_seen_ = recoveries;
        send_event(now, proto::event_kind::I2C_RECOVERED, recoveries);
    }
}

}  // namespace fw
