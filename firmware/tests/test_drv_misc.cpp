// Step interval chaining (the step ISR's 16-bit split) and the reset-cause decoding.
#include "../core/protocol_catalogue.h"
#include "../drivers/reset_cause.h"
#include "../drivers/step_chunk.h"
#include "test_runner.h"

namespace {
// Total ticks and number of compare matches a chained interval produces.
void split(uint32_t interval, uint32_t& total, int& matches, uint32_t& shortest) {
    uint32_t left = interval;
    total = 0;
    matches = 0;
    shortest = 0xFFFFFFFFUL;
    while (true) {
        const uint32_t period = static_cast<uint32_t>(drv::step_take_chunk(left)) + 1;
        total += period;
        ++matches;
        if (period < shortest) shortest = period;
        if (!left) break;
    }
}
}  // namespace

TEST(drv_step_chunk_short_interval_is_one_match) {
    uint32_t left = 125;  // 16000 steps/s
    CHECK_EQ(drv::step_take_chunk(left), 124);
    CHECK_EQ(left, 0);
    left = 0x10000;
    CHECK_EQ(drv::step_take_chunk(left), 0xFFFF);
    CHECK_EQ(left, 0);
}

TEST(drv_step_chunk_long_intervals_chain_exactly) {
    const uint32_t cases[] = {0x10001UL, 70000UL, 131072UL, 2000000UL, 4000000000UL};
    for (unsigned i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        uint32_t total, shortest;
        int matches;
        split(cases[i], total, matches, shortest);
        CHECK_EQ(total, cases[i]);
        CHECK(shortest >= drv::STEP_CHAIN_TICKS);
        CHECK(matches >= 2);
    }
}

TEST(drv_reset_cause_from_mcusr_and_record) {
    using namespace proto::boot_reason;
    drv::ResetRecord r = {0, drv::CAUSE_RUNNING, 1, -12345, 0};
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
    drv::ResetRecord r = {0, drv::CAUSE_RUNNING, 1, 320000, 0};
    drv::reset_record_seal(r);
    CHECK(drv::reset_record_intact(r));
    uint8_t* bytes = reinterpret_cast<uint8_t*>(&r);
    for (unsigned i = 0; i < sizeof r; ++i) {
        for (int bit = 0; bit < 8; ++bit) {
            bytes[i] ^= static_cast<uint8_t>(1 << bit);
            const bool intact = drv::reset_record_intact(r);
            bytes[i] ^= static_cast<uint8_t>(1 << bit);
            if (i >= 10) continue;  // padding after the CRC (if any) is not covered
            CHECK(!intact);
        }
    }
    drv::ResetRecord zero = {0, 0, 0, 0, 0};
    CHECK(!drv::reset_record_intact(zero));  // all-zero RAM is not a record
}

TEST(drv_position_survives_only_a_held_reset_at_rest) {
    using namespace proto::boot_reason;
    drv::ResetRecord r = {0, drv::CAUSE_RUNNING, 1, 6400, 0};
    drv::reset_record_seal(r);
    CHECK(drv::position_survives(EXTERNAL_RESET, r, true, true));
    CHECK(drv::position_survives(WATCHDOG_RESET, r, true, true));
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, true, false));  // /ENABLE pulled up: motor released
    CHECK(!drv::position_survives(POWER_ON, r, true, true));
    CHECK(!drv::position_survives(BROWN_OUT, r, true, true));
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, false, true));
    r.position_valid = 0;  // reset mid-move
    drv::reset_record_seal(r);
    CHECK(!drv::position_survives(EXTERNAL_RESET, r, true, true));
}
