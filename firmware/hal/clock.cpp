#include "clock.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

namespace hal {

namespace {
// Timer3 ticks at 2 MHz and overflows every 65536 ticks = 32768 us; the overflow ISR
// adds that to g_us_base, so micros() is one 64-bit add of TCNT3 / 2 (no 64-bit shifts:
// they are library loops on the AVR, and the main loop reads the clock often).
const uint16_t US_PER_OVERFLOW = 32768;
}  // namespace

volatile uint64_t detail::g_us_base = 0;

void clock_init() {
    TCCR3A = 0;
    TCCR3B = 1 << CS31;  // normal mode, F_CPU / 8
    TCNT3 = 0;
    TIFR3 = 1 << TOV3;
    TIMSK3 = 1 << TOIE3;
}

uint64_t micros() {
    uint64_t base;
    uint16_t t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        base = detail::g_us_base;
        t = TCNT3;
        // An overflow that happened after cli() is pending, not yet counted. If TCNT3
        // is small it wrapped before we read it: count the overflow here.
        if ((TIFR3 & (1 << TOV3)) && t < 0x8000) base += US_PER_OVERFLOW;
    }
    return base + (t >> 1);
}

uint16_t ticks16() { return TCNT3; }  // no ISR touches Timer3's 16-bit registers

void delay_us(uint8_t us) {
    while (us--) __builtin_avr_delay_cycles(F_CPU / 1000000UL);
}

}  // namespace hal

ISR(TIMER3_OVF_vect) { hal::detail::g_us_base = hal::detail::g_us_base + hal::US_PER_OVERFLOW; }
