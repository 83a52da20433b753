#include "step_timer.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "../drivers/step_chunk.h"
#include "pins.h"

namespace hal {

namespace {
const uint8_t RING_MASK = STEP_RING_SIZE - 1;
static_assert((STEP_RING_SIZE & RING_MASK) == 0, "ring size must be a power of two");

// Ring of queued steps: the main loop writes an entry, then advances g_head; the ISR
// reads it, then advances g_tail. Indices are single bytes (atomic to read).
volatile uint32_t g_interval[STEP_RING_SIZE];
volatile int8_t g_direction[STEP_RING_SIZE];
volatile uint8_t g_head = 0;
volatile uint8_t g_tail = 0;

volatile int32_t g_position = 0;  // ISR writes; main loop only inside ATOMIC_BLOCK
volatile uint32_t g_wait_left = 0;  // ticks still to chain before the pending STEP edge
volatile int8_t g_pending_dir = 0;  // direction of the pending STEP edge
volatile bool g_running = false;    // a STEP edge is pending on Timer1

const uint8_t TIMER1_STOPPED = 1 << WGM12;               // CTC on OCR1A, no clock
const uint8_t TIMER1_RUNNING = (1 << WGM12) | (1 << CS11);  // CTC, F_CPU / 8

__attribute__((always_inline)) inline void write_dir(int8_t direction) {
    if (direction > 0)
        PINS_DIR_PORT |= 1 << PINS_DIR_BIT;
    else
        PINS_DIR_PORT &= ~(1 << PINS_DIR_BIT);
}

// Program the compare match for the next STEP edge; interrupts must be masked (ISR or
// lock). CTC: the counter restarted at the last match, so the interval is measured
// from the previous STEP edge exactly, whatever the ISR latency.
__attribute__((always_inline)) inline void program_interval(uint32_t interval) {
    OCR1A = drv::step_take_chunk(interval);
    g_wait_left = interval;
}

// Start from idle with the oldest queued entry; interrupts masked.
void start_locked() {
    const uint8_t tail = g_tail;
    if (tail == g_head) return;
    const int8_t dir = g_direction[tail];
    const uint32_t interval = g_interval[tail];
    g_tail = (tail + 1) & RING_MASK;
    g_pending_dir = dir;
    write_dir(dir);  // the STEP edge follows >= STEP_MIN_INTERVAL_TICKS (20 us) later
    TCNT1 = 0;
    program_interval(interval);
    TIFR1 = 1 << OCF1A;
    TCCR1B = TIMER1_RUNNING;
    g_running = true;
}
}  // namespace

void step_init() {
    PINS_STEP_PORT &= ~(1 << PINS_STEP_BIT);
    TCCR1A = 0;
    TCCR1B = TIMER1_STOPPED;
    TCNT1 = 0;
    TIFR1 = 1 << OCF1A;
    TIMSK1 = 1 << OCIE1A;
}

uint8_t step_space() {
    const uint8_t used = (g_head - g_tail) & RING_MASK;
    return static_cast<uint8_t>(RING_MASK - used);
}

bool step_push(int8_t direction, uint32_t interval_ticks) {
    if (interval_ticks < STEP_MIN_INTERVAL_TICKS) interval_ticks = STEP_MIN_INTERVAL_TICKS;
    const uint8_t head = g_head;
    const uint8_t next = (head + 1) & RING_MASK;
    if (next == g_tail) return false;
    g_interval[head] = interval_ticks;
    g_direction[head] = direction > 0 ? 1 : -1;
    g_head = next;  // publish after the entry is written (all volatile: order kept)
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        if (!g_running) start_locked();
    }
    return true;
}

bool step_busy() { return g_running || g_head != g_tail; }

int32_t step_position() {
    int32_t p;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { p = g_position; }
    return p;
}

void step_set_position(int32_t steps) {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { g_position = steps; }
}

void step_halt() {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        TCCR1B = TIMER1_STOPPED;
        TIFR1 = 1 << OCF1A;
        g_tail = g_head;
        g_wait_left = 0;
        g_running = false;
    }
}

}  // namespace hal

// Step-timer ISR (TIMER1_COMPA = vector 17 on the ATmega2560). Loop-free on purpose:
// scripts/isr_cycles.py bounds its worst case from the disassembly.
ISR(TIMER1_COMPA_vect) {
    using namespace hal;
    uint32_t left = g_wait_left;
    if (left) {  // a chained part of a long interval: no step on this match
        OCR1A = drv::step_take_chunk(left);
        g_wait_left = left;
        return;
    }
    PINS_STEP_PORT |= 1 << PINS_STEP_BIT;  // STEP rises (DIR was set >= 20 us ago)
    const int8_t dir = g_pending_dir;
    g_position = g_position + dir;

    const uint8_t tail = g_tail;
    const bool more = tail != g_head;
    int8_t next_dir = dir;
    if (more) {
        next_dir = g_direction[tail];
        const uint32_t interval = g_interval[tail];
        g_tail = (tail + 1) & RING_MASK;
        g_pending_dir = next_dir;
        program_interval(interval);
    } else {
        TCCR1B = TIMER1_STOPPED;
        g_running = false;
    }
    // STEP high >= 1 us = 16 cycles whatever the compiler made of the code above:
    // 8 two-cycle no-ops, not a loop, so the ISR stays loop-free.
    __asm__ __volatile__(
        "rjmp .+0\n\trjmp .+0\n\trjmp .+0\n\trjmp .+0\n\t"
        "rjmp .+0\n\trjmp .+0\n\trjmp .+0\n\trjmp .+0\n\t" ::: "memory");
    PINS_STEP_PORT &= ~(1 << PINS_STEP_BIT);
    // DIR for the next edge only now: hold >= 200 ns after the rising edge is met, and
    // the next rising edge is >= STEP_MIN_INTERVAL_TICKS away.
    if (more) write_dir(next_dir);
}
