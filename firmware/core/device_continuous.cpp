// Device, part 4: the continuous sampler (periods below cfg::SINGLE_SHOT_MIN_PERIOD_US).
//
// The ADS1115 converts continuously at 860 samples/s and pulses ALERT/RDY at the end of
// each conversion; the board counts the pulses (an edge interrupt that only counts).
// Every conv_per_sample_ conversions make one sample: its position is the conversion
// just finished, read once over I2C (~75 us at 400 kHz), its t_us the instant that
// conversion started (the pass that saw the pulse, minus one conversion: within one
// main-loop pass of the truth). Pulses that pile up while a pass runs long count as
// samples missed, their counter values consumed (the host sees the gap). Should the ADC
// refuse continuous mode, samples keep the grid of the period, flagged position_invalid.
//
// The CS5513 runs at its own rate meanwhile (53..159 words/s, CLK/612 with its on-chip
// oscillator at 32..96 kHz: data sheet DS337, 2.5.4): a measurement is re-armed as soon
// as a word is read, and each sample carries the word finished since the previous one,
// if any, else says resistance_not_measured. The sense current stays on while sampling
// with the heater off; words from the first four conversions after it comes on are
// discarded by the driver (the sinc4 filter still averages the time it was off).
//
// Samples leave in SAMPLE_BLOCK frames (SampleBlockBuilder), sent the moment a block is
// full or must close. A block the line has no room for at that moment (urgent frames
// waiting, the TX ring full: an ACK, QUEUE_STATUS and a move's EVENTs can fill it) waits
// and is retried every pass; only when the next block closes while it still waits is it
// dropped whole (a gap of up to six counter values).
#include "config.h"
#include "device.h"

namespace fw {

namespace {
const uint8_t OF_OD = proto::adc_flags::RESISTANCE_OVERRANGE | proto::adc_flags::RESISTANCE_OSCILLATION;
}  // namespace

void Device::run_continuous(uint64_t now) {
    progress_words(now);
    int16_t counts = 0;
    bool position_ok = false;
    uint64_t t_us;
    if (continuous_ok_) {
        const uint8_t n = board_.position_ready();
        if (n == 0) return;
        const uint16_t seen = static_cast<uint16_t>(conv_seen_ + n);
        if (seen < conv_per_sample_) {
            conv_seen_ = static_cast<uint8_t>(seen);
            return;
        }
        const uint16_t due = static_cast<uint16_t>(seen / conv_per_sample_);
        conv_seen_ = static_cast<uint8_t>(seen % conv_per_sample_);
        if (due > 1) {  // pulses piled up: those samples are gone
            counter_ += due - 1u;
            samples_missed_ += due - 1u;
        }
        position_ok = board_.position_read(counts) > 0;
        t_us = now - cfg::MIN_SAMPLE_PERIOD_US;
    } else {
        if (!sample_due(now)) return;
        next_sample_us_ += period_us_;
        t_us = now;
    }
    proto::Sample s;
    s.counter = counter_++;
    s.t_us = t_us;
    s.step_position = board_.step_position();
    s.position_raw = position_ok ? counts : 0;
    s.adc_flags = position_ok ? 0 : proto::adc_flags::POSITION_INVALID;
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
    if (continuous_ok_) board_.position_continuous(false);
    continuous_ = false;
    continuous_ok_ = false;
    word_armed_ = false;
    word_ready_ = false;
}

}  // namespace fw
