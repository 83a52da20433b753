// AD8276 50 mA sense current source: one enable pin.
//
// Contract. set(true) is refused (returns false, source stays off) while the heater is
// on: the heater supply across the strings would otherwise drive the source and the
// CS5513 input. The settling time after enabling (cfg::RESISTANCE_SETTLE_US) is the
// caller's job: the core waits it before resistance_start(); on() / enabled_at_us()
// let it check. force_off() is the heater's side of the interlock.
#pragma once
#include <stdint.h>

namespace drv {
namespace current_source {

void init();
bool set(bool on);
void force_off();
bool on();
uint64_t enabled_at_us();

}  // namespace current_source
}  // namespace drv
