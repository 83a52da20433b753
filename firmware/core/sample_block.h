// SampleBlockBuilder: continuous-mode samples -> SAMPLE_BLOCK payloads.
//
// Contract (the same rules as host/tsa_bench/protocol/blocks.py BlockBuilder, which the
// simulated device uses). A block holds up to SAMPLES_PER_BLOCK consecutive samples:
// the first in full, each next one as deltas (time, step position, position counts
// modulo 65536, flags). It must be closed (take()) before a sample that does not
// follow on: another heater voltage or segment, a counter gap, a time step over 65535 us,
// a step delta outside int16, or a second resistance word (a sample with a word is one
// without RESISTANCE_NOT_MEASURED). The caller closes it as soon as it is full.
#pragma once
#include <stdint.h>

#include "protocol_catalogue.h"
#include "sampling_limits.h"

namespace fw {

class SampleBlockBuilder {
public:
    SampleBlockBuilder() : n_(0) {}
    uint8_t size() const { return n_; }
    bool full() const { return n_ >= SAMPLES_PER_BLOCK; }

    bool must_close_before(const proto::Sample& s) const {
        if (n_ == 0) return false;
        if (full() || s.heater_mV != blk_.heater_mV || s.segment != blk_.segment) return true;
        if (has_word(s) && blk_.resistance_at != NO_RESISTANCE) return true;
        if (s.counter != last_.counter + 1 || s.t_us - last_.t_us > 0xFFFFu) return true;
        const int32_t dstep = s.step_position - last_.step_position;
        return dstep < -32768 || dstep > 32767;
    }

    // Append a sample (close the block first when must_close_before() says so).
    void add(const proto::Sample& s) {
        const uint8_t flags = sample_flags(s);
        if (n_ == 0) {
            blk_.counter = s.counter;
            blk_.t_us = s.t_us;
            blk_.step_position = s.step_position;
            blk_.position_raw = s.position_raw;
            blk_.flags = flags;
            blk_.heater_mV = s.heater_mV;
            blk_.segment = s.segment;
            blk_.resistance_at = NO_RESISTANCE;
            blk_.resistance_raw = 0;
            blk_.more = 0;
        } else {
            proto::SampleBlockEntry& e = blk_.entries[n_ - 1];
            e.dt_us = static_cast<uint16_t>(s.t_us - last_.t_us);
            e.step_delta = static_cast<int16_t>(s.step_position - last_.step_position);
            e.position_delta = static_cast<int16_t>(static_cast<uint16_t>(s.position_raw - last_.position_raw));
            e.flags = flags;
            blk_.more = n_;
        }
        if (has_word(s)) {
            blk_.resistance_at = n_;
            blk_.resistance_raw = s.resistance_raw;
            if (s.adc_flags & proto::adc_flags::RESISTANCE_OVERRANGE) blk_.flags |= proto::sample_flags::RESISTANCE_OVERRANGE;
            if (s.adc_flags & proto::adc_flags::RESISTANCE_OSCILLATION) {
                blk_.flags |= proto::sample_flags::RESISTANCE_OSCILLATION;
            }
        }
        last_ = s;
        ++n_;
    }

    // Pack the block into buf (proto::SampleBlock::SIZE + MAX_ENTRIES * ENTRY_SIZE bytes)
    // and start a new one; returns the payload length (0 when empty).
    uint8_t take(uint8_t* buf) {
        if (n_ == 0) return 0;
        n_ = 0;
        return proto::pack(blk_, buf);
    }

private:
    static bool has_word(const proto::Sample& s) {
        return !(s.adc_flags & proto::adc_flags::RESISTANCE_NOT_MEASURED);
    }
    static uint8_t sample_flags(const proto::Sample& s) {
        uint8_t f = (s.adc_flags & proto::adc_flags::POSITION_INVALID) ? proto::sample_flags::POSITION_INVALID : 0;
        return static_cast<uint8_t>(f | (s.motor_moving ? proto::sample_flags::MOTOR_MOVING : 0));
    }

    proto::SampleBlock blk_;
    proto::Sample last_;
    uint8_t n_;
};

}  // namespace fw
