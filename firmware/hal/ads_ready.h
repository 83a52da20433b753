// ADS1115 ALERT/RDY pulses, counted by an edge interrupt (hal/pins.h: PE4, INT4).
//
// Contract. In continuous mode with the conversion-ready function on, the ADS1115 pulls
// ALERT/RDY low for ~8 us at the end of every conversion (data sheet SBAS444, 9.3.8);
// too short to be polled from the main loop. ads_ready_init() arms INT4 on the falling
// edge; its ISR only counts (saturating at 255). ads_ready_take() returns the count
// since the last call and clears it, atomically. AVR only.
#pragma once
#include <stdint.h>

namespace hal {

void ads_ready_init();
uint8_t ads_ready_take();

}  // namespace hal
