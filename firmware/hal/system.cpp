#include "system.h"

#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/wdt.h>
#include <string.h>
#include <util/atomic.h>

#include "pins.h"
#include "pwm.h"
#include "step_timer.h"

namespace {
// .noinit: .bss is zeroed in .init4, after these are written in .init3.
uint8_t g_reset_flags __attribute__((section(".noinit")));
uint8_t g_enable_level __attribute__((section(".noinit")));
drv::ResetRecord g_record __attribute__((section(".noinit")));
}  // namespace

// Runs before the C runtime initialises .data/.bss and before main(); naked and in
// .init3, so it falls through to the next init section (no prologue, no ret).
extern "C" void tsa_capture_reset_flags() __attribute__((naked, used, section(".init3")));
extern "C" void tsa_capture_reset_flags() {
    g_reset_flags = MCUSR;
    MCUSR = 0;
    wdt_disable();
    g_enable_level = PINS_EN_PIN & (1 << PINS_EN_BIT);  // A4988 /ENABLE, before anything drives it
}

namespace hal {

uint8_t reset_flags() { return g_reset_flags; }

bool motor_enable_held_at_reset() { return g_enable_level == 0; }

drv::ResetRecord& reset_record() { return g_record; }

void reset_record_write(uint8_t cause, int32_t position_steps, bool position_valid, bool armed) {
    // Sealed outside the lock (the CRC is most of the work); only the copy is masked, so
    // the watchdog ISR never sees half a record and the other ISRs wait ~40 cycles.
    drv::ResetRecord r;
    r.cause = cause;
    r.position_valid = position_valid ? 1 : 0;
    r.position_steps = position_steps;
    r.armed = armed ? 1 : 0;
    r.reserved = 0;
    r.config_hash = drv::CONFIG_HASH;
    drv::reset_record_seal(r);
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { memcpy(&g_record, &r, sizeof r); }
}

void quiesce() {
    wdt_disable();
    TIMSK0 = TIMSK1 = TIMSK2 = TIMSK3 = TIMSK4 = TIMSK5 = 0;
    UCSR0B = 0;
    TWCR = 0;
    EIMSK = 0;
    PCICR = 0;
}

void watchdog_enable() {
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
        wdt_reset();
        WDTCSR = (1 << WDCE) | (1 << WDE);
        WDTCSR = (1 << WDIE) | (1 << WDE) | (1 << WDP1) | (1 << WDP0);  // 128 ms at 5 V
    }
}

void watchdog_kick() { wdt_reset(); }

}  // namespace hal

// Watchdog time-out (vector 12): the main loop hung. Make the rig safe first, then
// restart the application without a hardware reset (see system.h).
ISR(WDT_vect) {
    hal::heater_pwm_emergency_off();
    PINS_ISRC_PORT &= ~(1 << PINS_ISRC_BIT);  // 50 mA sense current off
    const bool stepping = hal::step_running();
    hal::step_emergency_stop();
    g_record.cause = drv::CAUSE_WATCHDOG;
    if (stepping) g_record.position_valid = 0;
    drv::reset_record_seal(g_record);
    hal::quiesce();
    __asm__ __volatile__("jmp 0" ::: "memory");
}
