// Device, part 3: the sampler (see device.h).
//
// Samples sit on a grid anchored where SET_SAMPLING ran, the first one period later;
// each SAMPLE carries the time its position conversion actually started (the ADS1115
// starts converting when the config write completes; t_us is read right after it),
// and the state (step position, moving, segment, heater voltage applied) at that moment. Conversions are polled, never
// waited for. The 50 mA sense current stays on between samples while sampling runs and
// the heater is off (so only the first conversion after enabling it waits
// cfg::RESISTANCE_SETTLE_US); it goes off before the heater comes on, aborting a
// conversion in progress (the sample then says resistance_not_measured). The
// resistance never holds up the grid: a word not ready RESISTANCE_MARGIN_US before the
// next slot is given up (resistance_not_measured, sense current left on), so while the
// CS5513's filter settles after the current comes on (~80 ms) or when the period is
// shorter than its conversion time, samples still come on every slot with their
// position. A grid slot that passes while the previous sample is still converting its
// position is skipped, its counter value consumed, so the host sees the gap.
// Periods below cfg::SINGLE_SHOT_MIN_PERIOD_US run the continuous sampler instead
// (device_continuous.cpp).
#include "config.h"
#include "device.h"

namespace fw {

namespace {
// An ADS1115 conversion at 860 SPS takes ~1.2 ms; far longer means the ADC is gone.
const uint32_t POSITION_TIMEOUT_US = 20000UL;
const uint8_t OF_OD = proto::adc_flags::RESISTANCE_OVERRANGE | proto::adc_flags::RESISTANCE_OSCILLATION;
// Time left before the next grid slot at which a pending resistance word is given up.
const uint32_t RESISTANCE_MARGIN_US = 500UL;
}  // namespace

void Device::set_sampling(uint32_t period_us, uint64_t t_us) {
    const bool continuous = period_us > 0 && period_us < cfg::SINGLE_SHOT_MIN_PERIOD_US;
    if (continuous_ && !continuous) continuous_off();
    period_us_ = period_us;
    next_sample_us_ = t_us + period_us;
    if (continuous) {
        if (sampler_ == SAMPLER_BUSY) {  // a single-shot sample still converting: send what it has
            if (!position_done_) sample_.adc_flags |= proto::adc_flags::POSITION_INVALID;
            if (!resistance_done_) finish_resistance(proto::adc_flags::RESISTANCE_NOT_MEASURED);
            position_done_ = true;
            progress_sample(t_us);
        }
        conv_per_sample_ = conversions_per_sample(period_us);
        continuous_on(t_us);
    }
    if (period_us == 0 && sampler_ == SAMPLER_IDLE) sense_off();
}

void Device::run_sampler(uint64_t now) {
    retry_block();
    if (continuous_) {
        run_continuous(now);
        return;
    }
    // The sample in progress first: when it finishes, the next one may start at once.
    progress_sample(now);
    if (sampler_ != SAMPLER_IDLE || period_us_ == 0) return;
    now = board_.now_us();  // the pass's earlier work took time: decide on the present
    if (sample_due(now)) start_sample(now);
}

// True once the next sample's slot has come; slots already passed whole are counted as
// missed (the counter jumps over them, so the host sees the gap).
bool Device::sample_due(uint64_t now) {
    if (now < next_sample_us_) return false;
    const uint64_t late = now - next_sample_us_;
    if (late >= period_us_) {
        const uint64_t skipped = late / period_us_;
        next_sample_us_ += skipped * period_us_;
        counter_ += static_cast<uint32_t>(skipped);
        samples_missed_ += static_cast<uint32_t>(skipped);
    }
    return true;
}

void Device::start_sample(uint64_t now) {
    sample_.counter = counter_++;
    next_sample_us_ += period_us_;
    position_done_ = !board_.position_start();
    sample_.t_us = board_.now_us();
    sample_.step_position = board_.step_position();
    sample_.position_raw = 0;
    sample_.resistance_raw = 0;
    sample_.adc_flags = 0;
    sample_.heater_mV = heater_mV_;
    sample_.motor_moving = (exec_ == EXEC_MOVE || stopping_) ? 1 : 0;
    sample_.segment = segment_;
    sample_start_us_ = now;
    sampler_ = SAMPLER_BUSY;
    if (position_done_) sample_.adc_flags |= proto::adc_flags::POSITION_INVALID;
    resistance_done_ = false;
    resistance_started_ = false;
    if (heater_mV_ > 0) {
        finish_resistance(proto::adc_flags::RESISTANCE_NOT_MEASURED);
    } else if (!sense_on_) {
        if (board_.sense_current(true)) {
            sense_on_ = true;
            sense_since_us_ = now;
        } else {
            finish_resistance(proto::adc_flags::RESISTANCE_NOT_MEASURED);
        }
    }
}

void Device::progress_sample(uint64_t now) {
    if (sampler_ != SAMPLER_BUSY) return;
    if (!position_done_) {
        int16_t counts = 0;
        int8_t r = board_.position_poll(counts);
        if (r > 0) {
            sample_.position_raw = counts;
            position_done_ = true;
        } else if (r < 0 || now - sample_start_us_ > POSITION_TIMEOUT_US) {
            sample_.adc_flags |= proto::adc_flags::POSITION_INVALID;
            position_done_ = true;
        }
    }
    if (!resistance_done_) {
        if (!resistance_started_ && now - sense_since_us_ >= cfg::RESISTANCE_SETTLE_US) {
            if (board_.resistance_start()) {
                resistance_started_ = true;
                conversion_us_ = now;
            } else {
                finish_resistance(proto::adc_flags::RESISTANCE_NOT_MEASURED);
            }
        }
        if (resistance_started_ && !resistance_done_) {
            int32_t counts = 0;
            uint8_t flags = 0;
            int8_t r = board_.resistance_poll(counts, flags);
            if (r > 0) {
                sample_.resistance_raw = counts;
                finish_resistance(static_cast<uint8_t>(flags & OF_OD));
            } else if (r < 0 || now - conversion_us_ > cfg::RESISTANCE_TIMEOUT_US) {
                finish_resistance(proto::adc_flags::RESISTANCE_NOT_MEASURED);
            }
        }
        if (!resistance_done_ && period_us_ != 0 && now + RESISTANCE_MARGIN_US >= next_sample_us_) {
            // The next slot is due: keep the grid, keep the current on (still settling).
            resistance_done_ = true;
            sample_.resistance_raw = 0;
            sample_.adc_flags |= proto::adc_flags::RESISTANCE_NOT_MEASURED;
        }
    }
    if (!position_done_ || !resistance_done_) return;
    sampler_ = SAMPLER_IDLE;
    if (period_us_ == 0) sense_off();
    uint8_t buf[proto::Sample::SIZE];
    writer_.send_droppable(proto::Sample::ID, buf, proto::pack(sample_, buf));
}

void Device::finish_resistance(uint8_t extra_flags) {
    resistance_done_ = true;
    sample_.adc_flags |= extra_flags;
    if (extra_flags & proto::adc_flags::RESISTANCE_NOT_MEASURED) {
        sample_.resistance_raw = 0;
        sense_off();  // re-enabled (and settled again) by the next sample
    }
}

void Device::abort_resistance() {
    if (sampler_ == SAMPLER_BUSY && !resistance_done_) {
        finish_resistance(proto::adc_flags::RESISTANCE_NOT_MEASURED);
    }
    sense_off();
}

void Device::sense_off() {
    word_armed_ = false;
    word_ready_ = false;
    if (!sense_on_) return;
    board_.sense_current(false);
    sense_on_ = false;
}

}  // namespace fw
