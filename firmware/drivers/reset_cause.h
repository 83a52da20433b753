// Why the MCU reset, and whether the step position survived it.
//
// Contract. The Mega's stk500v2 bootloader reads MCUSR and clears it before it jumps to
// the application, so the flags alone say nothing on a stock board. The firmware
// therefore keeps a ResetRecord in .noinit (hal/system.cpp): SRAM keeps it across any
// reset but a power-on, where it is random and fails its CRC. The watchdog ISR writes
// cause = CAUSE_WATCHDOG into it before restarting. Decoding, in order:
//   PORF -> power_on; BORF -> brown_out; record not intact -> power_on (the bootloader
//   cleared PORF); cause watchdog or WDRF -> watchdog_reset; else external_reset (DTR,
//   the reset button).
// The position survives when the record is intact and marked valid (the motor was at
// rest), armed (the host sent ARM_RESET: it meant to reset the board by opening the
// port), written by a firmware of this configuration (config_hash: the firmware's
// version, catalogue hash, steps per turn, microstepping and twist limits, so a reflash
// with another geometry never keeps a count in the wrong units), the reset was not a
// power-on or brown-out, and the A4988's /ENABLE read low at start-up: with a pull-down
// on /ENABLE the driver stayed energized through reset and bootloader, so a loaded TSA
// could not turn the motor (firmware/README.md). A brown-out that the bootloader hides
// (it clears BORF) finds the record unarmed: the A4988's translator restarted at Home
// under its own UVLO and the strings turned the motor while the supply dipped.
#pragma once
#include <stdint.h>

#include "../config.h"
#include "../core/crc16.h"
#include "../core/protocol_catalogue.h"

namespace drv {

// ATmega2560 MCUSR bit positions (datasheet 12.5.1).
static const uint8_t MCUSR_PORF = 1 << 0;
static const uint8_t MCUSR_EXTRF = 1 << 1;
static const uint8_t MCUSR_BORF = 1 << 2;
static const uint8_t MCUSR_WDRF = 1 << 3;

static const uint16_t RESET_RECORD_MAGIC = 0x5A7B;
static const uint8_t CAUSE_RUNNING = 1;   // the application ran; a reset now is external
static const uint8_t CAUSE_WATCHDOG = 2;  // the watchdog ISR restarted the application

// A hash of what the kept count means: FNV-1a style over 32-bit words (compile time).
constexpr uint32_t config_mix(uint32_t h, uint32_t v) { return (h ^ v) * 16777619UL; }
constexpr uint32_t CONFIG_HASH = config_mix(
    config_mix(config_mix(config_mix(config_mix(config_mix(2166136261UL, (static_cast<uint32_t>(cfg::FW_MAJOR) << 16) |
                                                                             (static_cast<uint32_t>(cfg::FW_MINOR) << 8) |
                                                                             cfg::FW_PATCH),
                                                  proto::CATALOGUE_HASH),
                                       cfg::STEPS_PER_TURN),
                            cfg::MICROSTEPS),
                 static_cast<uint32_t>(cfg::MIN_TWIST_STEPS)),
    static_cast<uint32_t>(cfg::MAX_TWIST_STEPS));

struct ResetRecord {
    uint16_t magic;
    uint8_t cause;
    uint8_t position_valid;
    int32_t position_steps;
    uint8_t armed;         // the host armed this reset (ARM_RESET)
    uint8_t reserved;
    uint32_t config_hash;  // CONFIG_HASH of the firmware that wrote it
    uint16_t crc;          // CRC-16/CCITT-FALSE of the 14 bytes above
} __attribute__((packed));  // the AVR's layout on every build (the native tests flip each byte)
static_assert(sizeof(ResetRecord) == 16, "no padding");
static const uint8_t RESET_RECORD_CRC_BYTES = 14;

inline uint16_t reset_record_crc(const ResetRecord& r) {
    const uint8_t bytes[RESET_RECORD_CRC_BYTES] = {
        static_cast<uint8_t>(r.magic), static_cast<uint8_t>(r.magic >> 8), r.cause, r.position_valid,
        static_cast<uint8_t>(r.position_steps), static_cast<uint8_t>(r.position_steps >> 8),
        static_cast<uint8_t>(r.position_steps >> 16), static_cast<uint8_t>(r.position_steps >> 24), r.armed,
        r.reserved, static_cast<uint8_t>(r.config_hash), static_cast<uint8_t>(r.config_hash >> 8),
        static_cast<uint8_t>(r.config_hash >> 16), static_cast<uint8_t>(r.config_hash >> 24)};
    return fw::crc16(bytes, sizeof bytes);
}

inline void reset_record_seal(ResetRecord& r) {
    r.magic = RESET_RECORD_MAGIC;
    r.crc = reset_record_crc(r);
}

inline bool reset_record_intact(const ResetRecord& r) {
    return r.magic == RESET_RECORD_MAGIC && r.crc == reset_record_crc(r) &&
           (r.cause == CAUSE_RUNNING || r.cause == CAUSE_WATCHDOG) && r.position_valid <= 1 && r.armed <= 1;
}

inline uint8_t boot_reason_from(uint8_t mcusr, bool record_intact, uint8_t cause) {
    if (mcusr & MCUSR_PORF) return proto::boot_reason::POWER_ON;
    if (mcusr & MCUSR_BORF) return proto::boot_reason::BROWN_OUT;
    if (!record_intact) return proto::boot_reason::POWER_ON;
    if (cause == CAUSE_WATCHDOG || (mcusr & MCUSR_WDRF)) return proto::boot_reason::WATCHDOG_RESET;
    return proto::boot_reason::EXTERNAL_RESET;
}

inline bool position_survives(uint8_t reason, const ResetRecord& r, bool record_intact, bool motor_held) {
    return record_intact && r.position_valid && r.armed && r.config_hash == CONFIG_HASH && motor_held &&
           reason != proto::boot_reason::POWER_ON && reason != proto::boot_reason::BROWN_OUT;
}

}  // namespace drv
