// Time for drivers: a monotonic microsecond clock and short busy waits.
//
// Contract. micros() never goes backwards and is read atomically (on the AVR: Timer3
// at F_CPU/8 plus an overflow count, read inside an interrupt lock with the pending
// overflow accounted for). delay_us() busy-waits at least `us` microseconds and is meant
// for bit-bang timing only (a few microseconds); never use it to wait for a sensor.
#pragma once
#include <stdint.h>

namespace hal {

void clock_init();
uint64_t micros();
// The low 32 bits of micros(), for an ISR (interrupts masked; wraps every 71.6 min).
uint32_t micros32_locked();
// Timer3's raw count (2 MHz, wraps every 32.8 ms): a cheap clock for short bounded waits.
uint16_t ticks16();
void delay_us(uint8_t us);

}  // namespace hal
