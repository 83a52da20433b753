#include "system.h"

#include <avr/io.h>
#include <avr/wdt.h>

namespace {
// .noinit: .bss is zeroed in .init4, after this is written in .init3.
uint8_t g_reset_flags __attribute__((section(".noinit")));
}  // namespace

// Runs before the C runtime initialises .data/.bss and before main(); naked and in
// .init3, so it falls through to the next init section (no prologue, no ret).
extern "C" void tsa_capture_reset_flags() __attribute__((naked, used, section(".init3")));
extern "C" void tsa_capture_reset_flags() {
    g_reset_flags = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

namespace hal {

uint8_t reset_flags() { return g_reset_flags; }

void watchdog_enable() { wdt_enable(WDTO_500MS); }

void watchdog_kick() { wdt_reset(); }

}  // namespace hal
