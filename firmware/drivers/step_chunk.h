// Splitting a long step interval into timer periods, before the step is queued.
//
// Contract. The step ISR programs one 16-bit compare period per ring entry and never
// tests for a long interval itself (that test on every step cost cycles at the top
// rate). The main loop therefore splits a step whose interval exceeds
// STEP_SINGLE_MAX_TICKS (2 MHz ticks) before queuing it: step_wait_chunks() says how
// many wait entries of exactly STEP_CHAIN_TICKS go first (a wait is an entry with count
// 0: a compare match without a STEP edge), and the step then keeps the rest, at most
// STEP_SINGLE_MAX_TICKS and at least STEP_SINGLE_MAX_TICKS - STEP_CHAIN_TICKS ticks, so
// no period is ever short enough for the running counter to pass its compare value.
// STEP_SINGLE_MAX_TICKS leaves room for the 1/256-tick fraction the ISR carries (the
// q8 interval plus the carry stays within 24 bits). Header-only; tested natively.
#pragma once
#include <stdint.h>

namespace drv {

static const uint32_t STEP_SINGLE_MAX_TICKS = 0xFF00UL;
static const uint32_t STEP_CHAIN_TICKS = 0x8000UL;

// Wait entries needed before a step of `ticks`; `ticks` becomes what the step keeps.
inline uint8_t step_wait_chunks(uint32_t& ticks) {
    if (ticks <= STEP_SINGLE_MAX_TICKS) return 0;
    const uint32_t n = (ticks - STEP_SINGLE_MAX_TICKS + STEP_CHAIN_TICKS - 1) / STEP_CHAIN_TICKS;
    ticks -= n * STEP_CHAIN_TICKS;
    return static_cast<uint8_t>(n > 255 ? 255 : n);
}

}  // namespace drv
