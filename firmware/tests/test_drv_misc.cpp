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

TEST(drv_reset_cause_from_mcusr) {
    using namespace proto::boot_reason;
    CHECK_EQ(drv::boot_reason_from_mcusr(drv::MCUSR_PORF), POWER_ON);
    CHECK_EQ(drv::boot_reason_from_mcusr(drv::MCUSR_EXTRF), EXTERNAL_RESET);
    CHECK_EQ(drv::boot_reason_from_mcusr(drv::MCUSR_BORF), BROWN_OUT);
    CHECK_EQ(drv::boot_reason_from_mcusr(drv::MCUSR_WDRF), WATCHDOG_RESET);
    CHECK_EQ(drv::boot_reason_from_mcusr(0), EXTERNAL_RESET);
    CHECK_EQ(drv::boot_reason_from_mcusr(drv::MCUSR_PORF | drv::MCUSR_BORF), POWER_ON);
    CHECK_EQ(drv::boot_reason_from_mcusr(drv::MCUSR_WDRF | drv::MCUSR_EXTRF), WATCHDOG_RESET);
}
