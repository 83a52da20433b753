// Step generator: Timer1 compare-match ISR consuming a ring of step runs.
//
// Contract (AVR only). Timer1 runs in CTC mode at F_CPU/8 = 2 MHz (fw::STEP_TICK_HZ).
// Each queued entry is a run of `count` (1..255) steps: step j of the run lasts
// interval_q8 + j * add_q8, in 1/256 tick (24 bits: at most STEP_SINGLE_MAX_TICKS);
// each STEP edge comes floor(carry + interval) / 256 ticks after the previous one, the
// fraction carried to the next step (reset when the generator starts from idle). A
// cruise of thousands of steps is a handful of entries, a ramp a run per group of steps
// (Klipper's interval+add), so the main loop's work per step is small. The first step
// of a burst comes one interval after the push that found the generator idle. A step
// longer than STEP_SINGLE_MAX_TICKS (a slow one) is pushed alone (count 1): step_push
// queues wait entries of STEP_CHAIN_TICKS before it (drivers/step_chunk.h), so the ISR
// never tests for a long interval; intervals shorter than STEP_MIN_INTERVAL_TICKS are
// stretched to it. All steps queued between two idle moments share one direction: the
// direction of the push that found the generator idle; DIR is written then, a whole
// interval (>= 20 us) before the first STEP edge. STEP is held high >= 1 us inside the
// ISR (checked on its shortest path by scripts/isr_cycles.py). A push with last =
// false promises more steps: if the ring runs dry after such a push, the ISR stops the
// timer and counts an underrun (the step train paused mid-move), and a fast one as well
// when the last step was shorter than STEP_START_STOP_TICKS (faster than the start/stop
// speed: the motor may have lost steps); the next push restarts it; step_end_train()
// withdraws the promise (a stop with nothing more to come).
// Position, as Klipper keeps it: the ISR adds a run's steps to the position when it
// takes the run, not per step, and in 16 bits; step_position() subtracts the steps of
// the taken run still to come and extends the count to 32 bits (the main loop reads it
// every pass, far more often than every 32,767 steps). step_truncate() drops queued steps beyond the pending edge and `keep`
// more (a controlled stop replaces them), splitting a run if needed, with interrupts
// masked for at most keep + 1 entries.
#pragma once
#include <stdint.h>

#include "../config.h"

namespace hal {

static const uint8_t STEP_RING_SIZE = 128;  // entries (runs and waits); a power of two
static const uint16_t STEP_MIN_INTERVAL_TICKS = 40;  // 20 us; max rate is 16000 steps/s
// A step shorter than this is faster than the start/stop speed (cfg::START_STOP_STEPS_PER_S).
static const uint16_t STEP_START_STOP_TICKS = static_cast<uint16_t>(2000000UL / cfg::START_STOP_STEPS_PER_S);

void step_init();
uint8_t step_space();
// Queues a run (count >= 1). A step longer than STEP_SINGLE_MAX_TICKS must come alone
// (count 1): it takes step_entries_for() entries. Returns false, queuing nothing, when
// the ring lacks the room or such a run has count > 1.
bool step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last);
bool step_busy();
int32_t step_position();

namespace detail {  // the step ISR's state that step_position16_locked() reads
extern volatile uint16_t g_position16;
extern volatile uint8_t g_run_left;
extern volatile uint8_t g_pending;
extern volatile bool g_running;
extern volatile int8_t g_dir;
}  // namespace detail

// For the ALERT/RDY ISR (interrupts masked): the position's low 16 bits now (inline: the
// ISR stays free of calls); the main loop turns such a value into a position with
// step_position_near() (it must be within 32,767 steps of the present one).
__attribute__((always_inline)) inline uint16_t step_position16_locked() {
    const uint8_t owed = static_cast<uint8_t>(detail::g_run_left + (detail::g_running && detail::g_pending ? 1 : 0));
    return detail::g_dir > 0 ? static_cast<uint16_t>(detail::g_position16 - owed)
                             : static_cast<uint16_t>(detail::g_position16 + owed);
}
int32_t step_position_near(uint16_t p16);
void step_set_position(int32_t steps);
void step_halt();
// Drops queued steps but the pending edge and `keep` more; returns how many it dropped
// and, in rest_position, the position once the steps left have run.
uint32_t step_truncate(uint8_t keep, int32_t& rest_position);
// Nothing more follows what is queued: running dry is no underrun.
void step_end_train();
uint16_t step_underruns();
uint16_t step_fast_underruns();
// For the watchdog ISR: stop the timer and hold STEP low now (interrupts masked).
void step_emergency_stop();
bool step_running();

}  // namespace hal
