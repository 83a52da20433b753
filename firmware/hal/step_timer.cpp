#include "step_timer.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "../drivers/step_chunk.h"
#include "pins.h"

namespace hal {

namespace {
// Ring of queued entries: the main loop writes an entry, then advances g_head; the ISR
// reads it, then advances g_tail. Indices are single bytes (atomic to read), used
// modulo STEP_RING_SIZE; head - tail (mod 256) is the number of entries queued. An
// entry with count 0 is a wait: one compare period without a STEP edge.
const uint8_t RING_MASK = STEP_RING_SIZE - 1;
// Eight bytes, so the ISR finds an entry with one shift and reads it relative to one pointer.
// Intervals are stored less one tick (the compare value of CTC is the period - 1).
struct Entry {
    __uint24 q8;     // first step's interval less one tick, 1/256 tick
    uint8_t count;   // steps in the run; 0 = a wait
    int16_t add;     // added to the interval after each step
    uint16_t cum16;  // the position once the run is done (low 16 bits)
};
static_assert(sizeof(Entry) == 8, "one shift to index");
volatile Entry g_ring[STEP_RING_SIZE];
volatile uint8_t g_head = 0;
volatile uint8_t g_tail = 0;

volatile __uint24 g_run_q8 = 0;   // interval of the run's pending step (less one tick)
volatile int16_t g_run_add = 0;
volatile uint8_t g_carry = 0;     // fraction of a tick carried to the next interval
int32_t g_position32 = 0;   // main loop only: the last extended position ...
uint16_t g_seen16 = 0;      // ... and its 16-bit value
uint16_t g_pushed16 = 0;    // main loop only: the position once every queued run is done
volatile bool g_expect_more = false;  // the producer promised more steps
volatile uint16_t g_underruns = 0;
volatile uint16_t g_fast_underruns = 0;

}  // namespace

// Shared with the ALERT/RDY ISR (step_position16_locked, step_timer.h).
// Position after every step of the runs taken so far (Klipper's per-run update), in 16
// bits (the ISR's update is short); the steps of the taken run still to come are
// subtracted when it is read, and the main loop extends it to 32 bits (it reads it far
// more often than every 32,767 steps).
volatile uint16_t detail::g_position16 = 0;
volatile uint8_t detail::g_run_left = 0;  // the taken run's steps after the pending edge
volatile uint8_t detail::g_pending = 0;   // the pending compare match is a STEP edge (not a wait)
volatile bool detail::g_running = false;  // a compare match is pending on Timer1
volatile int8_t detail::g_dir = 1;        // direction of every queued step
using detail::g_position16;
using detail::g_run_left;
using detail::g_pending;
using detail::g_running;
using detail::g_dir;

namespace {
const uint8_t TIMER1_STOPPED = 1 << WGM12;               // CTC on OCR1A, no clock
const uint8_t TIMER1_RUNNING = (1 << WGM12) | (1 << CS11);  // CTC, F_CPU / 8

__attribute__((always_inline)) inline void write_dir(int8_t direction) {
    if (direction > 0)
        PINS_DIR_PORT |= 1 << PINS_DIR_BIT;
    else
        PINS_DIR_PORT &= ~(1 << PINS_DIR_BIT);
}

// Program the compare match one interval (plus the carried fraction) after the previous
// one; interrupts masked (ISR or lock). CTC: the counter restarted at the last match,
// so the interval is measured from the previous edge exactly, whatever the ISR latency.
// q8 (the interval less one tick) + carry stays within 24 bits (intervals <=
// STEP_SINGLE_MAX_TICKS).
__attribute__((always_inline)) inline void program_q8(__uint24 q8) {
    const __uint24 sum = q8 + g_carry;
    g_carry = static_cast<uint8_t>(sum);
    OCR1A = static_cast<uint16_t>(sum >> 8);
}

// Take the oldest queued entry; returns its first interval (to program). Interrupts
// masked, ring not empty.
__attribute__((always_inline)) inline __uint24 take_entry(uint8_t tail) {
    volatile Entry& e = g_ring[tail & RING_MASK];
    g_tail = static_cast<uint8_t>(tail + 1);
    const uint8_t count = e.count;
    const __uint24 q8 = e.q8;
    if (count) {
        g_pending = 1;
        g_run_left = static_cast<uint8_t>(count - 1);
        g_position16 = e.cum16;
        g_run_add = e.add;
        g_run_q8 = q8;
    } else {
        g_pending = 0;
    }
    return q8;
}

// Start from idle with the oldest queued entry; interrupts masked.
void start_locked() {
    const uint8_t tail = g_tail;
    if (tail == g_head) return;
    write_dir(g_dir);  // the STEP edge follows >= STEP_MIN_INTERVAL_TICKS (20 us) later
    TCNT1 = 0;
    g_carry = 0;
    g_run_left = 0;
    program_q8(take_entry(tail));
    TIFR1 = 1 << OCF1A;
    TCCR1B = TIMER1_RUNNING;
    g_running = true;
}

// 16-bit position -> 32 bits, from the last extension (main loop).
int32_t extend(uint16_t p16) {
    g_position32 += static_cast<int16_t>(static_cast<uint16_t>(p16 - g_seen16));
    g_seen16 = p16;
    return g_position32;
}

// Queue one entry at `head` (not yet published); interrupts may be on.
void put_entry(uint8_t head, uint32_t q8, int16_t add, uint8_t count, int8_t direction) {
    volatile Entry& e = g_ring[head & RING_MASK];
    e.q8 = static_cast<__uint24>(q8 - 0x100);
    e.count = count;
    e.add = add;
    g_pushed16 = static_cast<uint16_t>(direction > 0 ? g_pushed16 + count : g_pushed16 - count);
    e.cum16 = g_pushed16;
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
    const uint32_t max_q8 = drv::STEP_SINGLE_MAX_TICKS << 8;
    uint8_t waits = 0;
    if (interval_q8 > max_q8) {
        if (count != 1) return false;
        uint32_t ticks = interval_q8 >> 8;
        waits = drv::step_wait_chunks(ticks);
        interval_q8 = (ticks << 8) | (interval_q8 & 0xFF);
    } else if (add_q8 > 0 && interval_q8 + static_cast<uint32_t>(add_q8) * (count - 1) > max_q8) {
        return false;
    }
    uint8_t head = g_head;
    if (static_cast<uint8_t>(head - g_tail) > static_cast<uint8_t>(STEP_RING_SIZE - 1 - waits)) return false;
    // Steps queued while the generator runs keep its direction (see step_timer.h).
    // The ring is filled and published with interrupts on: the ISR reads an entry only
    // after g_head moved past it.
    const int8_t dir = g_running || static_cast<uint8_t>(g_head - g_tail) ? g_dir : (direction > 0 ? 1 : -1);
    for (uint8_t w = 0; w < waits; ++w) {
        put_entry(head, drv::STEP_CHAIN_TICKS << 8, 0, 0, dir);  // a wait: no step, the position stays
        head = static_cast<uint8_t>(head + 1);
    }
    put_entry(head, interval_q8, add_q8, count, dir);
    g_head = static_cast<uint8_t>(head + 1);  // publish after the entries are written (all volatile: order kept)
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        g_expect_more = !last;
        if (!g_running) {
            g_dir = dir;
            start_locked();
        }
    }
    return true;
}

bool step_busy() { return g_running || g_head != g_tail; }

bool step_running() { return g_running; }

int32_t step_position_near(uint16_t p16) {
    return step_position() + static_cast<int16_t>(static_cast<uint16_t>(p16 - g_seen16));
}

int32_t step_position() {
    uint16_t p;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { p = step_position16_locked(); }
    return extend(p);
}

void step_set_position(int32_t steps) {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        const uint16_t shift = static_cast<uint16_t>(static_cast<uint16_t>(steps) - step_position16_locked());
        g_position16 = static_cast<uint16_t>(g_position16 + shift);
        g_pushed16 = static_cast<uint16_t>(g_pushed16 + shift);
        g_position32 = steps;
        g_seen16 = static_cast<uint16_t>(steps);
    }
}

void step_halt() {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        TCCR1B = TIMER1_STOPPED;
        TIFR1 = 1 << OCF1A;
        g_position16 = g_pushed16 = step_position16_locked();
        g_tail = g_head;
        g_run_left = 0;
        g_running = false;
        g_expect_more = false;
    }
}

void step_end_train() {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { g_expect_more = false; }
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
    uint16_t rest16;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        old_head = g_head;
        uint8_t i = g_tail;
        uint8_t want = keep;  // steps after the pending edge still to keep
        uint8_t kept = 0;     // of them, from entries not taken yet
        const uint8_t run = g_run_left;
        if (run >= want) {
            split_dropped = static_cast<uint8_t>(run - want);
            g_run_left = want;
            if (g_dir > 0)
                g_position16 = static_cast<uint16_t>(g_position16 - split_dropped);
            else
                g_position16 = static_cast<uint16_t>(g_position16 + split_dropped);
            want = 0;
        } else {
            want = static_cast<uint8_t>(want - run);
        }
        // Bounded by keep + 1 step entries (each keeps at least one step) plus the
        // waits before them.
        while (want != 0 && i != old_head) {
            volatile Entry& e = g_ring[i & RING_MASK];
            const uint8_t c = e.count;
            if (c > want) {
                e.count = want;
                e.cum16 = static_cast<uint16_t>(g_dir > 0 ? e.cum16 - (c - want) : e.cum16 + (c - want));
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
        rest16 = static_cast<uint16_t>(g_position16 + (g_dir > 0 ? kept : -static_cast<int16_t>(kept)));
        g_pushed16 = rest16;
    }
    rest_position = step_position_near(rest16);
    // The entries past new_head are no longer read by the ISR: count them unmasked.
    uint32_t dropped = split_dropped;
    for (uint8_t j = new_head; j != old_head; j = static_cast<uint8_t>(j + 1)) dropped += g_ring[j & RING_MASK].count;
    return dropped;
}

uint16_t step_underruns() {
    uint16_t n;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { n = g_underruns; }
    return n;
}

uint16_t step_fast_underruns() {
    uint16_t n;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { n = g_fast_underruns; }
    return n;
}

}  // namespace hal

// Step-timer ISR (TIMER1_COMPA = vector 17 on the ATmega2560). Loop-free and short on
// purpose: scripts/isr_cycles.py bounds its worst case from the disassembly (<= 150
// cycles). Per step it only raises STEP, counts the run down, adds the run's `add` to a
// 24-bit interval and programs the next compare; the position moves per run.
ISR(TIMER1_COMPA_vect) {
    using namespace hal;
    if (g_pending) PINS_STEP_PORT |= 1 << PINS_STEP_BIT;  // STEP rises (DIR was set >= 20 us ago)
    const uint8_t run = g_run_left;
    if (run != 0) {  // the next step of the same run
        g_run_left = static_cast<uint8_t>(run - 1);
        const __uint24 q8 = g_run_q8 + g_run_add;
        g_run_q8 = q8;
        program_q8(q8);
    } else {
        const uint8_t tail = g_tail;
        if (tail != g_head) {
            program_q8(take_entry(tail));
        } else {
            TCCR1B = TIMER1_STOPPED;
            g_running = false;
            if (g_expect_more) {  // ran dry mid-move: the train pauses until the next push
                const uint16_t n = g_underruns;
                if (n != 0xFFFF) g_underruns = n + 1;
                if (OCR1A < STEP_START_STOP_TICKS - 1) {  // at speed: steps may be lost
                    const uint16_t f = g_fast_underruns;
                    if (f != 0xFFFF) g_fast_underruns = f + 1;
                }
            }
        }
    }
    // STEP high >= 1 us = 16 cycles: every path above is longer (the shortest is
    // checked by scripts/isr_cycles.py).
    PINS_STEP_PORT &= ~(1 << PINS_STEP_BIT);
}
