// Device, part 4: the continuous sampler (periods below cfg::SINGLE_SHOT_MIN_PERIOD_US).
//
// The ADS1115 converts continuously at 860 samples/s and pulses ALERT/RDY at the end of
// each conversion. The board's edge interrupt stamps every edge (time and step
// position) and, every conv_per_sample_ conversions, reads the conversion just finished:
// a sample stamped with its conversion's start (the edge before), its step position
// taken at that same instant (Board::position_take). The main loop only drains them,
// so a long pass costs no sample unless it outlasts the board's ring (8 samples).
// Samples the ring had no room for count as missed (their counter values consumed: the
// host sees the gap).
//
// Liveness. No edge for cfg::SENSOR_SILENCE_CONVERSIONS conversions (a chip reset to
// its defaults, a broken ALERT/RDY wire, a NACK when switching into continuous mode)
// sets the ADS1115 up again (a restart) and raises EVENT sensor_restarted once per
// outage; the set-up is retried every as long until it works, then every
// cfg::SENSOR_RETRY_US once the outage outlasts cfg::SENSOR_DEAD_US, which trips fault
// position_sensor (a controlled stop). The counter jumps over the conversions an outage
// cost. The conversion period is measured between edges (QUEUE_STATUS
// sensor_period_ns: the host fits the sensor's clock with it).
//
// The CS5513 runs at its own rate meanwhile (53..159 words/s, CLK/612 with its on-chip
// oscillator at 32..96 kHz: data sheet DS337, 2.5.4): a measurement is re-armed as soon
// as a word is read, and each sample carries the word finished since the previous one,
// if any, else says resistance_not_measured. The sense current stays on while sampling
// with the heater off; words from the first four conversions after it comes on are
// discarded by the driver (the sinc4 filter still averages the time it was off).
//
// Samples leave in SAMPLE_BLOCK frames (SampleBlockBuilder), handed to the writer the
// moment a block is full or must close; the writer encodes it once, when nothing urgent
// waits, and sends it as the TX ring makes room. A block the writer could not take yet
// waits; only when the next block closes while it still waits is it dropped whole (a
// gap of up to six counter values). While a block waits the host's frames wait too
// (device.cpp), so a burst of commands cannot crowd the samples off the line.
#include "config.h"
#include "device.h"

namespace fw {

namespace {
const uint8_t OF_OD = proto::adc_flags::RESISTANCE_OVERRANGE | proto::adc_flags::RESISTANCE_OSCILLATION;
const uint32_t SILENCE_US = cfg::SENSOR_SILENCE_CONVERSIONS * cfg::MIN_SAMPLE_PERIOD_US;
// The measured conversion period averages over at least this long.
const uint32_t PERIOD_WINDOW_US = 1000000UL;

// Time from `since` to `now`, 0 when `since` is later (an edge stamped after the pass
// read the clock).
uint64_t elapsed(uint64_t now, uint64_t since) { return now > since ? now - since : 0; }
}  // namespace

// Continuous sampling begins, or its conversions per sample change: set the ADS1115 up.
void Device::continuous_on(uint64_t now) {
    if (!continuous_) {
        word_armed_ = false;
        word_ready_ = false;
    }
    continuous_ = true;
    in_outage_ = false;
    have_last_stamp_ = false;
    last_alive_us_ = now;
    arm_continuous(now);
}

// (Re)arm the ADS1115 and the board's edge stamping; the first edge is a reference only.
void Device::arm_continuous(uint64_t now) {
    continuous_ok_ = board_.position_continuous(true, conv_per_sample_);
    armed_at_us_ = now;
    have_edge_ = false;
    edges_seen_ = 0;
    period_edges_ = 0;
    resume_gap_ = have_last_stamp_;
}

void Device::restart_continuous(uint64_t now) {
    if (sensor_restarts_ != 0xFFFF) ++sensor_restarts_;
    if (!in_outage_) {
        in_outage_ = true;
        sensor_event_owed_ = true;
    }
    arm_continuous(now);
}

void Device::run_continuous(uint64_t now) {
    progress_words(now);
    if (continuous_ok_) {
        ConvSample c;
        for (uint8_t n = 0; n < 8 && board_.position_take(c); ++n) take_conversion(c);
        uint64_t last_edge = 0;
        const uint16_t edges = board_.position_edges(last_edge);
        if (edges != edges_seen_) {  // the count wraps every 76 s: only a change counts
            const uint16_t new_edges = static_cast<uint16_t>(edges - edges_seen_);
            edges_seen_ = edges;
            have_edge_ = true;
            last_alive_us_ = last_edge;
            in_outage_ = false;
            measure_period(new_edges, last_edge);
        }
    }
    // Silence: no edge (or no working set-up) for a few conversions.
    const uint64_t quiet_since = continuous_ok_ && have_edge_ ? last_alive_us_ : armed_at_us_;
    const bool dead = elapsed(now, last_alive_us_) > cfg::SENSOR_DEAD_US;
    if (elapsed(now, quiet_since) > (dead ? cfg::SENSOR_RETRY_US : SILENCE_US)) restart_continuous(board_.now_us());
    if (dead && !fault_) trip(proto::fault::POSITION_SENSOR, now, true);
}

// The conversion period between edges, averaged over PERIOD_WINDOW_US or more: edges
// counted from a reference edge (the first after a set-up, then the window's last).
void Device::measure_period(uint16_t new_edges, uint64_t last_edge_us) {
    if (period_edges_ == 0) {  // the reference
        period_edges_ = 1;
        period_ref_us_ = last_edge_us;
        return;
    }
    period_edges_ += new_edges;
    const uint64_t span = last_edge_us - period_ref_us_;
    if (span < PERIOD_WINDOW_US) return;
    const uint32_t n = period_edges_ - 1;
    sensor_period_ns_ = static_cast<uint32_t>(span * 1000U / n);
    period_edges_ = 1;
    period_ref_us_ = last_edge_us;
}

void Device::take_conversion(const ConvSample& c) {
    if (c.lost) {  // the board's ring was full: those samples are gone
        counter_ += c.lost;
        samples_missed_ += c.lost;
    }
    if (resume_gap_) {  // the first sample after a restart: the outage's conversions are gone
        resume_gap_ = false;
        const uint32_t per_sample_us = static_cast<uint32_t>(conv_per_sample_) * cfg::MIN_SAMPLE_PERIOD_US;
        if (c.t_us > last_stamp_us_ + per_sample_us + per_sample_us / 2) {
            const uint32_t gap = static_cast<uint32_t>((c.t_us - last_stamp_us_ + per_sample_us / 2) / per_sample_us) - 1;
            counter_ += gap;
            samples_missed_ += gap;
        }
    }
    have_last_stamp_ = true;
    last_stamp_us_ = c.t_us;
    proto::Sample s;
    s.counter = counter_++;
    s.t_us = c.t_us;
    s.step_position = c.step_position;
    s.position_raw = c.ok ? c.counts : 0;
    s.adc_flags = c.ok ? 0 : proto::adc_flags::POSITION_INVALID;
    s.heater_mV = heater_mV_;
    s.motor_moving = (exec_ == EXEC_MOVE || stopping_) ? 1 : 0;
    s.segment = segment_;
    if (word_ready_ && heater_mV_ == 0) {
        s.resistance_raw = word_counts_;
        s.adc_flags |= word_flags_;
        word_ready_ = false;
    } else {
        s.resistance_raw = 0;
        s.adc_flags |= proto::adc_flags::RESISTANCE_NOT_MEASURED;
    }
    if (block_.must_close_before(s)) flush_block();
    block_.add(s);
    if (block_.full()) flush_block();
}

void Device::progress_words(uint64_t now) {
    if (heater_mV_ > 0) return;  // the sense current is off while heating
    if (!sense_on_) {
        if (!board_.sense_current(true)) return;
        sense_on_ = true;
        sense_since_us_ = now;
    }
    if (!word_armed_) {
        if (now - sense_since_us_ < cfg::RESISTANCE_SETTLE_US || !board_.resistance_start()) return;
        word_armed_ = true;
        conversion_us_ = now;
    }
    int32_t counts = 0;
    uint8_t flags = 0;
    const int8_t r = board_.resistance_poll(counts, flags);
    if (r > 0) {
        word_ready_ = true;
        word_counts_ = counts;
        word_flags_ = static_cast<uint8_t>(flags & OF_OD);
        word_armed_ = false;
    } else if (r < 0 || now - conversion_us_ > cfg::RESISTANCE_TIMEOUT_US) {
        word_armed_ = false;  // no word this time; re-armed on the next pass
    }
}

void Device::flush_block() {
    retry_block();
    if (block_.size() == 0) return;
    if (pending_len_) {  // the line never had room for the one before: it is lost
        samples_missed_ += pending_samples_;
    }
    pending_samples_ = block_.size();
    pending_len_ = block_.take(pending_);
    retry_block();
}

void Device::retry_block() {
    if (pending_len_ && writer_.try_send_sample(proto::SampleBlock::ID, pending_, pending_len_)) pending_len_ = 0;
}

void Device::continuous_off() {
    flush_block();
    board_.position_continuous(false, 1);
    continuous_ = false;
    continuous_ok_ = false;
    in_outage_ = false;
    sensor_period_ns_ = 0;
    word_armed_ = false;
    word_ready_ = false;
}

}  // namespace fw
