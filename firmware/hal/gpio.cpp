#include "gpio.h"

#include <util/atomic.h>

#include "pins.h"

namespace hal {

// The port registers are shared with the step ISR (PORTA: STEP/DIR), so every
// read-modify-write runs with interrupts masked. For ports A..G with constant addresses
// the compiler emits a single sbi/cbi anyway; the block costs a few cycles.
#define GPIO_WRITE_CASE(name, port, bit) \
    case name:                           \
        if (level)                       \
            PORT##port |= 1 << (bit);    \
        else                             \
            PORT##port &= ~(1 << (bit)); \
        break;

#define GPIO_DDR_CASE(name, port, bit) \
    case name:                         \
        if (out)                       \
            DDR##port |= 1 << (bit);   \
        else                           \
            DDR##port &= ~(1 << (bit)); \
        break;

#define GPIO_READ_CASE(name, port, bit) \
    case name:                          \
        return (PIN##port >> (bit)) & 1;

namespace {
void set_direction(Pin pin, bool out) {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        switch (pin) {
            HAL_PIN_TABLE(GPIO_DDR_CASE)
            default:
                break;
        }
    }
}
}  // namespace

void gpio_write(Pin pin, bool level) {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        switch (pin) {
            HAL_PIN_TABLE(GPIO_WRITE_CASE)
            default:
                break;
        }
    }
}

void gpio_output(Pin pin, bool level) {
    gpio_write(pin, level);  // PORT first: no glitch when DDR switches to output
    set_direction(pin, true);
}

void gpio_input(Pin pin, bool pullup) {
    set_direction(pin, false);
    gpio_write(pin, pullup);  // PORT bit of an input = pull-up
}

uint32_t res_shift_in(uint8_t bits) {
    uint32_t word = 0;
    for (uint8_t i = 0; i < bits; ++i) {
        // sbi/cbi: single instructions, so the ISRs' writes to PORTC are never undone.
        PINS_RES_SCLK_PORT |= 1 << PINS_RES_SCLK_BIT;
        __asm__ __volatile__("rjmp .+0\n\trjmp .+0" ::: "memory");  // 4 cycles: high >= 250 ns
        word <<= 1;
        if (PINS_RES_SDO_PIN & (1 << PINS_RES_SDO_BIT)) word |= 1;
        PINS_RES_SCLK_PORT &= ~(1 << PINS_RES_SCLK_BIT);
        __asm__ __volatile__("rjmp .+0\n\trjmp .+0" ::: "memory");  // low >= 250 ns
    }
    return word;
}

bool gpio_read(Pin pin) {
    switch (pin) {
        HAL_PIN_TABLE(GPIO_READ_CASE)
        default:
            return false;
    }
}

}  // namespace hal
