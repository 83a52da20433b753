// Heater: equivalent DC voltage -> PWM duty on the MOSFET (Timer2, OC2A).
//
// Contract. The strings are resistive, so the power of a PWM at duty d from supply
// V_s equals that of a DC voltage V when d = (V / V_s)^2. set_mV() clamps V to
// cfg::MAX_HEATER_MV (and to the supply), writes duty = round(255 * (V / V_s)^2) with
// V_s = cfg::HEATER_SUPPLY_MV, and returns the equivalent voltage actually applied
// (the clamped request). Interlock: any nonzero duty first turns the sense current off
// (current_source.h), so the 50 mA source never sees the heater supply.
#pragma once
#include <stdint.h>

namespace drv {
namespace heater {

void init();
uint8_t duty_for_mV(uint16_t mV);
uint16_t set_mV(uint16_t mV);
bool is_on();
uint16_t applied_mV();

}  // namespace heater
}  // namespace drv
