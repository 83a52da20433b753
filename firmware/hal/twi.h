// I2C (TWI) master, 400 kHz, with bus recovery.
//
// Contract. Blocking (but for the interrupt-driven 2-byte read below), but every wait is bounded (TWI_TIMEOUT_US per bus event): a stuck
// or absent device returns false and never hangs the main loop. A write sends
// address + bytes + STOP; a read sends address(R), receives n bytes (ACK all but the
// last) + STOP. A NACK fails the transfer (STOP, peripheral reset). A time-out, a bus
// error or a lost arbitration means the bus may be held (a slave stuck mid-byte pulls
// SDA low): the bus is recovered as NXP UM10204 3.1.16 describes - the TWI is turned
// off, SCL clocked by hand (open drain, ~100 kHz) until SDA is released or 9 clocks
// have passed, a STOP generated, the TWI turned on again - and counted
// (twi_recoveries()); further transfers fail at once for TWI_BACKOFF_US so a dead bus
// costs one recovery per back-off, not the main loop's time.
#pragma once
#include <stdint.h>

#ifdef __AVR__
#include <avr/io.h>
#endif

namespace hal {

static const uint16_t TWI_TIMEOUT_US = 1000;
static const uint32_t TWI_BACKOFF_US = 10000;

void twi_init();
bool twi_write(uint8_t address7, const uint8_t* data, uint8_t n);
bool twi_read(uint8_t address7, uint8_t* data, uint8_t n);
uint16_t twi_recoveries();  // since boot, saturating

// Interrupt-driven read of two bytes (address(R), two bytes, STOP), started from an ISR
// (interrupts masked): the TWI interrupt moves it on and stores the bytes in out[0..1],
// then *status = TWI_ASYNC_OK, or TWI_ASYNC_FAILED on a NACK or bus error. false (and
// nothing started) while another transfer runs. The blocking functions above wait for
// a running read to end first (or abort it after TWI_TIMEOUT_US). twi_async_service()
// (main loop) aborts a read the bus held longer than TWI_TIMEOUT_US and recovers the
// bus after a bus error, as the blocking functions do.
static const uint8_t TWI_ASYNC_PENDING = 0;
static const uint8_t TWI_ASYNC_OK = 1;
static const uint8_t TWI_ASYNC_FAILED = 2;
namespace detail {  // the interrupt-driven read's state (twi.cpp)
extern volatile uint8_t g_astate;  // 0 idle, 1 START sent, 2 SLA+R sent, 3 first byte, 4 second byte
extern volatile uint8_t* volatile g_aout;
extern volatile uint8_t* volatile g_astatus;
extern volatile uint8_t g_asla;
extern volatile uint16_t g_astart;  // Timer3 ticks when it began
}  // namespace detail

#ifdef __AVR__
// Inline: the ALERT/RDY ISR that starts it stays free of calls.
__attribute__((always_inline)) inline bool twi_async_read2(uint8_t address7, volatile uint8_t* out,
                                                           volatile uint8_t* status) {
    if (detail::g_astate || (TWCR & (1 << TWSTO))) return false;
    detail::g_aout = out;
    detail::g_astatus = status;
    *status = TWI_ASYNC_PENDING;
    detail::g_asla = static_cast<uint8_t>((address7 << 1) | 1);
    detail::g_astart = TCNT3;
    detail::g_astate = 1;
    TWCR = (1 << TWINT) | (1 << TWEN) | (1 << TWSTA) | (1 << TWIE);
    return true;
}
#endif
bool twi_async_busy();
void twi_async_service();

}  // namespace hal
