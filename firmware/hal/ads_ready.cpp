#include "ads_ready.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <string.h>
#include <util/atomic.h>

#include "clock.h"
#include "pins.h"
#include "step_timer.h"
#include "twi.h"

namespace {
struct Slot {  // eight bytes: one shift to index
    uint32_t t_us;
    uint16_t step_position16;
    volatile uint8_t bytes[2];
};
static_assert(sizeof(Slot) == 8, "one shift to index");
const uint8_t SLOT_MASK = hal::ADS_STREAM_SLOTS - 1;
Slot g_slots[hal::ADS_STREAM_SLOTS];
volatile uint8_t g_status[hal::ADS_STREAM_SLOTS];  // each slot's read: hal::TWI_ASYNC_*
volatile uint8_t g_head;     // ISR writes
volatile uint8_t g_tail;     // main loop
volatile uint8_t g_lost;     // samples dropped on a full ring since the last take (saturating)
volatile uint8_t g_every = 1;
volatile uint8_t g_until;    // edges until the next sample
volatile uint8_t g_address;
volatile bool g_have_prev;
volatile uint32_t g_prev_us;   // the last edge: the running conversion's start
volatile uint16_t g_prev_pos;
volatile uint16_t g_edges;     // since the start (wraps: the main loop takes differences)
}  // namespace

namespace hal {

void ads_stream_start(uint8_t address7, uint8_t every) {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        DDRE &= static_cast<uint8_t>(~(1 << PINS_ADS_RDY_BIT));  // input; the board's pull-up holds it high
        EICRB = static_cast<uint8_t>((EICRB & ~((1 << ISC41) | (1 << ISC40))) | (1 << ISC41));  // falling edge
        EIFR = 1 << INTF4;  // forget an edge from before
        g_address = address7;
        g_every = every ? every : 1;
        g_until = g_every;
        g_have_prev = false;
        g_edges = 0;
        g_tail = g_head;
        g_lost = 0;
        EIMSK |= 1 << INT4;
    }
}

void ads_stream_stop() {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        EIMSK &= static_cast<uint8_t>(~(1 << INT4));
        g_tail = g_head;
        g_lost = 0;
        g_have_prev = false;
    }
}

bool ads_stream_take(AdsSample& s, uint8_t& lost) {
    const uint8_t tail = g_tail;
    if (tail == g_head) return false;
    const Slot& slot = g_slots[tail & SLOT_MASK];
    const uint8_t status = g_status[tail & SLOT_MASK];
    if (status == TWI_ASYNC_PENDING) return false;  // its read is under way
    s.t_us = slot.t_us;
    s.step_position16 = slot.step_position16;
    s.bytes[0] = slot.bytes[0];
    s.bytes[1] = slot.bytes[1];
    s.status = status;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        lost = g_lost;
        g_lost = 0;
        g_tail = static_cast<uint8_t>(tail + 1);
    }
    return true;
}

void ads_stream_edges(uint16_t& edges, uint32_t& last_us) {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        edges = g_edges;
        last_us = g_prev_us;
    }
}

}  // namespace hal

// A conversion finished (ALERT/RDY fell): queue the sample whose conversion it ends
// (stamped with that conversion's start, the previous edge) and start reading its
// result, then stamp this edge. The clock is latched first; the rest cannot move while
// interrupts are masked. Loop- and call-free (scripts/isr_cycles.py).
ISR(INT4_vect) {
    const uint16_t t16 = TCNT3;
    const uint8_t overflow = TIFR3 & (1 << TOV3);
    if (g_have_prev && --g_until == 0) {
        g_until = g_every;
        const uint8_t head = g_head;
        if (static_cast<uint8_t>(head - g_tail) >= hal::ADS_STREAM_SLOTS) {
            if (g_lost != 0xFF) g_lost = static_cast<uint8_t>(g_lost + 1);
        } else {
            const uint8_t i = head & SLOT_MASK;
            // the byte offset as a byte (-Os would shift a 16-bit index in a loop)
            Slot& slot = *reinterpret_cast<Slot*>(reinterpret_cast<uint8_t*>(g_slots) + static_cast<uint8_t>(i << 3));
            slot.t_us = g_prev_us;
            slot.step_position16 = g_prev_pos;
            if (!hal::twi_async_read2(g_address, slot.bytes, &g_status[i])) g_status[i] = hal::TWI_ASYNC_FAILED;
            g_head = static_cast<uint8_t>(head + 1);
        }
    }
    g_have_prev = true;
    g_edges = static_cast<uint16_t>(g_edges + 1);
    g_prev_us = hal::micros32_from(t16, overflow);
    g_prev_pos = hal::step_position16_locked();
}
