#include "fake_hal.h"

#include <string.h>

#include "../hal/clock.h"
#include "../hal/irq.h"
#include "../hal/pwm.h"
#include "../hal/twi.h"

namespace fake {
namespace {

struct State {
    uint64_t now_us;
    bool level[hal::PIN_COUNT];
    bool output[hal::PIN_COUNT];
    bool pullup[hal::PIN_COUNT];
    bool external[hal::PIN_COUNT];
    PinEvent pin_events[MAX_PIN_EVENTS];
    int n_pin_events;
    // CS5513
    uint32_t cs_word;
    int cs_bit;  // index of the bit on SDO, -1 = no word (SDO high)
    // I2C
    I2cEvent i2c_events[MAX_I2C_EVENTS];
    int n_i2c_events;
    uint8_t read_queue[16][8];
    uint8_t read_len[16];
    int rq_head, rq_tail;
    uint8_t nack_address;
    // PWM
    uint16_t duty;  // heater duty in 1/4096
    int pwm_writes;
    // IRQ
    int mask_depth;
    IsrFn pending[16];
    int n_pending;
};

State s;

void record_i2c(bool is_read, uint8_t address, const uint8_t* data, uint8_t n) {
    if (s.n_i2c_events >= MAX_I2C_EVENTS) return;
    I2cEvent& e = s.i2c_events[s.n_i2c_events++];
    e.is_read = is_read;
    e.address = address;
    e.n = n;
    memset(e.data, 0, sizeof e.data);
    memcpy(e.data, data, n < 8 ? n : 8);
}

bool sdo_level() {
    if (s.level[hal::PIN_RES_CS]) return true;  // deselected: high-Z, pull-up
    if (s.cs_bit < 0) return true;             // converting: SDO high
    return (s.cs_word >> s.cs_bit) & 1u;
}

}  // namespace

void reset() {
    memset(&s, 0, sizeof s);
    for (int i = 0; i < hal::PIN_COUNT; ++i) s.level[i] = true;  // inputs float high
    s.cs_bit = -1;
    s.nack_address = 0xFF;
}

void advance_us(uint64_t us) { s.now_us += us; }
uint64_t now_us() { return s.now_us; }

bool level(hal::Pin pin) { return pin == hal::PIN_RES_SDO ? sdo_level() : s.level[pin]; }
bool is_output(hal::Pin pin) { return s.output[pin]; }
bool pullup(hal::Pin pin) { return s.pullup[pin]; }
void set_input(hal::Pin pin, bool lvl) {
    s.external[pin] = true;
    s.level[pin] = lvl;
}
int pin_event_count() { return s.n_pin_events; }
const PinEvent& pin_event(int i) { return s.pin_events[i]; }
int count_writes(hal::Pin pin) {
    int n = 0;
    for (int i = 0; i < s.n_pin_events; ++i) n += s.pin_events[i].pin == pin;
    return n;
}

void cs5513_load(uint32_t word24) {
    s.cs_word = word24 & 0xFFFFFFu;
    s.cs_bit = 23;
}
bool cs5513_word_pending() { return s.cs_bit >= 0; }

void i2c_queue_read(const uint8_t* data, uint8_t n) {
    memcpy(s.read_queue[s.rq_tail % 16], data, n);
    s.read_len[s.rq_tail % 16] = n;
    ++s.rq_tail;
}
void i2c_nack_address(uint8_t address7) { s.nack_address = address7; }
int i2c_event_count() { return s.n_i2c_events; }
const I2cEvent& i2c_event(int i) { return s.i2c_events[i]; }

uint16_t heater_steps() { return s.duty; }
int heater_pwm_writes() { return s.pwm_writes; }

void raise_interrupt(IsrFn fn) {
    if (s.mask_depth > 0) {
        if (s.n_pending < 16) s.pending[s.n_pending++] = fn;
        return;
    }
    fn();
}
bool interrupts_masked() { return s.mask_depth > 0; }

}  // namespace fake

// ---- the hal/ declarations, implemented on the fake state -------------------------
namespace hal {

using fake::s;

void gpio_output(Pin pin, bool lvl) {
    s.output[pin] = true;
    gpio_write(pin, lvl);
}

void gpio_input(Pin pin, bool pull) {
    s.output[pin] = false;
    s.pullup[pin] = pull;
}

void gpio_write(Pin pin, bool lvl) {
    const bool was = s.level[pin];
    s.level[pin] = lvl;
    if (s.n_pin_events < fake::MAX_PIN_EVENTS) {
        fake::PinEvent& e = s.pin_events[s.n_pin_events++];
        e.t_us = s.now_us;
        e.pin = pin;
        e.level = lvl;
    }
    // CS5513: the next bit appears after each SCLK falling edge; after 24 the word is gone.
    if (pin == PIN_RES_SCLK && was && !lvl && !s.level[PIN_RES_CS] && s.cs_bit >= 0) --s.cs_bit;
}

bool gpio_read(Pin pin) { return fake::level(pin); }

uint32_t res_shift_in(uint8_t bits) {  // the same edges, recorded, 1 us apart
    uint32_t word = 0;
    for (uint8_t i = 0; i < bits; ++i) {
        gpio_write(PIN_RES_SCLK, true);
        delay_us(1);
        word = (word << 1) | (gpio_read(PIN_RES_SDO) ? 1u : 0u);
        gpio_write(PIN_RES_SCLK, false);
        delay_us(1);
    }
    return word;
}

void clock_init() {}
uint64_t micros() { return s.now_us; }
void delay_us(uint8_t us) { s.now_us += us; }

void twi_init() {}

bool twi_write(uint8_t address7, const uint8_t* data, uint8_t n) {
    if (address7 == s.nack_address) return false;
    fake::record_i2c(false, address7, data, n);
    return true;
}

bool twi_read(uint8_t address7, uint8_t* data, uint8_t n) {
    if (address7 == s.nack_address || s.rq_head == s.rq_tail) return false;
    const int slot = s.rq_head++ % 16;
    memset(data, 0, n);
    memcpy(data, s.read_queue[slot], n < s.read_len[slot] ? n : s.read_len[slot]);
    fake::record_i2c(true, address7, data, n);
    return true;
}

void heater_pwm_init() {}
void heater_pwm_set_steps(uint16_t steps) {
    s.duty = steps;
    ++s.pwm_writes;
}
void heater_pwm_emergency_off() { s.duty = 0; }

InterruptLock::InterruptLock() : saved_(0) { ++s.mask_depth; }

InterruptLock::~InterruptLock() {
    if (--s.mask_depth > 0) return;
    // Run latched interrupts now, as the AVR does when SREG.I is restored.
    for (int i = 0; i < s.n_pending; ++i) s.pending[i]();
    s.n_pending = 0;
}

}  // namespace hal
