#include "clock.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

namespace hal {

namespace {
// Timer3 ticks at 2 MHz; 64-bit tick count = ovf_hi:ovf_lo:TCNT3 (16 + 32 + 16 bits).
volatile uint32_t g_ovf_lo = 0;
volatile uint16_t g_ovf_hi = 0;
}  // namespace

void clock_init() {
    TCCR3A = 0;
    TCCR3B = 1 << CS31;  // normal mode, F_CPU / 8
    TCNT3 = 0;
    TIFR3 = 1 << TOV3;
    TIMSK3 = 1 << TOIE3;
}

uint64_t micros() {
    uint32_t lo;
    uint16_t hi, t;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        lo = g_ovf_lo;
        hi = g_ovf_hi;
        t = TCNT3;
        // An overflow that happened after cli() is pending, not yet counted. If TCNT3
        // is small it wrapped before we read it: count the overflow here.
        if ((TIFR3 & (1 << TOV3)) && t < 0x8000) {
            if (++lo == 0) ++hi;
        }
    }
    const uint64_t ticks = (static_cast<uint64_t>(hi) << 48) | (static_cast<uint64_t>(lo) << 16) | t;
    return ticks >> 1;
}

uint16_t ticks16() { return TCNT3; }  // no ISR touches Timer3's 16-bit registers

void delay_us(uint8_t us) {
    while (us--) __builtin_avr_delay_cycles(F_CPU / 1000000UL);
}

}  // namespace hal

ISR(TIMER3_OVF_vect) {
    const uint32_t lo = hal::g_ovf_lo + 1;
    hal::g_ovf_lo = lo;
    if (lo == 0) hal::g_ovf_hi = hal::g_ovf_hi + 1;
}
