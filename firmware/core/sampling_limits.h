// Which sampling periods the device can carry, and how the continuous sampler paces.
//
// Contract (the simulated device applies the same rule: host/tsa_bench/protocol/
// blocks.py sampling_refusal). A period shorter than one ADS1115 conversion
// (cfg::MIN_SAMPLE_PERIOD_US) is refused too_fast_for_sensor; below
// cfg::SINGLE_SHOT_MIN_PERIOD_US (continuous sampling: a sample every k conversions) a
// period that is not k whole conversions (1163 or 2326 us) is refused
// between_conversions, never rounded; one whose sample frames need more than
// cfg::SAMPLE_LINE_BUDGET_PERCENT of `baud` (8N1: ten bits a byte) is refused
// too_fast_for_line. Sample frames: below cfg::SINGLE_SHOT_MIN_PERIOD_US full
// SAMPLE_BLOCKs (six samples in 72 bytes, a sample every conversions_per_sample()
// conversions at cfg::ADS1115_SPS), else one SAMPLE (36 bytes) a period.
#pragma once
#include <stdint.h>

#include "../config.h"
#include "frame.h"
#include "protocol_catalogue.h"

namespace fw {

static const uint8_t SAMPLES_PER_BLOCK = 1 + proto::SampleBlock::MAX_ENTRIES;
static const uint8_t NO_RESISTANCE = 255;

// Continuous sampling: one sample every this many ADS1115 conversions (>= 1).
inline uint8_t conversions_per_sample(uint32_t period_us) {
    const uint32_t k = period_us / cfg::MIN_SAMPLE_PERIOD_US;
    return static_cast<uint8_t>(k < 1 ? 1 : k > 255 ? 255 : k);
}

inline uint8_t sampling_refusal(uint32_t period_us, uint32_t baud) {
    if (period_us == 0) return proto::status::OK;
    if (period_us < cfg::MIN_SAMPLE_PERIOD_US) return proto::status::TOO_FAST_FOR_SENSOR;
    if (period_us < cfg::SINGLE_SHOT_MIN_PERIOD_US && period_us % cfg::MIN_SAMPLE_PERIOD_US != 0)
        return proto::status::BETWEEN_CONVERSIONS;
    // need > budget, in whole numbers: bytes/s * 100 * 10 against baud * percent
    const uint64_t budget = static_cast<uint64_t>(baud) * cfg::SAMPLE_LINE_BUDGET_PERCENT;
    uint64_t need;
    if (period_us >= cfg::SINGLE_SHOT_MIN_PERIOD_US) {
        need = static_cast<uint64_t>(frame_wire_bytes(proto::Sample::SIZE)) * 1000000ULL * 1000ULL / period_us;
    } else {
        const uint16_t block = frame_wire_bytes(proto::SampleBlock::SIZE +
                                                proto::SampleBlock::MAX_ENTRIES * proto::SampleBlock::ENTRY_SIZE);
        need = static_cast<uint64_t>(block) * cfg::ADS1115_SPS * 1000ULL /
               (static_cast<uint64_t>(SAMPLES_PER_BLOCK) * conversions_per_sample(period_us));
    }
    return need > budget ? proto::status::TOO_FAST_FOR_LINE : proto::status::OK;
}

}  // namespace fw
