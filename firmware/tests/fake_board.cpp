#include "fake_board.h"

#include <string.h>

#include "config.h"
#include "../drivers/heater_scale.h"

namespace fw {

FakeBoard::FakeBoard()
    : step_ring_size(32), tx_ring_size(512), tx_drain_bytes_per_ms(0), reason(2), position_counts(1000),
      position_start_fails(false), position_poll_fails(false), position_latency_us(0), position_conversion_us(1163),
      rdy_dead(false), continuous_start_failures(0), resistance_counts(50000),
      resistance_flags(0), resistance_start_fails(false), resistance_poll_fails(false), resistance_latency_us(0),
      step_glitch(0), kept_valid(false), kept_steps(0), uart_overrun_count(0), uart_frame_error_count(0),
      i2c_recovery_count(0), now(0), position(0), min_position(0), max_position(0), steps_executed(0),
      min_interval_ticks(0xFFFFFFFFUL), heater_mV(0), heater_requested_mV(0), sense_on(false), motor_enabled(false),
      kicks(0), continuous_reads(0), continuous_setups(0), fast_underruns(0), long_steps(0), edges_logged(0),
      interlock_violations(0), sense_refusals(0), unsettled_conversions(0), halts(0), underruns(0),
      truncations(0), record_steps(0), record_valid(false), record_armed(false), record_writes(0), rx_head_(0), rx_count_(0),
      tx_len_(0), tx_pending_milli_(0), step_head_(0), step_count_(0), last_edge_tick_(0), carry_(0), dir_(1),
      expect_more_(false), position_busy_(false),
      position_started_(0), resistance_busy_(false), resistance_started_(0), sense_since_(0), continuous_(false),
      continuous_since_(0), edges_done_(0), every_(1), until_(1), have_prev_(false), prev_us_(0), prev_pos_(0),
      last_edge_us_(0), conv_head_(0), conv_count_(0), conv_lost_(0), last_interval_ticks_(0) {}

void FakeBoard::run_steps_until(uint64_t target_tick) {
    while (step_count_ > 0) {
        Step& s = steps_[step_head_];
        const uint32_t sum = s.q8 + carry_;
        if (last_edge_tick_ + (sum >> 8) > target_tick) break;
        last_edge_tick_ += sum >> 8;
        last_interval_ticks_ = sum >> 8;
        carry_ = static_cast<uint8_t>(sum & 0xFF);
        s.q8 += s.add;
        position += s.dir + (s.dir > 0 ? step_glitch : -step_glitch);
        ++steps_executed;
        if (position < min_position) min_position = position;
        if (position > max_position) max_position = position;
        if (--s.count > 0) continue;
        step_head_ = static_cast<uint8_t>((step_head_ + 1) % STEP_RING_MAX);
        --step_count_;
        if (step_count_ == 0 && expect_more_) {  // ran dry mid-move
            if (underruns != 0xFFFF) ++underruns;
            if (last_interval_ticks_ < STEP_TICK_HZ / cfg::START_STOP_STEPS_PER_S && fast_underruns != 0xFFFF)
                ++fast_underruns;
        }
    }
}

// An ALERT/RDY edge at t_us (the AVR board's INT4 ISR): it ends one conversion and
// starts the next; every `every_`-th one queues the sample of the conversion it ends,
// stamped with that conversion's start (the previous edge) and the position then.
void FakeBoard::conversion_edge(uint64_t t_us) {
    if (edges_logged < EDGE_LOG) {
        edge_t_us[edges_logged] = t_us;
        edge_position[edges_logged] = position;
        ++edges_logged;
    }
    ++edges_done_;
    last_edge_us_ = t_us;
    if (have_prev_ && --until_ == 0) {
        until_ = every_;
        if (conv_count_ >= CONV_SLOTS) {
            if (conv_lost_ != 0xFF) ++conv_lost_;
        } else {
            ConvSample& c = conv_[(conv_head_ + conv_count_) % CONV_SLOTS];
            c.t_us = prev_us_;
            c.step_position = prev_pos_;
            c.counts = position_counts;
            c.ok = !position_poll_fails;
            c.lost = conv_lost_;
            conv_lost_ = 0;
            ++conv_count_;
        }
    }
    have_prev_ = true;
    prev_us_ = t_us;
    prev_pos_ = position;
}

void FakeBoard::advance_us(uint64_t us) {
    const uint64_t target = now + us;
    const uint64_t tick_per_us = STEP_TICK_HZ / 1000000UL;
    if (continuous_ && !rdy_dead && position_conversion_us) {
        for (;;) {
            const uint64_t edge = continuous_since_ + (edges_done_ + 1) * position_conversion_us;
            if (edge > target) break;
            run_steps_until(edge * tick_per_us);
            conversion_edge(edge);
        }
    }
    run_steps_until(target * tick_per_us);
    if (tx_drain_bytes_per_ms) {
        uint64_t drained = us * tx_drain_bytes_per_ms;  // milli-bytes
        tx_pending_milli_ = drained >= tx_pending_milli_ ? 0 : tx_pending_milli_ - drained;
    }
    now = target;
}

uint16_t FakeBoard::host_write(const uint8_t* data, uint16_t n) {
    uint16_t i = 0;
    for (; i < n && rx_count_ < RX_CAP; ++i) {
        rx_[(rx_head_ + rx_count_) % RX_CAP] = data[i];
        ++rx_count_;
    }
    return i;
}

uint32_t FakeBoard::take_tx(uint8_t* out, uint32_t cap) {
    uint32_t n = tx_len_ < cap ? tx_len_ : cap;
    memcpy(out, tx_, n);
    memmove(tx_, tx_ + n, tx_len_ - n);
    tx_len_ -= n;
    return n;
}

int16_t FakeBoard::serial_read() {
    if (rx_count_ == 0) return -1;
    uint8_t b = rx_[rx_head_];
    rx_head_ = static_cast<uint16_t>((rx_head_ + 1) % RX_CAP);
    --rx_count_;
    return b;
}

int16_t FakeBoard::serial_peek(uint16_t offset) {
    if (offset >= rx_count_) return -1;
    return rx_[(rx_head_ + offset) % RX_CAP];
}

void FakeBoard::serial_skip(uint16_t n) {
    if (n > rx_count_) n = rx_count_;
    rx_head_ = static_cast<uint16_t>((rx_head_ + n) % RX_CAP);
    rx_count_ = static_cast<uint16_t>(rx_count_ - n);
}

uint16_t FakeBoard::serial_tx_free() {
    uint64_t pending = (tx_pending_milli_ + 999) / 1000;
    return pending >= tx_ring_size ? 0 : static_cast<uint16_t>(tx_ring_size - pending);
}

uint16_t FakeBoard::serial_write(const uint8_t* data, uint16_t n) {
    uint16_t room = serial_tx_free();
    if (n > room) n = room;
    if (tx_drain_bytes_per_ms) tx_pending_milli_ += static_cast<uint64_t>(n) * 1000;
    uint32_t keep = n;
    if (tx_len_ + keep > TX_CAP) tx_len_ = 0;  // nobody read the capture: forget it
    memcpy(tx_ + tx_len_, data, keep);
    tx_len_ += keep;
    return n;
}

uint8_t FakeBoard::step_space() {
    uint8_t size = step_ring_size < 1 ? 1 : step_ring_size > STEP_RING_MAX ? STEP_RING_MAX : step_ring_size;
    return step_count_ >= size ? 0 : static_cast<uint8_t>(size - step_count_);
}

bool FakeBoard::step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last) {
    if (step_space() == 0 || count == 0) return false;
    // the AVR board's rule: only a lone step may be longer than a run's steps
    const uint32_t max_q8 = STEP_MAX_RUN_INTERVAL_TICKS << 8;
    const int32_t last_q8 = static_cast<int32_t>(interval_q8) + static_cast<int32_t>(add_q8) * (count - 1);
    if (count > 1 && (interval_q8 > max_q8 || last_q8 > static_cast<int32_t>(max_q8))) return false;
    if (interval_q8 > max_q8) ++long_steps;
    expect_more_ = !last;
    if (step_count_ == 0) {
        last_edge_tick_ = now * (STEP_TICK_HZ / 1000000UL);  // first step: from now
        carry_ = 0;
        dir_ = direction >= 0 ? 1 : -1;  // steps queued while running keep the direction
    } else {
        const uint32_t shortest = add_q8 < 0 ? interval_q8 + static_cast<int32_t>(add_q8) * (count - 1) : interval_q8;
        if ((shortest >> 8) < min_interval_ticks) min_interval_ticks = shortest >> 8;
    }
    Step& s = steps_[(step_head_ + step_count_) % STEP_RING_MAX];
    s.dir = dir_;
    s.q8 = interval_q8;
    s.add = add_q8;
    s.count = count;
    ++step_count_;
    return true;
}

void FakeBoard::step_halt() {
    step_count_ = 0;
    expect_more_ = false;
    ++halts;
}

// The first queued step is the pending edge (its time is already running); keeps it
// and `keep` more, splitting a run if needed.
uint32_t FakeBoard::step_truncate(uint8_t keep, int32_t& rest_position) {
    ++truncations;
    uint32_t want = step_count_ == 0 ? 0 : 1u + keep;
    uint32_t kept = 0, dropped = 0;
    uint8_t entries = 0;
    for (uint8_t i = 0; i < step_count_; ++i) {
        Step& s = steps_[(step_head_ + i) % STEP_RING_MAX];
        if (want == 0) {
            dropped += s.count;
            continue;
        }
        ++entries;
        if (s.count > want) {
            dropped += s.count - want;
            s.count = static_cast<uint8_t>(want);
        }
        kept += s.count;
        want -= s.count;
    }
    step_count_ = entries;
    rest_position = position + dir_ * static_cast<int32_t>(kept);
    return dropped;
}

uint16_t FakeBoard::heater_set_mV(uint16_t mV) {
    const uint16_t applied = drv::heater::applied_for_mV(mV);
    if (applied > 0 && sense_on) {
        ++interlock_violations;
        sense_on = false;  // the driver's own interlock
    }
    heater_requested_mV = mV;
    heater_mV = applied;
    return applied;
}

bool FakeBoard::sense_current(bool on) {
    if (on && heater_mV > 0) {
        ++sense_refusals;
        return false;
    }
    if (on && !sense_on) sense_since_ = now;
    sense_on = on;
    return true;
}

bool FakeBoard::position_start() {
    if (position_start_fails) return false;
    position_busy_ = true;
    position_started_ = now;
    return true;
}

int8_t FakeBoard::position_poll(int16_t& counts) {
    if (!position_busy_) return -1;
    if (position_poll_fails) {
        position_busy_ = false;
        return -1;
    }
    if (now - position_started_ < position_latency_us) return 0;
    position_busy_ = false;
    counts = position_counts;
    return 1;
}

bool FakeBoard::position_continuous(bool on, uint8_t every) {
    continuous_ = false;
    conv_count_ = 0;
    conv_lost_ = 0;
    if (!on) return !position_start_fails;
    ++continuous_setups;
    if (position_start_fails) return false;
    if (continuous_start_failures) {
        --continuous_start_failures;
        return false;
    }
    continuous_ = true;
    continuous_since_ = now;
    edges_done_ = 0;
    every_ = until_ = every ? every : 1;
    have_prev_ = false;
    return true;
}

bool FakeBoard::position_take(ConvSample& s) {
    if (conv_count_ == 0) return false;
    s = conv_[conv_head_];
    conv_head_ = static_cast<uint8_t>((conv_head_ + 1) % CONV_SLOTS);
    --conv_count_;
    ++continuous_reads;
    return true;
}

uint16_t FakeBoard::position_edges(uint64_t& last_us) {
    last_us = last_edge_us_;
    return continuous_ ? static_cast<uint16_t>(edges_done_) : 0;  // wraps, as the AVR board's
}

bool FakeBoard::resistance_start() {
    if (resistance_start_fails) return false;
    if (!sense_on || now - sense_since_ < cfg::RESISTANCE_SETTLE_US) ++unsettled_conversions;
    resistance_busy_ = true;
    resistance_started_ = now;
    return true;
}

int8_t FakeBoard::resistance_poll(int32_t& counts, uint8_t& flags) {
    if (!resistance_busy_) return -1;
    if (resistance_poll_fails) {
        resistance_busy_ = false;
        return -1;
    }
    if (now - resistance_started_ < resistance_latency_us) return 0;
    resistance_busy_ = false;
    counts = resistance_counts;
    flags = resistance_flags;
    return 1;
}

}  // namespace fw
