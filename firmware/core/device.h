// Device: the bench firmware's protocol dispatcher, segment executor, sampler and
// safety logic, on top of a Board. Behaves as host/tsa_bench/sim/device.py (the
// protocol's executable specification) except where real hardware differs: the end of
// a move is stamped when the core sees the last step done (poll granularity), not at
// the closed-form end; a SAMPLE is stamped with the time its position conversion
// actually started and leaves when its conversions finish; grid slots that pass while
// a conversion is still running are skipped with their counter values (a visible gap);
// SIM_SET_LOAD is an unknown message unless set_sim_load_handler() was called; sensor
// failures only flag the sample.
//
// Position. The step position is known only after SET_POSITION or when it survived a
// reset (Board::position_kept); until then MOVE_TO/MOVE_BY are refused (bad_state) and
// QUEUE_STATUS says position_unknown. A move marks the persisted record invalid while
// it runs, so a reset mid-move leaves the position unknown.
//
// Stopping. STOP and the host watchdog stop the motor under control: the queued steps
// beyond about cfg::STOP_KEEP_US of them (2..16 steps) are dropped and replaced by a deceleration at
// cfg::MAX_ACCEL_STEPS_PER_S2 (StepPlanner::stop); EVENT stopped (or fault) carries the
// position the motor comes to rest at, and nothing new starts before it is there. The
// twist-limit guard halts at once (a planner bug) and makes the position unknown. A
// fault that stays latched for cfg::FAULT_RELEASE_MS releases the motor (position
// unknown), turns sampling and the sense current off (EVENT motor_released);
// CLEAR_QUEUE re-energizes it.
//
// Position trust. A position survives a reset only when the host armed it (ARM_RESET:
// it is about to reopen the port, which resets a Mega) and the board says the record
// held (Board::position_kept); a move disarms it. A step underrun above the start/stop
// speed makes the position suspect (EVENT position_suspect, QUEUE_STATUS state bit)
// until SET_POSITION.
//
// Contract. boot() once, then poll() forever from the main loop; poll() never blocks
// and its passes are short slices: it handles at most FRAMES_PER_PASS host frames
// (RX_BUDGET bytes), feeding steps after each, pushes step runs until
// STEP_LOOKAHEAD_US of steps are queued or the board's ring is full, advances the
// executor, the watchdog and the sampler state machine, flushes output, and kicks the
// hardware watchdog. The longest pass since the previous QUEUE_STATUS is reported in
// it (max_pass_us). Everything here runs in the main loop:
// nothing in the core is shared with an interrupt; multi-byte state the step and
// serial ISRs touch lives behind the Board, which reads it atomically.
// Backpressure instead of loss: host bytes are left in the RX ring while the outbox
// lacks room for a command's replies, and the executor waits for room before starting
// a segment, so ACKs and EVENTs are never dropped; only SAMPLEs can be. Meanwhile a
// second parser scans the waiting bytes (without consuming them) for a STOP: found, it
// acts at once, the bytes up to it are dropped (commands sent before a STOP must not
// run after it; they get no ACK), and its ACK and EVENT stopped follow when there is
// room.
#pragma once
#include <stdint.h>

#include "board.h"
#include "cmd_queue.h"
#include "frame.h"
#include "planner.h"
#include "protocol_catalogue.h"
#include "sample_block.h"
#include "writer.h"

namespace fw {

static const uint16_t NO_SEGMENT = 0xFFFF;

typedef void (*SimLoadHandler)(void* ctx, uint32_t load_mg);

// Most step runs (entries) feed_steps() hands to the step ring per call (see device_exec.cpp).
static const uint8_t FEED_RUNS_PER_CALL = 4;
// feed_steps() keeps this much step time queued ahead of the step generator, no more:
// the ring (128 entries, ~8 ms of single ramp steps at the top rate) is never filled in one
// go at a move's start, so the work per pass stays proportional to the steps taken.
static const uint32_t STEP_LOOKAHEAD_US = 10000UL;

class Device {
public:
    static const uint8_t RX_BUDGET = 64;
    static const uint8_t FRAMES_PER_PASS = 2;

    explicit Device(Board& board);
    void boot();
    void poll();
    // Simulated benches only: IDENTITY gets the SIMULATED flag and SIM_SET_LOAD is
    // accepted and handed to fn; without a handler SIM_SET_LOAD is an unknown message.
    void set_sim_load_handler(SimLoadHandler fn, void* ctx);

    uint8_t fault() const { return fault_; }
    bool executing() const { return exec_ != EXEC_NONE; }
    bool stopping() const { return stopping_; }
    bool position_known() const { return position_known_; }
    bool motor_released() const { return motor_released_; }
    // Something runs that the host must supervise: a segment, the queue, the heater, a stop.
    bool active() const { return exec_ != EXEC_NONE || !queue_.empty() || heater_mV_ > 0 || stopping_; }
    // Host silence trips the watchdog while active or sampling (the sense current is on).
    bool watchdog_armed() const { return active() || period_us_ > 0; }
    uint8_t queue_free() const { return queue_.free(); }
    uint16_t heater_mV() const { return heater_mV_; }
    uint16_t segment() const { return segment_; }
    int32_t projected_steps() const { return projected_; }
    uint32_t sampling_period_us() const { return period_us_; }
    uint8_t state() const;
    const FrameErrors& frame_errors() const { return parser_.errors(); }
    uint32_t duplicates() const { return duplicates_; }
    uint32_t samples_dropped() const { return writer_.dropped() + samples_missed_; }
    uint32_t urgent_lost() const { return writer_.urgent_lost(); }
    uint32_t stops_found_waiting() const { return stops_found_; }
    bool position_suspect() const { return position_suspect_; }
    uint16_t sensor_restarts() const { return sensor_restarts_; }
    uint32_t sensor_period_ns() const { return sensor_period_ns_; }

private:
    enum Exec { EXEC_NONE, EXEC_MOVE, EXEC_DWELL };
    enum SamplerState { SAMPLER_IDLE, SAMPLER_BUSY };

    // device.cpp: frames and commands
    void read_serial(uint64_t now);
    bool host_may_speak();
    void scan_for_stop(uint64_t now);
    void handle_frame(uint64_t now, uint8_t id, uint16_t seq, const uint8_t* p, uint8_t len);
    void handle_hello();
    uint8_t check(uint8_t id, const uint8_t* p) const;
    void apply(uint8_t id, const uint8_t* p, uint64_t now);
    void send_ack(uint8_t slot, uint16_t seq, uint8_t id, uint8_t status);
    void send_queue_status(uint64_t now);
    void send_event(uint64_t t_us, uint8_t kind, uint16_t code);
    void send_event_value(uint64_t t_us, uint8_t kind, uint16_t code, int32_t value);
    void report_counters(uint64_t now);
    void record_position(int32_t steps);

    // device_exec.cpp: queue, segments, motion, safety
    void push(const QueuedCommand& c, uint64_t now);
    void run_executor(uint64_t now);
    void start_segments();
    bool begin(const QueuedCommand& c);
    void finish_segment(uint64_t t_us);
    void feed_steps();
    void controlled_stop();
    void halt_now();
    void clear_queue();
    void trip(uint8_t code, uint64_t now, bool controlled);
    void release_motor(uint64_t now);
    void set_heater(uint16_t mV);
    void set_position(int32_t steps);
    void check_safety(uint64_t now);

    // device_sample.cpp: the sampling grid and the conversions
    void set_sampling(uint32_t period_us, uint64_t t_us);
    void run_sampler(uint64_t now);
    bool sample_due(uint64_t now);
    void start_sample(uint64_t now);
    void progress_sample(uint64_t now);
    void run_continuous(uint64_t now);
    void continuous_on(uint64_t now);
    void arm_continuous(uint64_t now);
    void restart_continuous(uint64_t now);
    void measure_period(uint16_t new_edges, uint64_t last_edge_us);
    void take_conversion(const ConvSample& c);
    void progress_words(uint64_t now);
    void continuous_off();
    void flush_block();
    void retry_block();
    void finish_resistance(uint8_t extra_flags);
    void abort_resistance();
    void sense_off();

    Board& board_;
    FrameParser parser_;
    FrameWriter writer_;
    CommandQueue queue_;
    StepPlanner planner_;
    SimLoadHandler sim_load_;
    void* sim_ctx_;

    // duplicate filter: the last accepted command and its ACK
    bool has_last_;
    uint16_t last_seq_;
    uint8_t last_id_;
    proto::Ack last_ack_;
    uint32_t duplicates_;
    uint64_t last_host_us_;

    // STOP while the outbox is full: a second parser over the bytes still waiting
    FrameParser scanner_;
    uint16_t scan_offset_;   // bytes past the next unread one the scanner has seen
    bool stop_owed_;         // a STOP acted on; its ACK and EVENT wait for room
    uint16_t stop_seq_;
    uint32_t stops_found_;

    // executor
    uint64_t burst_us_;     // when the step generator last started from idle
    uint32_t last_run_q8_;  // the first interval of the run pushed last (the present speed)
    uint32_t fed_ticks_;    // step time handed to it since then, STEP_TICK_HZ ticks
    Exec exec_;
    bool starting_;         // idle with segments (or QUEUE_EMPTY) still to start/report
    uint16_t segment_;
    int32_t projected_;
    int32_t move_target_;
    int8_t move_dir_;
    uint64_t seg_t_us_;     // when the current segment started (or the last one ended)
    uint32_t dwell_us_;
    uint16_t heater_mV_;    // equivalent voltage applied (after the PWM's rounding)
    uint8_t fault_;
    uint64_t fault_since_us_;
    bool stopping_;         // a controlled stop's deceleration is still running
    int32_t rest_steps_;    // where the motor comes to rest after a controlled stop
    bool position_known_;
    bool position_suspect_;  // a fast underrun since the position was last set
    bool reset_armed_;       // ARM_RESET: the record may keep the position across the next reset
    bool motor_released_;
    uint16_t underruns_seen_;
    uint16_t fast_underruns_seen_;
    uint16_t recoveries_seen_;
    uint16_t max_pass_us_;   // longest poll() since the last QUEUE_STATUS

    // sampler
    uint32_t period_us_;
    uint64_t next_sample_us_;
    uint32_t counter_;
    uint32_t samples_missed_;
    SamplerState sampler_;
    proto::Sample sample_;
    bool position_done_;
    bool resistance_done_;
    bool resistance_started_;
    bool sense_on_;
    uint64_t sense_since_us_;
    uint64_t sample_start_us_;
    uint64_t conversion_us_;  // resistance conversion started at
    // continuous sampler (periods below cfg::SINGLE_SHOT_MIN_PERIOD_US)
    bool continuous_;
    bool continuous_ok_;      // the ADS1115 took continuous mode and its edges are stamped
    bool in_outage_;          // no edge for a while: restarts under way
    bool sensor_event_owed_;  // EVENT sensor_restarted waits for outbox room
    bool resume_gap_;         // the next sample follows a restart: count the conversions lost
    bool have_last_stamp_;
    uint8_t conv_per_sample_;
    uint16_t sensor_restarts_;
    bool have_edge_;          // an edge came since the last set-up
    uint16_t edges_seen_;     // the board's edge count (wraps)
    uint32_t period_edges_;   // edges since the period's reference (0: no reference yet)
    uint32_t sensor_period_ns_;
    uint64_t period_ref_us_;
    uint64_t last_alive_us_;  // the last edge (or when continuous sampling began)
    uint64_t armed_at_us_;    // the last set-up of the ADS1115
    uint64_t last_stamp_us_;  // the last sample's t_us
    bool word_armed_;         // a CS5513 measurement is armed
    bool word_ready_;         // a CS5513 word waits for the next sample
    int32_t word_counts_;
    uint8_t word_flags_;
    SampleBlockBuilder block_;
    // a closed block the line had no room for yet (sent on a later pass; dropped only
    // when the next block closes first)
    uint8_t pending_[proto::SampleBlock::SIZE + proto::SampleBlock::MAX_ENTRIES * proto::SampleBlock::ENTRY_SIZE];
    uint8_t pending_len_;
    uint8_t pending_samples_;
};

}  // namespace fw
