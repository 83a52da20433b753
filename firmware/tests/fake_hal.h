// Native stand-in for the hal/ functions the drivers call (gpio, clock, twi, pwm, irq).
//
// Contract. Everything is recorded so driver tests can assert on transactions: pin
// writes with the fake time, I2C writes and reads, PWM duties. Time only moves when a
// test advances it or a driver busy-waits (delay_us). Scripted devices:
//   - a CS5513 on PIN_RES_CS/SCLK/SDO: cs5513_load(word) makes SDO fall (word ready);
//     it shifts a new bit out after each SCLK falling edge, like the part;
//   - I2C: queued read payloads and an optional NACK address.
// Simulated interrupts: raise_interrupt(fn) runs fn now, or when the outermost
// hal::InterruptLock ends if one is held (latched like an AVR interrupt flag).
// reset() restores the power-on state; every test calls it first.
#pragma once
#include <stdint.h>

#include "../hal/gpio.h"

namespace fake {

struct PinEvent {
    uint64_t t_us;
    uint8_t pin;
    bool level;
};

struct I2cEvent {
    bool is_read;
    uint8_t address;
    uint8_t n;
    uint8_t data[8];
};

static const int MAX_PIN_EVENTS = 512;
static const int MAX_I2C_EVENTS = 64;

void reset();
void advance_us(uint64_t us);
uint64_t now_us();

// Pins.
bool level(hal::Pin pin);
bool is_output(hal::Pin pin);
bool pullup(hal::Pin pin);
void set_input(hal::Pin pin, bool level);  // drive an input from outside
int pin_event_count();
const PinEvent& pin_event(int i);
int count_writes(hal::Pin pin);

// CS5513 model.
void cs5513_load(uint32_t word24);
bool cs5513_word_pending();

// I2C.
void i2c_queue_read(const uint8_t* data, uint8_t n);
void i2c_nack_address(uint8_t address7);  // 0xFF = everyone ACKs
int i2c_event_count();
const I2cEvent& i2c_event(int i);

// PWM.
uint16_t heater_steps();  // duty in 1/4096
int heater_pwm_writes();

// Interrupts.
typedef void (*IsrFn)();
void raise_interrupt(IsrFn fn);
bool interrupts_masked();

}  // namespace fake
