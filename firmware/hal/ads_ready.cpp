#include "ads_ready.h"

#include <avr/interrupt.h>
#include <avr/io.h>

#include "irq.h"
#include "pins.h"

namespace {
volatile uint8_t g_pulses;
}  // namespace

namespace hal {

void ads_ready_init() {
    InterruptLock lock;
    DDRE &= static_cast<uint8_t>(~(1 << PINS_ADS_RDY_BIT));   // input; the board's pull-up holds it high
    EICRB = static_cast<uint8_t>((EICRB & ~((1 << ISC41) | (1 << ISC40))) | (1 << ISC41));  // falling edge
    EIFR = 1 << INTF4;   // forget an edge from before
    EIMSK |= 1 << INT4;
    g_pulses = 0;
}

uint8_t ads_ready_take() {
    InterruptLock lock;
    const uint8_t n = g_pulses;
    g_pulses = 0;
    return n;
}

}  // namespace hal

// A conversion finished: count it (the main loop reads the result).
ISR(INT4_vect) {
    const uint8_t n = g_pulses;
    if (n != 0xFF) g_pulses = static_cast<uint8_t>(n + 1);
}
