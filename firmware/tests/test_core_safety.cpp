// Safety: limits refused at acceptance never move the motor past them, the runtime
// twist guard, the host watchdog, STOP mid-move, the heater / sense-current interlock.
#include "config.h"
#include "test_core_harness.h"
#include "test_runner.h"

using core_test::Harness;
namespace st = proto::status;
namespace ev = proto::event_kind;

TEST(core_safety_limits_never_passed) {
    // Pseudo-random MOVE_TO / MOVE_BY at the bench limits: accepted ones run, refused
    // ones have no effect; the motor never leaves [MIN, MAX].
    Harness h;
    h.keepalive = true;
    h.step_us = 200;
    h.boot();
    uint32_t r = 2024;
    int accepted = 0, refused = 0;
    for (int i = 0; i < 60; ++i) {
        r = r * 1664525UL + 1013904223UL;
        int32_t span = cfg::MAX_TWIST_STEPS - cfg::MIN_TWIST_STEPS;
        int32_t target = cfg::MIN_TWIST_STEPS - span / 2 + static_cast<int32_t>((r >> 4) % (2 * span));
        h.clear();
        uint16_t s;
        uint8_t id;
        if (i % 2) {
            s = h.move_to(static_cast<uint16_t>(i), target, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
            id = proto::MoveTo::ID;
        } else {
            s = h.move_by(static_cast<uint16_t>(i), target / 4, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
            id = proto::MoveBy::ID;
        }
        int status = h.ack_status(s, id);
        (status == st::OK ? accepted : refused)++;
        h.run_until_event(ev::QUEUE_EMPTY, 30000000);
        CHECK(h.board.position >= cfg::MIN_TWIST_STEPS && h.board.position <= cfg::MAX_TWIST_STEPS);
    }
    CHECK(h.board.min_position >= cfg::MIN_TWIST_STEPS);
    CHECK(h.board.max_position <= cfg::MAX_TWIST_STEPS);
    CHECK(accepted > 10);
    CHECK(refused > 5);
    CHECK_EQ(h.dev.fault(), 0);
}

TEST(core_safety_runtime_twist_guard) {
    // A driver losing count (every step moves two) runs past MAX: halt + FAULT.
    Harness h;
    h.keepalive = true;
    h.boot();
    h.board.step_glitch = 1;
    h.move_to(1, cfg::MAX_TWIST_STEPS, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
    int i = h.run_until_event(ev::FAULT, 60000000);
    CHECK(i >= 0);
    if (i >= 0) CHECK_EQ(h.replies[i].f[3], proto::fault::TWIST_LIMIT);
    CHECK_EQ(h.dev.fault(), proto::fault::TWIST_LIMIT);
    CHECK(!h.board.step_busy());
    CHECK(h.board.position <= cfg::MAX_TWIST_STEPS + 4);  // caught within one poll
}

TEST(core_safety_watchdog_trip) {
    Harness h;
    h.boot();
    h.heater(1, 3000);
    h.move_to(2, 32000, 1000, 1000);
    h.dwell(3, 1000000);
    uint64_t t_last = h.board.now;
    h.clear();
    h.run_us(cfg::WATCHDOG_MS * 1000UL - 1000);
    CHECK_EQ(h.count(proto::Event::ID, ev::FAULT), 0);
    h.run_us(2000);
    int i = h.find(proto::Event::ID, ev::FAULT);
    CHECK(i >= 0);
    int32_t rest = 0;
    if (i >= 0) {
        CHECK_EQ(h.replies[i].f[3], proto::fault::WATCHDOG);
        CHECK(h.replies[i].f[0] >= static_cast<int64_t>(t_last + cfg::WATCHDOG_MS * 1000UL));
        CHECK(h.replies[i].f[0] < static_cast<int64_t>(t_last + cfg::WATCHDOG_MS * 1000UL + 200));
        rest = static_cast<int32_t>(h.replies[i].f[4]);  // where the motor comes to rest
        // at 1000 steps/s a stop at the limit takes 1.6 steps; at most the pending edge
        // and cfg::STOP_KEEP_STEPS more run first
        CHECK(rest >= h.board.position && rest <= h.board.position + 2 + cfg::STOP_KEEP_MAX_STEPS);
    }
    CHECK_EQ(h.board.heater_mV, 0);  // at once, not after the deceleration
    CHECK_EQ(h.dev.queue_free(), cfg::QUEUE_SLOTS);
    h.run_us(20000);
    CHECK(!h.board.step_busy());
    CHECK(!h.dev.stopping());
    CHECK(!h.dev.active());
    CHECK_EQ(h.board.position, rest);
    CHECK(h.dev.position_known());  // a controlled stop keeps the position
    h.run_us(100000);
    CHECK_EQ(h.board.position, rest);
    CHECK_EQ(h.count(proto::Event::ID, ev::FAULT), 1);
    // an idle device never trips
    Harness idle;
    idle.boot();
    idle.run_us(10 * cfg::WATCHDOG_MS * 1000UL);
    CHECK_EQ(idle.dev.fault(), 0);
}

TEST(core_safety_any_valid_frame_feeds_watchdog) {
    Harness h;
    h.boot();
    h.heater(1, 1000);
    for (int i = 0; i < 10; ++i) {
        h.run_us(cfg::WATCHDOG_MS * 500UL);
        h.send(0x77, 0, 0);  // unknown message, still a valid frame from the host
    }
    CHECK_EQ(h.dev.fault(), 0);
}

TEST(core_safety_stop_mid_move) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.heater(1, 2000);
    h.move_to(2, 100000, 8000, 16000);
    h.dwell(3, 1000000);
    h.run_us(1500000);
    CHECK(h.board.step_busy());
    h.clear();
    const int32_t at_stop = h.board.position;
    uint16_t s = h.stop();
    CHECK_EQ(h.replies[0].id, proto::Ack::ID);
    CHECK_EQ(h.ack_status(s, proto::Stop::ID), st::OK);
    CHECK_EQ(h.replies[0].f[3], cfg::QUEUE_SLOTS);
    CHECK_EQ(h.replies[1].f[1], ev::STOPPED);
    CHECK_EQ(h.replies[1].f[2], 2);
    const int32_t rest = static_cast<int32_t>(h.replies[1].f[4]);
    // 8000 steps/s decelerating at the limit (320000 steps/s^2) takes 100 steps, 25 ms:
    // far shorter than the move's own deceleration (2000 steps)
    CHECK(rest > at_stop + 90 && rest < at_stop + 110 + cfg::STOP_KEEP_MAX_STEPS);
    CHECK_EQ(h.board.heater_mV, 0);
    CHECK(!h.dev.executing());
    CHECK(h.dev.stopping());
    h.run_us(500000);
    CHECK(!h.dev.stopping());
    CHECK_EQ(h.board.position, rest);
    CHECK_EQ(h.count(proto::Event::ID, ev::SEGMENT_DONE), 0);  // the stopped segment gets none
    CHECK_EQ(h.dev.fault(), 0);
    CHECK(h.dev.position_known());
    // the deceleration never speeds up, and ends at a crawl
    // MOVE_BY after STOP is relative to where it stopped
    h.move_by(4, 10);
    h.run_until_event(ev::QUEUE_EMPTY, 1000000);
    CHECK_EQ(h.board.position, rest + 10);
}

TEST(core_safety_heater_and_sense_never_together) {
    Harness h;
    h.keepalive = true;
    h.board.resistance_latency_us = 3000;
    h.boot();
    h.sampling(1, cfg::SINGLE_SHOT_MIN_PERIOD_US);
    for (int i = 0; i < 40; ++i) {
        h.run_us(1700 + 137 * static_cast<uint32_t>(i % 7));
        h.heater(static_cast<uint16_t>(10 + i), static_cast<uint16_t>(i % 2 ? 0 : 4000));
        CHECK(!(h.board.heater_mV > 0 && h.board.sense_on));
    }
    h.run_us(80000);
    CHECK_EQ(h.board.interlock_violations, 0);
    CHECK_EQ(h.board.sense_refusals, 0);
    CHECK_EQ(h.board.unsettled_conversions, 0);
    CHECK(h.count(proto::Sample::ID) > 20);
}
