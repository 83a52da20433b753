// Device dispatch, exchange style: bytes in, decoded replies out, checked against the
// behaviour of host/tsa_bench/sim/device.py.
#include "config.h"
#include "test_core_harness.h"
#include "test_runner.h"
#include "../drivers/heater_scale.h"

using core_test::Harness;
namespace st = proto::status;
namespace ev = proto::event_kind;

TEST(core_device_boot_sends_boot_with_reason) {
    Harness h;
    h.board.reason = proto::boot_reason::WATCHDOG_RESET;
    h.boot();
    CHECK_EQ(h.n, 1);
    CHECK_EQ(h.replies[0].id, proto::Boot::ID);
    CHECK_EQ(h.replies[0].seq, 0);
    CHECK_EQ(h.replies[0].f[0], cfg::FW_MAJOR);
    CHECK_EQ(h.replies[0].f[3], proto::boot_reason::WATCHDOG_RESET);
    CHECK(h.board.motor_enabled);
    CHECK(h.board.kicks > 0);
}

TEST(core_device_hello_identity_and_bad_hello) {
    Harness h;
    h.boot();
    h.clear();
    h.hello();
    CHECK_EQ(h.n, 1);
    CHECK_EQ(h.replies[0].id, proto::Identity::ID);
    const int64_t* f = h.replies[0].f;
    CHECK_EQ(f[0], proto::PROTOCOL_VERSION);
    CHECK_EQ(f[4], proto::CATALOGUE_HASH);
    CHECK_EQ(f[5], cfg::STEPS_PER_TURN);
    CHECK_EQ(f[6], cfg::MIN_TWIST_STEPS);
    CHECK_EQ(f[7], cfg::MAX_TWIST_STEPS);
    CHECK_EQ(f[8], cfg::MAX_RATE_STEPS_PER_S);
    CHECK_EQ(f[9], cfg::MAX_ACCEL_STEPS_PER_S2);
    CHECK_EQ(f[10], cfg::MAX_HEATER_MV);
    CHECK_EQ(f[11], cfg::QUEUE_SLOTS);
    CHECK_EQ(f[12], cfg::WATCHDOG_MS);
    CHECK_EQ(f[13], 0);  // not simulated
    h.clear();
    uint16_t s1 = h.hello(2);
    uint16_t s2 = h.hello(1, proto::CATALOGUE_HASH ^ 1);
    CHECK_EQ(h.n, 2);
    CHECK_EQ(h.ack_status(s1, proto::Hello::ID), st::BAD_ARGUMENT);
    CHECK_EQ(h.ack_status(s2, proto::Hello::ID), st::BAD_ARGUMENT);
    CHECK_EQ(h.replies[1].f[3], cfg::QUEUE_SLOTS);
}

TEST(core_device_unknown_and_bad_length) {
    Harness h;
    h.boot();
    h.clear();
    uint8_t p[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    uint16_t a = h.send(0x42, p, 0);
    uint16_t b = h.send(proto::Ack::ID, p, proto::Ack::SIZE);  // device-direction id
    uint16_t c = h.send(proto::SimSetLoad::ID, p, 4);         // real device: unknown
    uint16_t d = h.send(proto::Heartbeat::ID, p, 1);
    uint16_t e = h.send(proto::Dwell::ID, p, 4);
    CHECK_EQ(h.ack_status(a, 0x42), st::UNKNOWN_MESSAGE);
    CHECK_EQ(h.ack_status(b, proto::Ack::ID), st::UNKNOWN_MESSAGE);
    CHECK_EQ(h.ack_status(c, proto::SimSetLoad::ID), st::UNKNOWN_MESSAGE);
    CHECK_EQ(h.ack_status(d, proto::Heartbeat::ID), st::BAD_LENGTH);
    CHECK_EQ(h.ack_status(e, proto::Dwell::ID), st::BAD_LENGTH);
    CHECK_EQ(h.n, 5);
}

namespace {
uint32_t g_load;
void on_load(void* ctx, uint32_t mg) {
    *static_cast<uint32_t*>(ctx) = mg;
}
}  // namespace

TEST(core_device_sim_set_load_when_simulated) {
    Harness h;
    h.dev.set_sim_load_handler(on_load, &g_load);
    h.boot();
    h.hello();
    CHECK_EQ(h.replies[h.n - 1].f[13], proto::device_flags::SIMULATED);
    proto::SimSetLoad m;
    m.load_mg = 550000;
    uint16_t s = h.send_msg(m);
    CHECK_EQ(h.ack_status(s, proto::SimSetLoad::ID), st::OK);
    CHECK_EQ(g_load, 550000);
}

TEST(core_device_heartbeat_and_duplicates) {
    Harness h;
    h.boot();
    h.run_us(1000);
    h.clear();
    uint16_t s = h.heartbeat();
    CHECK_EQ(h.n, 2);
    CHECK_EQ(h.replies[0].id, proto::Ack::ID);
    CHECK_EQ(h.replies[0].f[0], s);
    CHECK_EQ(h.replies[1].id, proto::QueueStatus::ID);
    CHECK_EQ(h.replies[1].f[0], h.board.now);
    CHECK_EQ(h.replies[1].f[1], cfg::QUEUE_SLOTS);
    CHECK_EQ(h.replies[1].f[3], fw::NO_SEGMENT);
    // A retransmitted DWELL is answered from the filter and not queued twice.
    h.clear();
    uint8_t p[proto::Dwell::SIZE];
    proto::Dwell d;
    d.segment = 3;
    d.duration_us = 1000000;
    proto::pack(d, p);
    h.send_seq(500, proto::Dwell::ID, p, sizeof p);
    h.send_seq(500, proto::Dwell::ID, p, sizeof p);
    CHECK_EQ(h.count(proto::Ack::ID), 2);
    CHECK_EQ(h.count(proto::Event::ID, ev::SEGMENT_STARTED), 1);
    CHECK_EQ(h.dev.duplicates(), 1);
    // Same seq, different id: a new command. HEARTBEAT repeat: stored ACK + fresh status.
    h.clear();
    h.send_seq(501, proto::Heartbeat::ID, 0, 0);
    h.run_us(500);
    h.send_seq(501, proto::Heartbeat::ID, 0, 0);
    CHECK_EQ(h.count(proto::Ack::ID), 2);
    CHECK_EQ(h.count(proto::QueueStatus::ID), 2);
    CHECK(h.replies[3].f[0] > h.replies[1].f[0]);
    // HELLO resets the filter: the same frame runs again.
    h.hello();
    h.clear();
    h.send_seq(500, proto::Dwell::ID, p, sizeof p);
    CHECK_EQ(h.dev.queue_free(), cfg::QUEUE_SLOTS - 1);
}

TEST(core_device_refused_command_is_reevaluated) {
    Harness h;
    h.boot();
    uint8_t p[proto::Dwell::SIZE];
    proto::Dwell d;
    d.segment = 1;
    d.duration_us = 5000000;
    proto::pack(d, p);
    for (uint16_t i = 0; i < cfg::QUEUE_SLOTS + 1; ++i) h.send_seq(static_cast<uint16_t>(10 + i), proto::Dwell::ID, p, 6);
    h.clear();
    h.send_seq(99, proto::Dwell::ID, p, 6);
    CHECK_EQ(h.last_ack_status(), st::QUEUE_FULL);
    CHECK_EQ(h.last_ack_free(), 0);
    h.keepalive = true;
    h.run_us(5000000);  // the first dwell ends, a slot frees
    h.clear();
    h.send_seq(99, proto::Dwell::ID, p, 6);
    CHECK_EQ(h.last_ack_status(), st::OK);
}

TEST(core_device_check_order) {
    Harness h;
    h.boot();
    // BAD_ARGUMENT before LIMIT_EXCEEDED
    uint16_t s = h.move_to(1, cfg::MAX_TWIST_STEPS + 1, 0, 1000);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::BAD_ARGUMENT);
    s = h.move_to(1, 100, 1000, 0);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::BAD_ARGUMENT);
    s = h.move_to(1, 100, cfg::MAX_RATE_STEPS_PER_S + 1, 1000);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::LIMIT_EXCEEDED);
    s = h.move_to(1, 100, 1000, cfg::MAX_ACCEL_STEPS_PER_S2 + 1);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::LIMIT_EXCEEDED);
    s = h.move_to(1, cfg::MIN_TWIST_STEPS - 1);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::LIMIT_EXCEEDED);
    s = h.move_to(1, cfg::MAX_TWIST_STEPS, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::OK);
    // MOVE_BY is checked against the position after everything queued
    s = h.move_by(2, 1);
    CHECK_EQ(h.ack_status(s, proto::MoveBy::ID), st::LIMIT_EXCEEDED);
    s = h.move_by(2, -1000);
    CHECK_EQ(h.ack_status(s, proto::MoveBy::ID), st::OK);
    CHECK_EQ(h.dev.projected_steps(), cfg::MAX_TWIST_STEPS - 1000);
    s = h.heater(3, cfg::MAX_HEATER_MV + 1);
    CHECK_EQ(h.ack_status(s, proto::SetHeater::ID), st::LIMIT_EXCEEDED);
    s = h.sampling(3, cfg::MIN_SAMPLE_PERIOD_US - 1);
    CHECK_EQ(h.ack_status(s, proto::SetSampling::ID), st::TOO_FAST_FOR_SENSOR);
    s = h.sampling(3, 0);
    CHECK_EQ(h.ack_status(s, proto::SetSampling::ID), st::OK);
    // fill the queue: QUEUE_FULL comes last
    while (h.dev.queue_free() > 0) h.dwell(4, 1000);
    s = h.move_to(5, cfg::MAX_TWIST_STEPS + 1);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::LIMIT_EXCEEDED);
    s = h.dwell(5, 1);
    CHECK_EQ(h.ack_status(s, proto::Dwell::ID), st::QUEUE_FULL);
    // a latched fault refuses queued commands first of all
    h.run_us(cfg::WATCHDOG_MS * 1000UL + 1000);
    CHECK_EQ(h.dev.fault(), proto::fault::WATCHDOG);
    s = h.move_to(6, 0, 0, 0);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::BAD_STATE);
    s = h.heartbeat();
    CHECK_EQ(h.ack_status(s, proto::Heartbeat::ID), st::OK);
}

TEST(core_device_instant_segments_and_events) {
    Harness h;
    h.boot();
    h.run_us(200);
    h.clear();
    uint16_t s = h.heater(7, 5000);
    // ACK first (queue_free counts no executing command), then STARTED, DONE, QUEUE_EMPTY
    CHECK_EQ(h.n, 4);
    CHECK_EQ(h.replies[0].id, proto::Ack::ID);
    CHECK_EQ(h.replies[0].f[0], s);
    CHECK_EQ(h.replies[0].f[3], cfg::QUEUE_SLOTS);
    CHECK_EQ(h.replies[1].f[1], ev::SEGMENT_STARTED);
    CHECK_EQ(h.replies[1].f[2], 7);
    CHECK_EQ(h.replies[2].f[1], ev::SEGMENT_DONE);
    CHECK_EQ(h.replies[3].f[1], ev::QUEUE_EMPTY);
    CHECK_EQ(h.replies[3].f[0], h.board.now);
    CHECK_EQ(h.board.heater_mV, drv::heater::applied_for_mV(5000));  // 5003: what the PWM applies
    CHECK(h.dev.active());
}

TEST(core_device_dwell_timing_and_chain) {
    Harness h;
    h.boot();
    h.clear();
    uint64_t t0 = h.board.now;
    h.dwell(1, 300000);
    h.dwell(2, 200000);
    h.heater(3, 1000);
    h.heater(4, 0);
    CHECK_EQ(h.last_ack_free(), cfg::QUEUE_SLOTS - 3);
    h.run_us(600000);
    // STARTED 1, DONE 1 @ +300 ms, STARTED 2, DONE 2 @ +500 ms, 3 and 4 instantly, QUEUE_EMPTY
    int expect_kinds[] = {ev::SEGMENT_STARTED, ev::SEGMENT_DONE, ev::SEGMENT_STARTED, ev::SEGMENT_DONE,
                          ev::SEGMENT_STARTED, ev::SEGMENT_DONE, ev::SEGMENT_STARTED, ev::SEGMENT_DONE,
                          ev::QUEUE_EMPTY};
    int k = 0;
    for (int i = 0; i < h.n; ++i) {
        if (h.replies[i].id != proto::Event::ID) continue;
        if (k < 9) CHECK_EQ(h.replies[i].f[1], expect_kinds[k]);
        if (k == 1) CHECK_EQ(h.replies[i].f[0], t0 + 300000);
        if (k == 3) CHECK_EQ(h.replies[i].f[0], t0 + 500000);
        if (k == 8) CHECK_EQ(h.replies[i].f[2], 4);
        ++k;
    }
    CHECK_EQ(k, 9);
    CHECK(!h.dev.active());
}

TEST(core_device_move_runs_to_target) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.clear();
    h.move_to(10, 6400, 3200, 32000);
    CHECK(h.dev.executing());
    int done = h.run_until_event(ev::SEGMENT_DONE, 5000000);
    CHECK(done >= 0);
    CHECK_EQ(h.board.position, 6400);
    if (done >= 0) CHECK_EQ(h.replies[done].f[4], 6400);
    // closed form: 0.1 s ramps + 1.9 s cruise = 2.1 s
    if (done >= 0) CHECK(h.replies[done].f[0] > 2090000 && h.replies[done].f[0] < 2110000);
    h.clear();
    h.heartbeat();
    h.move_by(11, -400);
    CHECK(h.run_until_event(ev::QUEUE_EMPTY, 5000000) >= 0);
    CHECK_EQ(h.board.position, 6000);
    CHECK_EQ(h.board.steps_executed, 6800);
    // moving to where it is: instantaneous
    h.clear();
    h.move_to(12, 6000);
    CHECK_EQ(h.count(proto::Event::ID, ev::SEGMENT_DONE), 1);
    CHECK(!h.dev.executing());
}

TEST(core_device_clear_queue_and_fault_cleared) {
    Harness h;
    h.boot();
    h.dwell(1, 100000);
    h.dwell(2, 100000);
    h.dwell(3, 100000);
    h.clear();
    uint16_t s = h.clear_queue();
    CHECK_EQ(h.ack_status(s, proto::ClearQueue::ID), st::OK);
    CHECK_EQ(h.last_ack_free(), cfg::QUEUE_SLOTS);
    CHECK_EQ(h.count(proto::Event::ID), 0);  // no fault: no FAULT_CLEARED
    h.run_us(150000);                          // the executing dwell still finishes
    CHECK_EQ(h.count(proto::Event::ID, ev::SEGMENT_DONE), 1);
    CHECK_EQ(h.count(proto::Event::ID, ev::QUEUE_EMPTY), 1);
    // latch a watchdog fault, then clear it
    h.heater(4, 1000);
    h.run_us(cfg::WATCHDOG_MS * 1000UL + 100);
    h.clear();
    h.clear_queue();
    CHECK_EQ(h.n, 2);
    CHECK_EQ(h.replies[1].f[1], ev::FAULT_CLEARED);
    CHECK_EQ(h.replies[1].f[3], proto::fault::WATCHDOG);
    CHECK_EQ(h.dev.fault(), 0);
    s = h.dwell(5, 10);
    CHECK_EQ(h.ack_status(s, proto::Dwell::ID), st::OK);
}

TEST(core_device_frame_errors_counted_and_ignored) {
    Harness h;
    h.boot();
    h.clear();
    const uint8_t junk[] = {0x05, 0x01, 0x02, 0x00, 0x03, 0x11, 0x22, 0x00, 0x02, 0x01, 0x00};
    h.board.host_write(junk, sizeof junk);
    h.poll_once();
    CHECK_EQ(h.n, 0);
    CHECK_EQ(h.dev.frame_errors().total(), 3);
    h.heartbeat();
    CHECK_EQ(h.n, 2);
}

TEST(core_device_rx_backpressure_loses_nothing) {
    // 40 commands arrive at once with a TX ring that takes one frame at a time.
    Harness h;
    h.board.tx_ring_size = 40;
    h.board.tx_drain_bytes_per_ms = 25;
    h.boot();
    uint8_t buf[40 * 16];
    int len = 0;
    for (int i = 0; i < 40; ++i) {
        uint8_t p[4];
        proto::SetHeater m;
        m.segment = static_cast<uint16_t>(i);
        m.voltage_mV = static_cast<uint16_t>(i % 2 ? 0 : 1000);
        proto::pack(m, p);
        len += fw::frame_encode(proto::SetHeater::ID, static_cast<uint16_t>(1000 + i), p, 4, buf + len);
    }
    h.board.host_write(buf, static_cast<uint16_t>(len));
    h.run_us(200000);
    CHECK_EQ(h.count(proto::Ack::ID), 40);
    CHECK_EQ(h.count(proto::Event::ID, ev::SEGMENT_STARTED), 40);
    CHECK_EQ(h.count(proto::Event::ID, ev::SEGMENT_DONE), 40);
    CHECK_EQ(h.dev.urgent_lost(), 0);
    // device seq numbers run without a gap
    for (int i = 1; i < h.n; ++i) CHECK_EQ(h.replies[i].seq, static_cast<uint16_t>(h.replies[i - 1].seq + 1));
}
