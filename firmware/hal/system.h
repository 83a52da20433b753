// Reset cause, the record that survives resets, and the watchdog (AVR only).
//
// Contract. Before main() (in .init3) the MCUSR reset flags and the level of the
// A4988's /ENABLE pin (still an input: its external pull decides) are captured, MCUSR
// is cleared and the watchdog turned off (after a watchdog reset it stays armed at its
// shortest period). reset_record() is the drivers/reset_cause.h ResetRecord in .noinit,
// placed after .bss: clear of the stk500v2 bootloader's few globals at the bottom of
// SRAM and its stack (a 285-byte message buffer) at the top. reset_record_write() seals
// a new record (armed: the host armed the next reset) and copies it in with interrupts
// masked, so the watchdog ISR never sees half of one.
// watchdog_enable() arms the WDT in interrupt-then-reset mode (~120 ms): its interrupt
// (ISR in system.cpp) turns the heater and the sense current off and stops STEP at
// once, records cause watchdog, disables the WDT and restarts the application at its
// reset vector, so a hung main loop never leads to a hardware watchdog reset (with the
// 2011 stk500v2 bootloader, which never disables the watchdog, that is an endless
// reset loop). Only if the ISR cannot complete does the second time-out reset the chip.
// quiesce() turns every interrupt source the firmware uses off (after such a restart
// the peripherals are not in their reset state).
#pragma once
#include <stdint.h>

#include "../drivers/reset_cause.h"

namespace hal {

uint8_t reset_flags();
// /ENABLE read low at start-up: the driver stayed energized through the reset.
bool motor_enable_held_at_reset();
drv::ResetRecord& reset_record();
void reset_record_write(uint8_t cause, int32_t position_steps, bool position_valid, bool armed);
void quiesce();
void watchdog_enable();
void watchdog_kick();

}  // namespace hal
