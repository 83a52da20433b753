#include "step_timer.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "../drivers/step_chunk.h"
#include "pins.h"

namespace hal {

namespace {
// Ring of queued step intervals: the main loop writes an entry, then advances g_head;
// the ISR reads it, then advances g_tail. Indices are single bytes (atomic to read) and
// wrap at 256 by themselves.
volatile uint32_t g_interval[STEP_RING_SIZE];
volatile uint8_t g_head = 0;
volatile uint8_t g_tail = 0;

volatile int32_t g_position = 0;  // ISR writes; main loop only inside ATOMIC_BLOCK
volatile uint32_t g_wait_left = 0;  // ticks still to chain before the pending STEP edge
volatile int8_t g_dir = 1;          // direction of every queued step
volatile bool g_running = false;    // a STEP edge is pending on Timer1
volatile bool g_expect_more = false;  // the producer promised more steps
volatile uint16_t g_underruns = 0;

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
    const uint32_t interval = g_interval[tail];
    g_tail = static_cast<uint8_t>(tail + 1);
    write_dir(g_dir);  // the STEP edge follows >= STEP_MIN_INTERVAL_TICKS (20 us) later
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
    const uint8_t used = static_cast<uint8_t>(g_head - g_tail);
    return static_cast<uint8_t>(255 - used);
}

bool step_push(int8_t direction, uint32_t interval_ticks, bool last) {
    if (interval_ticks < STEP_MIN_INTERVAL_TICKS) interval_ticks = STEP_MIN_INTERVAL_TICKS;
    const uint8_t head = g_head;
    const uint8_t next = static_cast<uint8_t>(head + 1);
    if (next == g_tail) return false;
    g_interval[head] = interval_ticks;
    g_head = next;  // publish after the entry is written (all volatile: order kept)
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        g_expect_more = !last;
        if (!g_running) {
            g_dir = direction > 0 ? 1 : -1;
            start_locked();
        }
    }
    return true;
}

bool step_busy() { return g_running || g_head != g_tail; }

bool step_running() { return g_running; }

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
        g_expect_more = false;
    }
}

void step_emergency_stop() {
    TCCR1B = TIMER1_STOPPED;
    TIMSK1 = 0;
    PINS_STEP_PORT &= ~(1 << PINS_STEP_BIT);
    g_running = false;
}

uint16_t step_truncate(uint8_t keep, int32_t& rest_position) {
    uint16_t dropped = 0;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        const uint8_t tail = g_tail;
        const uint8_t used = static_cast<uint8_t>(g_head - tail);
        const uint8_t kept = used < keep ? used : keep;
        dropped = static_cast<uint16_t>(used - kept);
        g_head = static_cast<uint8_t>(tail + kept);
        const int32_t left = static_cast<int32_t>(kept) + (g_running ? 1 : 0);
        rest_position = g_position + (g_dir > 0 ? left : -left);
    }
    return dropped;
}

uint16_t step_underruns() {
    uint16_t n;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { n = g_underruns; }
    return n;
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
    g_position = g_position + g_dir;

    const uint8_t tail = g_tail;
    if (tail != g_head) {
        const uint32_t interval = g_interval[tail];
        g_tail = static_cast<uint8_t>(tail + 1);
        program_interval(interval);
    } else {
        TCCR1B = TIMER1_STOPPED;
        g_running = false;
        if (g_expect_more) {  // ran dry mid-move: the train pauses until the next push
            const uint16_t n = g_underruns;
            if (n != 0xFFFF) g_underruns = n + 1;
        }
    }
    // STEP high >= 1 us = 16 cycles whatever the compiler made of the code above:
    // 8 two-cycle no-ops, not a loop, so the ISR stays loop-free.
    __asm__ __volatile__(
        "rjmp .+0\n\trjmp .+0\n\trjmp .+0\n\trjmp .+0\n\t"
        "rjmp .+0\n\trjmp .+0\n\trjmp .+0\n\trjmp .+0\n\t" ::: "memory");
    PINS_STEP_PORT &= ~(1 << PINS_STEP_BIT);
}
