// Logical GPIO pins and the helpers the drivers use.
//
// Contract. Drivers name pins by hal::Pin only; the AVR mapping to ports and bits lives
// in hal/pins.h (one table, every pin commented). gpio_write is safe against the step
// ISR (the read-modify-write of the port register runs with interrupts masked). The
// native fake (tests/fake_hal.cpp) records every write with a timestamp.
#pragma once
#include <stdint.h>

namespace hal {

enum Pin : uint8_t {
    PIN_MOTOR_STEP = 0,  // A4988 STEP (driven by the step ISR through direct port access)
    PIN_MOTOR_DIR,       // A4988 DIR
    PIN_MOTOR_EN,        // A4988 /ENABLE, active low
    PIN_MOTOR_MS1,       // A4988 MS1..MS3: all high = 1/16 microstep
    PIN_MOTOR_MS2,
    PIN_MOTOR_MS3,
    PIN_RES_CS,          // CS5513 /CS
    PIN_RES_SCLK,        // CS5513 SCLK (bit-banged)
    PIN_RES_SDO,         // CS5513 SDO (input; falls when a conversion is ready)
    PIN_ISRC_EN,         // AD8276 50 mA sense current enable, active high
    PIN_HEATER,          // heater MOSFET gate (OC2A PWM; GPIO only to force it low)
    PIN_LED,             // status LED
    PIN_COUNT
};

void gpio_output(Pin pin, bool level);  // make an output, driving `level` first
void gpio_input(Pin pin, bool pullup);
void gpio_write(Pin pin, bool level);
bool gpio_read(Pin pin);
// CS5513 serial port: clocks `bits` bits in, MSB first: SCLK rises, stays high >= 250 ns,
// SDO is read, SCLK falls (the part shifts the next bit out) and stays low >= 250 ns
// (the CS55xx serial timing t1/t2). On the AVR a tight loop on the port registers
// (~1.3 us per bit), not gpio_write/gpio_read.
uint32_t res_shift_in(uint8_t bits);

}  // namespace hal
