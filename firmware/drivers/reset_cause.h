// MCUSR reset flags -> proto::boot_reason.
//
// Contract. Flags accumulate until cleared, and hal/system.cpp clears them at every boot,
// so normally exactly one is set. Priority when several are: power-on (it implies the
// others are meaningless), brown-out, watchdog, external. No flag at all (the Mega's
// bootloader may clear MCUSR before jumping to us after a DTR reset) reads as external.
#pragma once
#include <stdint.h>

#include "../core/protocol_catalogue.h"

namespace drv {

// ATmega2560 MCUSR bit positions (datasheet 12.5.1).
static const uint8_t MCUSR_PORF = 1 << 0;
static const uint8_t MCUSR_EXTRF = 1 << 1;
static const uint8_t MCUSR_BORF = 1 << 2;
static const uint8_t MCUSR_WDRF = 1 << 3;

inline uint8_t boot_reason_from_mcusr(uint8_t flags) {
    if (flags & MCUSR_PORF) return proto::boot_reason::POWER_ON;
    if (flags & MCUSR_BORF) return proto::boot_reason::BROWN_OUT;
    if (flags & MCUSR_WDRF) return proto::boot_reason::WATCHDOG_RESET;
    return proto::boot_reason::EXTERNAL_RESET;
}

}  // namespace drv
