// Heater: equivalent DC voltage -> PWM duty on the MOSFET (Timer2, OC2A).
//
// Contract. The strings are resistive, so the power of a PWM at duty d from supply
// V_s equals that of a DC voltage V when d = (V / V_s)^2. set_mV() clamps V to
// cfg::MAX_HEATER_MV (and to the supply) and sets the duty to n/4096 with
// n = round(4096 V^2 / V_s^2) (hal/pwm.h dithers Timer2's (OCR2A + 1)/256 periods to
// that resolution); it returns the equivalent voltage actually applied,
// V_s sqrt(n / 4096) rounded to the mV, which is what SAMPLE reports. Rounding rule:
// the applied voltage is the nearest of the 4097 duty steps in power (V^2); the
// smallest non-zero one is V_s / 64 (375 mV at 24 V), and a request below
// V_s / sqrt(8192) (265 mV at 24 V) rounds to off (applied 0). Above 2 V the applied
// voltage is within 1 % of the request at a 24 V supply. Interlock: any nonzero duty
// first turns the sense current off (current_source.h), so the 50 mA source never sees
// the heater supply.
#pragma once
#include <stdint.h>

#include "heater_scale.h"

namespace drv {
namespace heater {

void init();
uint16_t set_mV(uint16_t mV);
bool is_on();
uint16_t applied_mV();

}  // namespace heater
}  // namespace drv
