#include "step_timer.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "../drivers/step_chunk.h"
#include "pins.h"

namespace hal {

namespace {
// Ring of queued step runs: the main loop writes an entry, then advances g_head; the
// ISR reads it, then advances g_tail. Indices are single bytes (atomic to read), used
// modulo STEP_RING_SIZE; head - tail (mod 256) is the number of entries queued.
const uint8_t RING_MASK = STEP_RING_SIZE - 1;
volatile uint32_t g_q8[STEP_RING_SIZE];    // first step's interval, 1/256 tick
volatile int16_t g_add[STEP_RING_SIZE];    // added to the interval after each step
volatile uint8_t g_count[STEP_RING_SIZE];  // steps in the run, >= 1
volatile uint8_t g_head = 0;
volatile uint8_t g_tail = 0;

volatile uint32_t g_run_q8 = 0;   // interval of the run's next step
volatile int16_t g_run_add = 0;
volatile uint8_t g_run_left = 0;  // its steps after the pending edge
volatile uint8_t g_carry = 0;     // fraction of a tick carried to the next interval

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

// Program the compare match for the next STEP edge, one interval (plus the carried
// fraction) after the previous one; interrupts must be masked (ISR or lock). CTC: the
// counter restarted at the last match, so the interval is measured from the previous
// STEP edge exactly, whatever the ISR latency.
__attribute__((always_inline)) inline void program_q8(uint32_t q8) {
    const uint32_t sum = q8 + g_carry;
    g_carry = static_cast<uint8_t>(sum);
    uint32_t interval = sum >> 8;
    OCR1A = drv::step_take_chunk(interval);
    g_wait_left = interval;
}

// Take the oldest queued run and program its first step; interrupts masked, ring not empty.
__attribute__((always_inline)) inline void take_entry(uint8_t tail) {
    const uint8_t i = tail & RING_MASK;
    const uint32_t q8 = g_q8[i];
    const int16_t add = g_add[i];
    g_run_add = add;
    g_run_q8 = q8 + add;
    g_run_left = static_cast<uint8_t>(g_count[i] - 1);
    g_tail = static_cast<uint8_t>(tail + 1);
    program_q8(q8);
}

// Start from idle with the oldest queued run; interrupts masked.
void start_locked() {
    const uint8_t tail = g_tail;
    if (tail == g_head) return;
    write_dir(g_dir);  // the STEP edge follows >= STEP_MIN_INTERVAL_TICKS (20 us) later
    TCNT1 = 0;
    g_carry = 0;
    take_entry(tail);
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
    return static_cast<uint8_t>(STEP_RING_SIZE - used);
}

bool step_push(int8_t direction, uint32_t interval_q8, int16_t add_q8, uint8_t count, bool last) {
    if (count == 0) return false;
    const uint32_t min_q8 = static_cast<uint32_t>(STEP_MIN_INTERVAL_TICKS) << 8;
    if (interval_q8 < min_q8) interval_q8 = min_q8;
    // A shrinking run never goes below the minimum either (its last step is the shortest).
    if (add_q8 < 0 && interval_q8 + static_cast<int32_t>(add_q8) * (count - 1) < min_q8) add_q8 = 0;
    const uint8_t head = g_head;
    if (static_cast<uint8_t>(head - g_tail) >= STEP_RING_SIZE) return false;
    const uint8_t i = head & RING_MASK;
    g_q8[i] = interval_q8;
    g_add[i] = add_q8;
    g_count[i] = count;
    g_head = static_cast<uint8_t>(head + 1);  // publish after the entry is written (all volatile: order kept)
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
        g_run_left = 0;
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

uint32_t step_truncate(uint8_t keep, int32_t& rest_position) {
    uint8_t old_head, new_head;
    uint8_t split_dropped = 0;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        old_head = g_head;
        uint8_t i = g_tail;
        uint8_t want = keep;  // steps after the pending edge still to keep
        uint8_t kept = 0;
        const uint8_t run = g_run_left;
        if (run >= want) {
            split_dropped = static_cast<uint8_t>(run - want);
            g_run_left = want;
            kept = want;
            want = 0;
        } else {
            kept = run;
            want = static_cast<uint8_t>(want - run);
        }
        // Bounded by keep + 1 iterations: each one keeps at least one step.
        while (want != 0 && i != old_head) {
            const uint8_t c = g_count[i & RING_MASK];
            if (c > want) {
                g_count[i & RING_MASK] = want;
                split_dropped = static_cast<uint8_t>(split_dropped + (c - want));
                kept = static_cast<uint8_t>(kept + want);
                want = 0;
            } else {
                kept = static_cast<uint8_t>(kept + c);
                want = static_cast<uint8_t>(want - c);
            }
            i = static_cast<uint8_t>(i + 1);
        }
        new_head = i;
        g_head = new_head;
        const int32_t left = static_cast<int32_t>(kept) + (g_running ? 1 : 0);
        rest_position = g_position + (g_dir > 0 ? left : -left);
    }
    // The entries past new_head are no longer read by the ISR: count them unmasked.
    uint32_t dropped = split_dropped;
    for (uint8_t j = new_head; j != old_head; j = static_cast<uint8_t>(j + 1)) dropped += g_count[j & RING_MASK];
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

    const uint8_t run = g_run_left;
    const uint8_t tail = g_tail;
    if (run != 0) {  // the next step of the same run
        g_run_left = static_cast<uint8_t>(run - 1);
        const uint32_t q8 = g_run_q8;
        g_run_q8 = q8 + g_run_add;
        program_q8(q8);
    } else if (tail != g_head) {
        take_entry(tail);
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
