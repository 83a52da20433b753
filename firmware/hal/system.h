// Reset cause and watchdog (AVR only).
//
// Contract. The MCUSR reset flags are captured before main() (in .init3, which also
// turns the watchdog off: after a watchdog reset it stays armed at its shortest period)
// and MCUSR is cleared. reset_flags() returns the captured byte; decode it with
// drivers/reset_cause.h. watchdog_enable() arms the WDT (system reset, ~500 ms);
// watchdog_kick() feeds it.
#pragma once
#include <stdint.h>

namespace hal {

uint8_t reset_flags();
void watchdog_enable();
void watchdog_kick();

}  // namespace hal
