// Heater PWM: Timer2 fast PWM on OC2A (8-bit, ~976 Hz).
//
// Contract. duty 0 disconnects the compare output and drives the pin low (fast PWM
// would otherwise leave a one-tick spike every period); 255 is fully on.
#pragma once
#include <stdint.h>

namespace hal {

void heater_pwm_init();
void heater_pwm_set(uint8_t duty);

}  // namespace hal
