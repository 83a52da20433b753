// Time for drivers: a monotonic microsecond clock and short busy waits.
//
// Contract. micros() never goes backwards and is read atomically (on the AVR: Timer3
// at F_CPU/8 plus an overflow count, read inside an interrupt lock with the pending
// overflow accounted for). delay_us() busy-waits at least `us` microseconds and is meant
// for bit-bang timing only (a few microseconds); never use it to wait for a sensor.
#pragma once
#include <stdint.h>

#ifdef __AVR__
#include <avr/io.h>
#endif

namespace hal {

namespace detail {
extern volatile uint64_t g_us_base;  // microseconds at Timer3's last overflow (its ISR adds)
}  // namespace detail

void clock_init();
uint64_t micros();
#ifdef __AVR__
// The low 32 bits of micros() at a Timer3 count an ISR latched (interrupts masked; wraps
// every 71.6 min), with TOV3 as it read it right after: an overflow not yet counted by
// the overflow ISR. Inline: the ALERT/RDY ISR stays free of calls.
__attribute__((always_inline)) inline uint32_t micros32_from(uint16_t t, uint8_t tov3) {
    // the low half of the base, byte by byte (little-endian; char access may alias anything)
    const volatile uint8_t* b = reinterpret_cast<const volatile uint8_t*>(&detail::g_us_base);
    uint32_t base = static_cast<uint32_t>(b[0]) | (static_cast<uint32_t>(b[1]) << 8) |
                    (static_cast<uint32_t>(b[2]) << 16) | (static_cast<uint32_t>(b[3]) << 24);
    if (tov3 && t < 0x8000) base += 32768;
    return base + (t >> 1);
}
#endif
// Timer3's raw count (2 MHz, wraps every 32.8 ms): a cheap clock for short bounded waits.
uint16_t ticks16();
void delay_us(uint8_t us);

}  // namespace hal
