#include "twi.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "clock.h"

namespace hal {

volatile uint8_t detail::g_astate = 0;
volatile uint8_t* volatile detail::g_aout = 0;
volatile uint8_t* volatile detail::g_astatus = 0;
volatile uint8_t detail::g_asla = 0;
volatile uint16_t detail::g_astart = 0;
using detail::g_astate;
using detail::g_aout;
using detail::g_astatus;
using detail::g_asla;
using detail::g_astart;

namespace {
const uint32_t TWI_HZ = 400000UL;

// TWSR status codes (prescaler bits masked), ATmega2560 datasheet tables 24-2/24-3.
const uint8_t ST_BUS_ERROR = 0x00;
const uint8_t ST_START = 0x08;
const uint8_t ST_REP_START = 0x10;
const uint8_t ST_SLA_W_ACK = 0x18;
const uint8_t ST_DATA_W_ACK = 0x28;
const uint8_t ST_ARB_LOST = 0x38;
const uint8_t ST_SLA_R_ACK = 0x40;
const uint8_t ST_DATA_R_ACK = 0x50;
const uint8_t ST_DATA_R_NACK = 0x58;

// TWI pins on the ATmega2560: SCL = PD0, SDA = PD1 (external pull-ups on the board).
const uint8_t SCL = 1 << 0;
const uint8_t SDA = 1 << 1;

volatile bool g_arecover = false;  // a bus error in the interrupt-driven read asks for a recovery

uint16_t g_recoveries = 0;
uint64_t g_backoff_until_us = 0;
bool g_bus_suspect = false;  // the last failure may have left the bus held

uint8_t status() { return TWSR & 0xF8; }

// Timer3 ticks (2 MHz) in the time-out: polled cheaply, so the end of a byte is seen
// within a few cycles (the ADS1115 starts converting then; the sampler stamps it).
const uint16_t TIMEOUT_TICKS = TWI_TIMEOUT_US * 2;

// Wait for TWINT, bounded.
bool wait_int() {
    const uint16_t t0 = ticks16();
    while (!(TWCR & (1 << TWINT))) {
        if (static_cast<uint16_t>(ticks16() - t0) > TIMEOUT_TICKS) {
            g_bus_suspect = true;
            return false;
        }
    }
    const uint8_t st = status();
    if (st == ST_BUS_ERROR || st == ST_ARB_LOST) g_bus_suspect = true;
    return true;
}

bool command(uint8_t twcr_bits) {
    TWCR = static_cast<uint8_t>((1 << TWINT) | (1 << TWEN) | twcr_bits);
    return wait_int();
}

void stop() {
    TWCR = (1 << TWINT) | (1 << TWEN) | (1 << TWSTO);
    const uint16_t t0 = ticks16();
    while (TWCR & (1 << TWSTO)) {
        if (static_cast<uint16_t>(ticks16() - t0) > TIMEOUT_TICKS) break;
    }
}

void half_clock() {
    // 5 us: ~100 kHz, within every I2C device's timing.
    const uint64_t t0 = micros();
    while (micros() - t0 < 5) {
    }
}

// Free a bus a slave holds: clock SCL by hand until SDA is high (at most 9 clocks),
// then a STOP (SDA rising while SCL is high). Open drain: a line is driven low by
// making it an output (PORT bit 0) and released by making it an input.
void recover_bus() {
    TWCR = 0;
    PORTD &= static_cast<uint8_t>(~(SCL | SDA));
    DDRD &= static_cast<uint8_t>(~(SCL | SDA));
    half_clock();
    for (uint8_t i = 0; i < 9 && !(PIND & SDA); ++i) {
        DDRD |= SCL;
        half_clock();
        DDRD &= static_cast<uint8_t>(~SCL);
        half_clock();
    }
    DDRD |= SDA;  // SDA low while SCL is high ...
    half_clock();
    DDRD &= static_cast<uint8_t>(~SDA);  // ... then released: STOP
    half_clock();
    twi_init();
    if (g_recoveries != 0xFFFF) ++g_recoveries;
    g_backoff_until_us = micros() + TWI_BACKOFF_US;
    g_bus_suspect = false;
}

bool fail() {
    if (g_bus_suspect) {
        recover_bus();
        return false;
    }
    stop();
    TWCR = 0;  // reset the TWI state machine, release SDA/SCL
    TWCR = 1 << TWEN;
    return false;
}

bool begin(uint8_t sla) {
    if (!command(1 << TWSTA)) return false;
    const uint8_t st = status();
    if (st != ST_START && st != ST_REP_START) return false;
    TWDR = sla;
    return command(0);
}

bool backing_off() { return g_backoff_until_us != 0 && micros() < g_backoff_until_us; }

void async_abort_locked() {
    if (g_astate) {
        g_astate = 0;
        *g_astatus = TWI_ASYNC_FAILED;
    }
}

// A blocking transfer begins: an interrupt-driven read must be over (bounded wait), and
// the TWI interrupt off.
void async_settle() {
    const uint16_t t0 = ticks16();
    while (g_astate && static_cast<uint16_t>(ticks16() - t0) <= TIMEOUT_TICKS) {
    }
    bool held = false;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        held = g_astate != 0;
        async_abort_locked();
        TWCR = static_cast<uint8_t>(TWCR & ~((1 << TWIE) | (1 << TWINT)));
    }
    if (held || g_arecover) {
        g_arecover = false;
        recover_bus();
    }
}
}  // namespace

void twi_init() {
    TWSR = 0;                                             // prescaler 1
    TWBR = static_cast<uint8_t>((F_CPU / TWI_HZ - 16) / 2);  // 12 -> 400 kHz
    TWCR = 1 << TWEN;
}

bool twi_write(uint8_t address7, const uint8_t* data, uint8_t n) {
    async_settle();
    if (backing_off()) return false;
    if (!begin(static_cast<uint8_t>(address7 << 1)) || status() != ST_SLA_W_ACK) return fail();
    for (uint8_t i = 0; i < n; ++i) {
        TWDR = data[i];
        if (!command(0) || status() != ST_DATA_W_ACK) return fail();
    }
    stop();
    return true;
}

bool twi_read(uint8_t address7, uint8_t* data, uint8_t n) {
    if (n == 0) return true;
    async_settle();
    if (backing_off()) return false;
    if (!begin(static_cast<uint8_t>((address7 << 1) | 1)) || status() != ST_SLA_R_ACK) return fail();
    for (uint8_t i = 0; i < n; ++i) {
        const bool last = i + 1 == n;
        if (!command(last ? 0 : (1 << TWEA))) return fail();
        if (status() != (last ? ST_DATA_R_NACK : ST_DATA_R_ACK)) return fail();
        data[i] = TWDR;
    }
    stop();
    return true;
}

uint16_t twi_recoveries() { return g_recoveries; }

bool twi_async_busy() { return g_astate != 0; }

void twi_async_service() {
    bool stuck = false;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        if (g_astate && static_cast<uint16_t>(ticks16() - g_astart) > TIMEOUT_TICKS) {
            stuck = true;
            async_abort_locked();
            TWCR = 0;
        }
    }
    if (stuck || g_arecover) {
        g_arecover = false;
        recover_bus();
    }
}

}  // namespace hal

// TWI interrupt: the next step of the interrupt-driven 2-byte read (vector 39).
ISR(TWI_vect) {
    using namespace hal;
    const uint8_t st = status();
    const uint8_t on = (1 << TWINT) | (1 << TWEN) | (1 << TWIE);
    switch (g_astate) {
    case 1:
        if (st == ST_START || st == ST_REP_START) {
            TWDR = g_asla;
            TWCR = on;
            g_astate = 2;
            return;
        }
        break;
    case 2:
        if (st == ST_SLA_R_ACK) {
            TWCR = on | (1 << TWEA);
            g_astate = 3;
            return;
        }
        break;
    case 3:
        if (st == ST_DATA_R_ACK) {
            g_aout[0] = TWDR;
            TWCR = on;
            g_astate = 4;
            return;
        }
        break;
    case 4:
        if (st == ST_DATA_R_NACK) {
            g_aout[1] = TWDR;
            TWCR = (1 << TWINT) | (1 << TWEN) | (1 << TWSTO);
            *g_astatus = TWI_ASYNC_OK;
            g_astate = 0;
            return;
        }
        break;
    default:
        break;
    }
    // NACK, bus error, lost arbitration, or a stray interrupt: end it
    if (st == ST_BUS_ERROR || st == ST_ARB_LOST) g_arecover = true;
    TWCR = (1 << TWINT) | (1 << TWEN) | (1 << TWSTO);
    if (g_astate) {
        g_astate = 0;
        *g_astatus = TWI_ASYNC_FAILED;
    }
}
