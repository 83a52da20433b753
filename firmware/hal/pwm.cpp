#include "pwm.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <util/atomic.h>

#include "../drivers/heater_dither.h"
#include "gpio.h"

namespace hal {

namespace {
volatile drv::HeaterDither g_dither = {0, 0, 0};
volatile bool g_on = false;
const uint8_t FAST_PWM = (1 << WGM21) | (1 << WGM20);  // TOP = 0xFF
const uint8_t PRESCALE_64 = 1 << CS22;                  // F_CPU / 64 / 256 = 976.6 Hz
}  // namespace

void heater_pwm_init() {
    TIMSK2 = 0;
    gpio_output(PIN_HEATER, false);
    OCR2A = 0;
    TCCR2A = FAST_PWM;  // OC2A disconnected
    TCCR2B = PRESCALE_64;
}

void heater_pwm_set_steps(uint16_t steps) {
    if (steps > drv::HEATER_DUTY_STEPS) steps = drv::HEATER_DUTY_STEPS;
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        if (steps == 0) {
            TIMSK2 = 0;
            TCCR2A = FAST_PWM;
            gpio_write(PIN_HEATER, false);
            g_on = false;
            return;
        }
        drv::HeaterDither d;
        d.set(steps);
        g_dither.base = d.base;
        g_dither.frac = d.frac;
        if (!g_on) {
            g_on = true;
            // Clear the OC2A latch with a forced compare in normal mode (forcing is
            // ignored in PWM modes), then fast PWM with the output disconnected: the
            // ISR connects it at the next compare match, when a period is in its low part.
            TCCR2A = 1 << COM2A1;
            TCCR2B = (1 << FOC2A) | PRESCALE_64;
            TCCR2A = FAST_PWM;
            TCCR2B = PRESCALE_64;
            g_dither.acc = 0;
            TIFR2 = 1 << OCF2A;
            TIMSK2 = 1 << OCIE2A;
        }
    }
}

void heater_pwm_emergency_off() {
    TIMSK2 = 0;
    TCCR2A = FAST_PWM;
    PORTB &= ~(1 << PB4);
    g_on = false;
}

}  // namespace hal

// Timer2 compare match A (vector 13 on the ATmega2560): the output was just cleared.
ISR(TIMER2_COMPA_vect) {
    using namespace hal;
    drv::HeaterDither d = {g_dither.base, g_dither.frac, g_dither.acc};
    const uint16_t n = d.next();
    g_dither.acc = d.acc;
    if (n == 0) {
        TCCR2A = FAST_PWM;  // disconnected: the pin reads PORTB4 = 0
    } else {
        OCR2A = static_cast<uint8_t>(n - 1);
        TCCR2A = FAST_PWM | (1 << COM2A1);
    }
}
