// Splitting a step interval into 16-bit timer periods (used by the step ISR).
//
// Contract. `left` is the number of 2 MHz ticks still to wait until the next STEP edge.
// step_take_chunk() removes one timer period from it and returns the OCR1A value for
// that period (CTC: period = OCR1A + 1). Intervals up to 65536 ticks take one period;
// longer ones are chained in 32768-tick periods until at most 65536 remain, so no
// chained period is ever shorter than 32768 ticks (no risk of a compare value that the
// running counter has already passed). Header-only so the ISR inlines it; tested natively.
#pragma once
#include <stdint.h>

namespace drv {

static const uint32_t STEP_SINGLE_MAX_TICKS = 0x10000UL;
static const uint32_t STEP_CHAIN_TICKS = 0x8000UL;

__attribute__((always_inline)) inline uint16_t step_take_chunk(uint32_t& left) {
    const uint32_t chunk = left > STEP_SINGLE_MAX_TICKS ? STEP_CHAIN_TICKS : left;
    left -= chunk;
    return static_cast<uint16_t>(chunk - 1);
}

}  // namespace drv
