// FakeBoard: a simulated Board for the native tests, the fuzz target and the native
// stdio device. Contract: time moves only when advance_us() is called; queued steps
// execute as that time passes (each at its interval after the previous edge, the first
// of a burst after its push); the serial line is a byte FIFO in (host_write) and a
// capture buffer out (take_tx), with an optional TX ring that drains at a given rate so
// tests can fill it; sensors return scripted values after scripted latencies, or fail.
// It also records what the core must never do (interlock violations, conversions
// without a settled sense current) so tests can assert on them. Fixed buffers only.
#pragma once
#include <stdint.h>

#include "board.h"

namespace fw {

class FakeBoard : public Board {
public:
    static const uint16_t RX_CAP = 4096;
    static const uint32_t TX_CAP = 65536;
    static const uint8_t STEP_RING_MAX = 64;

    FakeBoard();

    // --- test controls -----------------------------------------------------------
    void advance_us(uint64_t us);
    // Queues bytes as if the host had sent them; returns how many fitted.
    uint16_t host_write(const uint8_t* data, uint16_t n);
    uint16_t rx_pending() const { return rx_count_; }
    // Moves captured device output into out (up to cap bytes); returns the count.
    uint32_t take_tx(uint8_t* out, uint32_t cap);
    uint32_t tx_captured() const { return tx_len_; }

    // configuration (public fields: tests set them directly)
    uint8_t step_ring_size;        // 1..STEP_RING_MAX
    uint16_t tx_ring_size;         // serial_tx_free() when nothing is pending
    uint32_t tx_drain_bytes_per_ms;  // 0 = drains instantly
    uint8_t reason;
    int16_t position_counts;
    bool position_start_fails;
    bool position_poll_fails;
    uint32_t position_latency_us;
    uint32_t position_conversion_us;  // continuous mode: a conversion (ALERT/RDY pulse) every this long
    bool rdy_dead;                   // continuous mode: the ALERT/RDY edges never arrive (an unwired D2)
    uint8_t continuous_start_failures;  // the next this many continuous set-ups fail (a NACK)
    int32_t resistance_counts;
    uint8_t resistance_flags;
    bool resistance_start_fails;
    bool resistance_poll_fails;
    uint32_t resistance_latency_us;
    int32_t step_glitch;           // added to every executed step (simulates a lost step)
    bool kept_valid;               // position_kept(): the position survived a reset (false: power-on)
    int32_t kept_steps;
    uint16_t uart_overrun_count;   // counters the board reports
    uint16_t uart_frame_error_count;
    uint16_t i2c_recovery_count;

    // observations
    uint64_t now;
    int32_t position;
    int32_t min_position;
    int32_t max_position;
    uint32_t steps_executed;
    uint32_t min_interval_ticks;   // shortest interval pushed, whole ticks (excluding a burst's first)
    uint16_t heater_mV;              // equivalent voltage applied (the driver's duty scale)
    uint16_t heater_requested_mV;
    bool sense_on;
    bool motor_enabled;
    uint32_t kicks;
    uint32_t continuous_reads;       // continuous samples read (position_take)
    uint32_t continuous_setups;      // position_continuous(true, ...) calls
    uint16_t fast_underruns;         // underruns with the last step faster than the start/stop speed
    uint32_t long_steps;             // steps pushed alone beyond STEP_MAX_RUN_INTERVAL_TICKS
    static const uint32_t EDGE_LOG = 4096;
    uint64_t edge_t_us[EDGE_LOG];    // every ALERT/RDY edge (the true conversion starts) ...
    int32_t edge_position[EDGE_LOG]; // ... and the step position at it
    uint32_t edges_logged;
    uint32_t interlock_violations;   // heater switched on while sense current was on
    uint32_t sense_refusals;         // sense_current(true) refused (heater on)
    uint32_t unsettled_conversions;  // resistance started without a settled sense current
    uint32_t halts;
    uint16_t underruns;              // the ring ran dry while more steps were promised
    uint32_t truncations;
    int32_t record_steps;            // the last position_record()
    bool record_valid;
    bool record_armed;
    uint32_t record_writes;

    // --- Board ---------------------------------------------------------------------
    uint64_t now_us() override { return now; }
    int16_t serial_read() override;
    int16_t serial_peek(uint16_t offset) override;
    void serial_skip(uint16_t n) override;
    uint16_t serial_tx_free() override;
    uint16_t serial_write(const uint8_t* data, uint16_t n) override;
    void motor_enable(bool on) override { motor_enabled = on; }
    uint8_t step_space() override;
    bool step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last) override;
    bool step_busy() override { return step_count_ > 0; }
    // steps still to be emitted from the ring (every run's count)
    uint32_t steps_pending() const {
        uint32_t n = 0;
        for (uint8_t i = 0; i < step_count_; ++i) n += steps_[(step_head_ + i) % STEP_RING_MAX].count;
        return n;
    }
    int32_t step_position() override { return position; }
    void step_set_position(int32_t steps) override { position = steps; }
    void step_halt() override;
    uint32_t step_truncate(uint8_t keep, int32_t& rest_position) override;
    void step_end_train() override { expect_more_ = false; }
    uint16_t step_underruns() override { return underruns; }
    uint16_t step_fast_underruns() override { return fast_underruns; }
    uint16_t heater_set_mV(uint16_t mV) override;
    bool sense_current(bool on) override;
    bool position_start() override;
    bool position_continuous(bool on, uint8_t every) override;
    bool position_take(ConvSample& s) override;
    uint16_t position_edges(uint64_t& last_us) override;
    int8_t position_poll(int16_t& counts) override;
    bool resistance_start() override;
    int8_t resistance_poll(int32_t& counts, uint8_t& flags) override;
    uint8_t boot_reason() override { return reason; }
    void kick_hw_watchdog() override { ++kicks; }
    bool position_kept(int32_t& steps) override {
        steps = kept_steps;
        return kept_valid;
    }
    void position_record(int32_t steps, bool valid, bool armed) override {
        record_steps = steps;
        record_valid = valid;
        record_armed = armed;
        ++record_writes;
    }
    uint16_t uart_overruns() override { return uart_overrun_count; }
    uint16_t uart_frame_errors() override { return uart_frame_error_count; }
    uint16_t i2c_recoveries() override { return i2c_recovery_count; }

private:
    struct Step {  // a run of `count` steps: the next lasts q8 (1/256 tick), then q8 += add
        int8_t dir;
        uint32_t q8;
        int16_t add;
        uint8_t count;
    };
    uint8_t rx_[RX_CAP];
    uint16_t rx_head_, rx_count_;
    uint8_t tx_[TX_CAP];
    uint32_t tx_len_;
    uint64_t tx_pending_milli_;  // bytes not yet drained, in 1/1000 byte
    static const uint8_t CONV_SLOTS = 8;  // the AVR board's ring of continuous samples
    void run_steps_until(uint64_t tick);
    void conversion_edge(uint64_t t_us);
    Step steps_[STEP_RING_MAX];
    uint8_t step_head_, step_count_;
    uint64_t last_edge_tick_;
    uint8_t carry_;  // fraction of a tick carried to the next step
    int8_t dir_;
    bool expect_more_;
    bool position_busy_;
    uint64_t position_started_;
    bool resistance_busy_;
    uint64_t resistance_started_;
    uint64_t sense_since_;
    bool continuous_;
    uint64_t continuous_since_;
    uint64_t edges_done_;         // conversion edges since continuous_since_
    uint8_t every_, until_;
    bool have_prev_;
    uint64_t prev_us_;
    int32_t prev_pos_;
    uint64_t last_edge_us_;
    ConvSample conv_[CONV_SLOTS];
    uint8_t conv_head_, conv_count_, conv_lost_;
    uint32_t last_interval_ticks_;
};

}  // namespace fw
