#include "pwm.h"

#include <avr/io.h>
#include <util/atomic.h>

#include "gpio.h"

namespace hal {

void heater_pwm_init() {
    gpio_output(PIN_HEATER, false);
    OCR2A = 0;
    TCCR2A = (1 << WGM21) | (1 << WGM20);  // fast PWM, TOP = 0xFF, OC2A disconnected
    TCCR2B = 1 << CS22;                    // F_CPU / 64 / 256 = 976.6 Hz
}

void heater_pwm_set(uint8_t duty) {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        if (duty == 0) {
            TCCR2A &= ~((1 << COM2A1) | (1 << COM2A0));
            gpio_write(PIN_HEATER, false);
        } else {
            // Non-inverting: high for (OCR2A + 1) / 256 of the period; 255 = always on.
            OCR2A = duty;
            TCCR2A |= 1 << COM2A1;
        }
    }
}

}  // namespace hal
