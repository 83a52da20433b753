// Step generator: Timer1 compare-match ISR consuming a ring of (direction, interval).
//
// Contract (AVR only). Timer1 runs in CTC mode at F_CPU/8 = 2 MHz (fw::STEP_TICK_HZ).
// Each queued entry is one step: its STEP edge comes `interval_ticks` after the previous
// STEP edge (after step_push, when the generator was idle). Intervals longer than the
// 16-bit timer are chained over several compare matches (drivers/step_chunk.h);
// intervals shorter than STEP_MIN_INTERVAL_TICKS are stretched to it. DIR is written when
// the previous pulse ends (or at start), so it is set a whole interval (>= 20 us) before
// the STEP edge it belongs to; STEP is held high >= 1 us inside the ISR. The position is
// a volatile int32 written by the ISR; step_position()/step_set_position() access it
// only inside ATOMIC_BLOCK.
#pragma once
#include <stdint.h>

namespace hal {

static const uint8_t STEP_RING_SIZE = 64;  // power of two
static const uint16_t STEP_MIN_INTERVAL_TICKS = 40;  // 20 us; max rate is 16000 steps/s

void step_init();
uint8_t step_space();
// Caller checks step_space() first; a push into a full ring is dropped (returns false).
bool step_push(int8_t direction, uint32_t interval_ticks);
bool step_busy();
int32_t step_position();
void step_set_position(int32_t steps);
void step_halt();

}  // namespace hal
