// Step generator: Timer1 compare-match ISR consuming a ring of step runs.
//
// Contract (AVR only). Timer1 runs in CTC mode at F_CPU/8 = 2 MHz (fw::STEP_TICK_HZ).
// Each queued entry is a run of `count` (1..255) steps: step j of the run lasts
// interval_q8 + j * add_q8, in 1/256 tick; each STEP edge comes floor(carry +
// interval) / 256 ticks after the previous one, the fraction carried to the next step
// (reset when the generator starts from idle). A cruise of thousands of steps is a
// handful of entries, a ramp a run per group of steps (Klipper's interval+add), so the
// main loop's work per step is small. The first step of a burst comes one interval after the
// push that found the generator idle. Intervals longer than the 16-bit timer are
// chained over several compare matches (drivers/step_chunk.h); intervals shorter than
// STEP_MIN_INTERVAL_TICKS are stretched to it. All steps queued between two idle
// moments share one direction: the direction of the push that found the generator
// idle; DIR is written then, a whole interval (>= 20 us) before the first STEP edge.
// STEP is held high >= 1 us inside the ISR. A push with last = false promises more
// steps: if the ring runs dry after such a push, the ISR stops the timer and counts an
// underrun (the step train paused mid-move); the next push restarts it. The position
// is a volatile int32 written by the ISR; step_position() and step_set_position()
// access it only inside ATOMIC_BLOCK. step_truncate() drops queued steps beyond the
// pending edge and `keep` more (a controlled stop replaces them), splitting a run if
// needed, with interrupts masked for at most keep + 1 entries.
#pragma once
#include <stdint.h>

namespace hal {

static const uint8_t STEP_RING_SIZE = 128;  // entries (runs); a power of two
static const uint16_t STEP_MIN_INTERVAL_TICKS = 40;  // 20 us; max rate is 16000 steps/s

void step_init();
uint8_t step_space();
// Caller checks step_space() first (free entries); a push into a full ring is dropped
// (returns false). count >= 1.
bool step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last);
bool step_busy();
int32_t step_position();
void step_set_position(int32_t steps);
void step_halt();
// Drops queued steps but the pending edge and `keep` more; returns how many it dropped
// and, in rest_position, the position once the steps left have run.
uint32_t step_truncate(uint8_t keep, int32_t& rest_position);
uint16_t step_underruns();
// For the watchdog ISR: stop the timer and hold STEP low now (interrupts masked).
void step_emergency_stop();
bool step_running();

}  // namespace hal
