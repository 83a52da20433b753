// Step interval chaining (the step ISR's 16-bit split) and the reset-cause decoding.
#include "../core/protocol_catalogue.h"
#include "../drivers/reset_cause.h"
#include "../drivers/step_chunk.h"
#include "test_runner.h"

TEST(drv_step_short_interval_needs_no_wait) {
    uint32_t ticks = 125;  // 16000 steps/s
    CHECK_EQ(drv::step_wait_chunks(ticks), 0);
    CHECK_EQ(ticks, 125u);
    ticks = drv::STEP_SINGLE_MAX_TICKS;
    CHECK_EQ(drv::step_wait_chunks(ticks), 0);
    CHECK_EQ(ticks, drv::STEP_SINGLE_MAX_TICKS);
}

TEST(drv_step_long_intervals_split_into_waits_exactly) {
    // just over the limit, 1 step/s, the slowest first ramp step (a = 1 step/s^2: c0 = 2.83 s)
    const uint32_t cases[] = {drv::STEP_SINGLE_MAX_TICKS + 1, 70000UL, 131072UL, 2000000UL, 5656855UL};
    for (unsigned i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        uint32_t ticks = cases[i];
        const uint8_t waits = drv::step_wait_chunks(ticks);
        CHECK(waits >= 1);
        CHECK_EQ(waits * drv::STEP_CHAIN_TICKS + ticks, cases[i]);  // nothing lost, nothing added
        CHECK(ticks <= drv::STEP_SINGLE_MAX_TICKS);                   // the step fits one period
        CHECK(ticks > drv::STEP_SINGLE_MAX_TICKS - drv::STEP_CHAIN_TICKS);  // never a short last period
    }
}

TEST(drv_reset_cause_from_mcusr_and_record) {
    using namespace proto::boot_reason;
    drv::ResetRecord r = {0, drv::CAUSE_RUNNING, 1, -12345, 1, 0, drv::CONFIG_HASH, 0};
    drv::reset_record_seal(r);
    CHECK(drv::reset_record_intact(r));
    const uint8_t running = drv::CAUSE_RUNNING, wdt = drv::CAUSE_WATCHDOG;
    CHECK_EQ(drv::boot_reason_from(drv::MCUSR_PORF, true, running), POWER_ON);
    CHECK_EQ(drv::boot_reason_from(drv::MCUSR_BORF, true, running), BROWN_OUT);
    CHECK_EQ(drv::boot_reason_from(drv::MCUSR_WDRF, true, running), WATCHDOG_RESET);
    CHECK_EQ(drv::boot_reason_from(drv::MCUSR_PORF | drv::MCUSR_BORF, true, running), POWER_ON);
    // A stock Mega's bootloader clears MCUSR: the record tells the story.
    CHECK_EQ(drv::boot_reason_from(0, true, running), EXTERNAL_RESET);
    CHECK_EQ(drv::boot_reason_from(0, true, wdt), WATCHDOG_RESET);
    CHECK_EQ(drv::boot_reason_from(0, false, running), POWER_ON);
    CHECK_EQ(drv::boot_reason_from(drv::MCUSR_EXTRF, false, 0), POWER_ON);
}

TEST(drv_reset_record_detects_any_damage) {
    drv::ResetRecord r = {0, drv::CAUSE_RUNNING, 1, 320000, 1, 0, drv::CONFIG_HASH, 0};
    drv::reset_record_seal(r);
    CHECK(drv::reset_record_intact(r));
    uint8_t* bytes = reinterpret_cast<uint8_t*>(&r);
    for (unsigned i = 0; i < sizeof r; ++i) {
        for (int bit = 0; bit < 8; ++bit) {
            bytes[i] ^= static_cast<uint8_t>(1 << bit);
            const bool intact = drv::reset_record_intact(r);
            bytes[i] ^= static_cast<uint8_t>(1 << bit);
            if (i >= drv::RESET_RECORD_CRC_BYTES + 2) continue;  // padding after the CRC (if any) is not covered
            CHECK(!intact);
        }
    }
    drv::ResetRecord zero = {0, 0, 0, 0, 0, 0, 0, 0};
    CHECK(!drv::reset_record_intact(zero));  // all-zero RAM is not a record
}

TEST(drv_position_survives_only_a_held_armed_reset_at_rest_of_the_same_firmware) {
    using namespace proto::boot_reason;
    drv::ResetRecord r = {0, drv::CAUSE_RUNNING, 1, 6400, 1, 0, drv::CONFIG_HASH, 0};
    drv::reset_record_seal(r);
    CHECK(drv::position_survives(EXTERNAL_RESET, r, true, true));
    CHECK(drv::position_survives(WATCHDOG_RESET, r, true, true));
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, true, false));  // /ENABLE pulled up: motor released
    CHECK(!drv::position_survives(POWER_ON, r, true, true));
    CHECK(!drv::position_survives(BROWN_OUT, r, true, true));
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, false, true));
    r.armed = 0;  // the host did not arrange this reset (a brown-out the bootloader hid)
    drv::reset_record_seal(r);
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, true, true));
    CHECK(!drv::position_survives(WATCHDOG_RESET, r, true, true));
    r.armed = 1;
    r.config_hash = drv::CONFIG_HASH ^ 1;  // written by a firmware of another geometry
    drv::reset_record_seal(r);
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, true, true));
    r.config_hash = drv::CONFIG_HASH;
    r.position_valid = 0;  // reset mid-move
    drv::reset_record_seal(r);
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, true, true));
}

TEST(drv_config_hash_covers_the_geometry) {
    // the same mixing with one input changed gives another hash
    CHECK(drv::config_mix(drv::config_mix(1, cfg::STEPS_PER_TURN), cfg::MICROSTEPS) !=
          drv::config_mix(drv::config_mix(1, cfg::STEPS_PER_TURN * 2), cfg::MICROSTEPS));
    CHECK(drv::config_mix(drv::config_mix(1, cfg::STEPS_PER_TURN), cfg::MICROSTEPS) !=
          drv::config_mix(drv::config_mix(1, cfg::STEPS_PER_TURN), cfg::MICROSTEPS / 2));
}
