// Sampling: the grid, the SAMPLE fields, flags for heater-on / sensor failures, and
// drops when the TX ring is full (the counter still advances).
#include "config.h"
#include "test_core_harness.h"
#include "test_runner.h"

using core_test::Harness;
namespace af = proto::adc_flags;

TEST(core_sampling_grid_and_fields) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.run_us(1234);
    uint64_t anchor = h.board.now;
    h.sampling(5, 10000);
    h.clear();
    h.board.position_counts = 21345;
    h.board.resistance_counts = -262144;
    h.run_us(105000);
    int k = 0;
    for (int i = 0; i < h.n; ++i) {
        if (h.replies[i].id != proto::Sample::ID) continue;
        const int64_t* f = h.replies[i].f;
        CHECK_EQ(f[0], k);
        CHECK_EQ(f[1], anchor + 10000ULL * (k + 1));
        CHECK_EQ(f[2], 0);
        CHECK_EQ(f[3], 21345);
        CHECK_EQ(f[4], -262144);
        CHECK_EQ(f[5], 0);
        CHECK_EQ(f[6], 0);
        CHECK_EQ(f[7], 0);
        CHECK_EQ(f[8], 5);
        ++k;
    }
    CHECK_EQ(k, 10);
    CHECK_EQ(h.dev.samples_dropped(), 0);
}

TEST(core_sampling_no_segment_before_any) {
    Harness h;
    h.boot();
    h.sampling(0xFFFF, cfg::SINGLE_SHOT_MIN_PERIOD_US);
    h.run_us(cfg::SINGLE_SHOT_MIN_PERIOD_US + 2500);
    int i = h.find(proto::Sample::ID);
    CHECK(i >= 0);
    if (i >= 0) CHECK_EQ(h.replies[i].f[8], 0xFFFF);
}

TEST(core_sampling_flags) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.sampling(1, 5000);
    h.heater(2, 6000);
    h.clear();
    h.run_us(20000);
    int i = h.find(proto::Sample::ID);
    CHECK(i >= 0);
    if (i >= 0) {
        CHECK_EQ(h.replies[i].f[5], af::RESISTANCE_NOT_MEASURED);
        CHECK_EQ(h.replies[i].f[4], 0);
        CHECK_EQ(h.replies[i].f[6], 6000);
    }
    h.heater(3, 0);
    h.board.resistance_flags = af::RESISTANCE_OVERRANGE | af::RESISTANCE_OSCILLATION;
    h.board.position_poll_fails = true;
    h.clear();
    h.run_us(20000);
    i = h.find(proto::Sample::ID);
    CHECK(i >= 0);
    if (i >= 0) CHECK_EQ(h.replies[i].f[5], af::POSITION_INVALID | af::RESISTANCE_OVERRANGE | af::RESISTANCE_OSCILLATION);
    h.board.position_poll_fails = false;
    h.board.position_start_fails = true;
    h.board.resistance_poll_fails = true;
    h.clear();
    h.run_us(45000);
    i = h.find(proto::Sample::ID);
    // the first SAMPLE may have started before the failures: take the next one
    if (i >= 0 && h.find(proto::Sample::ID, -1, i + 1) >= 0) i = h.find(proto::Sample::ID, -1, i + 1);
    CHECK(i >= 0);
    if (i >= 0) CHECK_EQ(h.replies[i].f[5], af::POSITION_INVALID | af::RESISTANCE_NOT_MEASURED);
    CHECK_EQ(h.board.unsettled_conversions, 0);
}

TEST(core_sampling_moving_flag_and_position) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.sampling(1, 20000);
    h.move_to(2, 3200, 3200, 32000);
    h.clear();
    h.run_us(1200000);
    int moving = 0, last_pos = -1;
    bool monotonic = true;
    for (int i = 0; i < h.n; ++i) {
        if (h.replies[i].id != proto::Sample::ID) continue;
        if (h.replies[i].f[7]) ++moving;
        if (h.replies[i].f[2] < last_pos) monotonic = false;
        last_pos = static_cast<int>(h.replies[i].f[2]);
    }
    CHECK(moving >= 50);
    CHECK(monotonic);
    CHECK_EQ(last_pos, 3200);
}

TEST(core_sampling_drops_when_tx_full_and_counter_advances) {
    Harness h;
    h.keepalive = true;
    h.board.tx_ring_size = 64;
    h.board.tx_drain_bytes_per_ms = 10;  // too slow for a 36-byte SAMPLE every 3 ms
    h.boot();
    h.sampling(1, cfg::SINGLE_SHOT_MIN_PERIOD_US);
    h.clear();
    h.run_us(300000);
    CHECK(h.dev.samples_dropped() > 0);
    CHECK_EQ(h.dev.urgent_lost(), 0);
    int64_t last = -1;
    int gaps = 0, got = 0;
    for (int i = 0; i < h.n; ++i) {
        if (h.replies[i].id != proto::Sample::ID) continue;
        ++got;
        if (last >= 0 && h.replies[i].f[0] != last + 1) ++gaps;
        CHECK(h.replies[i].f[0] > last);
        last = h.replies[i].f[0];
    }
    CHECK(got > 10);
    CHECK(gaps > 0);
    CHECK_EQ(h.count(proto::Ack::ID), h.count(proto::QueueStatus::ID));  // heartbeats all answered
}

TEST(core_sampling_slow_conversion_skips_slots) {
    Harness h;
    h.keepalive = true;
    h.board.position_latency_us = 7500;  // slower than the 3 ms period
    h.boot();
    const uint64_t anchor = h.board.now;
    h.sampling(1, 3000);
    h.clear();
    h.run_us(150000);
    int got = h.count(proto::Sample::ID);
    CHECK(got > 10 && got < 30);
    int64_t last_t = 0, last_counter = -1;
    for (int i = 0; i < h.n; ++i) {
        if (h.replies[i].id != proto::Sample::ID) continue;
        // stamped when its conversion started: after its counter's grid slot (late when
        // the previous conversion still ran), never a whole period late
        const int64_t slot = static_cast<int64_t>(anchor) + 3000 * (h.replies[i].f[0] + 1);
        CHECK(h.replies[i].f[1] >= slot && h.replies[i].f[1] < slot + 3000);
        CHECK(h.replies[i].f[1] > last_t);
        CHECK(h.replies[i].f[0] > last_counter);
        last_t = h.replies[i].f[1];
        last_counter = h.replies[i].f[0];
    }
    h.sampling(2, 0);
    h.run_us(10000);
    h.clear();
    h.run_us(10000);
    CHECK_EQ(h.count(proto::Sample::ID), 0);
    CHECK(!h.board.sense_on);
}

TEST(core_sampling_stamp_is_the_actual_conversion_start) {
    // A main loop that comes round late (here every 700 us) starts conversions late:
    // the SAMPLE says when its conversion really started, not when it was due.
    Harness h;
    h.keepalive = true;
    h.step_us = 700;
    h.boot();
    const uint64_t anchor = h.board.now;
    h.sampling(1, 10000);
    h.clear();
    h.run_us(200000);
    int late = 0, got = 0;
    for (int i = 0; i < h.n; ++i) {
        if (h.replies[i].id != proto::Sample::ID) continue;
        ++got;
        const int64_t due = static_cast<int64_t>(anchor) + 10000 * (h.replies[i].f[0] + 1);
        const int64_t t = h.replies[i].f[1];
        CHECK(t >= due && t < due + 700);
        if (t != due) ++late;
    }
    CHECK(got >= 18);
    CHECK(late > got / 2);
}

TEST(core_sampling_slow_resistance_keeps_the_grid) {
    // A CS5513 word takes up to 19.1 ms (and ~80 ms after the current comes on): at a
    // 10 ms period the sample gives up the resistance before the next slot instead of
    // losing that slot, and the sense current stays on.
    Harness h;
    h.keepalive = true;
    h.board.resistance_latency_us = 15000;
    h.board.position_counts = 21345;
    h.boot();
    h.sampling(1, 10000);
    h.clear();
    h.run_us(200000);
    int got = 0;
    int64_t last = -1;
    for (int i = 0; i < h.n; ++i) {
        if (h.replies[i].id != proto::Sample::ID) continue;
        ++got;
        if (last >= 0) CHECK_EQ(h.replies[i].f[0], last + 1);  // no counter gap
        last = h.replies[i].f[0];
        CHECK_EQ(h.replies[i].f[5], af::RESISTANCE_NOT_MEASURED);
        CHECK_EQ(h.replies[i].f[3], 21345);  // the position is there
    }
    CHECK(got >= 19);
    CHECK(h.board.sense_on);
    CHECK_EQ(h.dev.samples_dropped(), 0);
}
