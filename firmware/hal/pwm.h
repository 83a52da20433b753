// Heater PWM: Timer2 fast PWM on OC2A (8-bit, 976.6 Hz), dithered to 4096 duty steps.
//
// Contract. heater_pwm_set_steps(steps) sets the duty to steps/4096 (0..4096): 0
// disconnects the compare output and drives the pin low at once (no ISR runs); any
// other value starts the TIMER2_COMPA ISR, which at every compare match (the output is
// low then) chooses the next period's on-count with drivers/heater_dither.h and
// connects (OCR2A = n - 1, double-buffered to the next period) or disconnects (n = 0)
// the output, so no period ever has a glitch. heater_pwm_emergency_off() is for the
// watchdog ISR (interrupts masked).
#pragma once
#include <stdint.h>

namespace hal {

void heater_pwm_init();
void heater_pwm_set_steps(uint16_t steps);
void heater_pwm_emergency_off();

}  // namespace hal
