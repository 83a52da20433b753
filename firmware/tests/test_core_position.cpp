// Position that survives resets, SET_POSITION, the controlled stop, the fault release,
// STOP while the outbox is full, and the counters the board reports (step underruns,
// I2C recoveries, UART errors) as EVENTs and QUEUE_STATUS fields.
#include "config.h"
#include "test_core_harness.h"
#include "test_runner.h"

using core_test::Harness;
namespace st = proto::status;
namespace ev = proto::event_kind;
namespace ds = proto::device_state;

namespace {
// Fields of the last QUEUE_STATUS (-1 when there is none).
int64_t last_status_field(const Harness& h, int field) {
    for (int i = h.n - 1; i >= 0; --i)
        if (h.replies[i].id == proto::QueueStatus::ID) return h.replies[i].f[field];
    return -1;
}
const int QS_STATE = 5, QS_POSITION = 6, QS_UNDERRUNS = 7, QS_UART_OVERRUNS = 8, QS_FRAME_ERRORS = 9,
          QS_I2C = 10;
}  // namespace

TEST(core_position_unknown_after_power_on_refuses_moves) {
    Harness h;
    h.board.kept_valid = false;  // power-on: nothing survived
    h.board.position = 777;      // whatever the step counter held
    h.boot();
    CHECK(!h.dev.position_known());
    CHECK_EQ(h.board.position, 0);  // never a silent zero to the host: the state says unknown
    CHECK(!h.board.record_valid);
    h.heartbeat();
    CHECK_EQ(last_status_field(h, QS_STATE) & ds::POSITION_UNKNOWN, ds::POSITION_UNKNOWN);
    uint16_t s = h.move_to(1, 100);
    CHECK_EQ(h.ack_status(s, proto::MoveTo::ID), st::BAD_STATE);
    s = h.move_by(1, 100);
    CHECK_EQ(h.ack_status(s, proto::MoveBy::ID), st::BAD_STATE);
    s = h.dwell(1, 1000);  // everything else still works
    CHECK_EQ(h.ack_status(s, proto::Dwell::ID), st::OK);
    h.run_us(2000);
    s = h.set_position(cfg::MAX_TWIST_STEPS + 1);
    CHECK_EQ(h.ack_status(s, proto::SetPosition::ID), st::LIMIT_EXCEEDED);
    s = h.set_position(-3200);
    CHECK_EQ(h.ack_status(s, proto::SetPosition::ID), st::OK);
    CHECK(h.dev.position_known());
    CHECK_EQ(h.board.position, -3200);
    CHECK(h.board.record_valid);
    CHECK_EQ(h.board.record_steps, -3200);
    h.clear();
    h.heartbeat();
    CHECK_EQ(last_status_field(h, QS_STATE), 0);
    CHECK_EQ(last_status_field(h, QS_POSITION), -3200);
    s = h.move_by(2, 100);
    CHECK_EQ(h.ack_status(s, proto::MoveBy::ID), st::OK);
    h.run_until_event(ev::QUEUE_EMPTY, 1000000);
    CHECK_EQ(h.board.position, -3100);
}

TEST(core_position_kept_through_a_reset) {
    Harness h;
    h.board.kept_valid = true;
    h.board.kept_steps = 64000;
    h.boot();
    CHECK(h.dev.position_known());
    CHECK_EQ(h.board.position, 64000);
    CHECK_EQ(h.dev.projected_steps(), 64000);
    CHECK(h.board.record_valid && h.board.record_steps == 64000);
    CHECK(h.board.motor_enabled);
}

TEST(core_position_record_is_invalid_while_moving) {
    Harness h;
    h.boot();
    h.move_to(1, 6400, 16000, 320000);
    h.run_us(100000);
    CHECK(h.board.step_busy());
    CHECK(!h.board.record_valid);  // a reset now would leave the position unknown
    h.run_until_event(ev::QUEUE_EMPTY, 2000000);
    CHECK(h.board.record_valid);
    CHECK_EQ(h.board.record_steps, 6400);
}

TEST(core_set_position_refused_while_a_move_runs_or_waits) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.move_to(1, 6400, 3200, 32000);
    h.run_us(10000);
    uint16_t s = h.set_position(0);
    CHECK_EQ(h.ack_status(s, proto::SetPosition::ID), st::BAD_STATE);
    h.run_until_event(ev::QUEUE_EMPTY, 5000000);
    h.dwell(2, 100000);
    h.move_to(3, 0);
    s = h.set_position(0);
    CHECK_EQ(h.ack_status(s, proto::SetPosition::ID), st::BAD_STATE);  // a move waits
    h.clear_queue();
    h.run_us(200000);
    s = h.set_position(100);
    CHECK_EQ(h.ack_status(s, proto::SetPosition::ID), st::OK);
    CHECK_EQ(h.board.position, 100);
}

TEST(core_stop_fast_decelerates_at_the_limit_slow_stops_at_once) {
    Harness h;
    h.keepalive = true;
    h.board.step_ring_size = 64;
    h.boot();
    h.move_to(1, 200000, cfg::MAX_RATE_STEPS_PER_S, 32000);
    h.run_us(1500000);  // cruising at 16000 steps/s
    const int32_t at = h.board.position;
    h.clear();
    h.stop();
    const int32_t rest = static_cast<int32_t>(h.replies[1].f[4]);
    // v^2 / 2a = 16000^2 / 640000 = 400 steps (plus the steps already committed)
    CHECK(rest >= at + 400 && rest <= at + 400 + 2 + cfg::STOP_KEEP_MAX_STEPS);
    h.heartbeat();
    CHECK_EQ(last_status_field(h, QS_STATE) & ds::STOPPING, ds::STOPPING);
    // a queued command waits until the motor is at rest, then runs
    uint16_t s = h.move_by(2, -100);
    CHECK_EQ(h.ack_status(s, proto::MoveBy::ID), st::OK);
    CHECK_EQ(h.count(proto::Event::ID, ev::SEGMENT_STARTED), 0);
    h.run_us(30000);  // 400 steps at the limit: 50 ms
    CHECK(h.dev.stopping());
    h.run_us(40000);
    CHECK(!h.dev.stopping());
    h.run_until_event(ev::QUEUE_EMPTY, 1000000);
    CHECK_EQ(h.board.position, rest - 100);
    // slow: at 100 steps/s the stop takes no step at all
    Harness slow;
    slow.keepalive = true;
    slow.boot();
    slow.move_to(1, 100000, 100, 1000);
    slow.run_us(2000000);
    const int32_t where = slow.board.position;
    slow.clear();
    slow.stop();
    CHECK(slow.replies[1].f[4] <= where + 1 + cfg::STOP_KEEP_STEPS);  // slow: only the fewest are kept
    slow.run_us(200000);
    CHECK_EQ(slow.board.position, slow.replies[1].f[4]);
}

TEST(core_fault_releases_the_motor_after_the_release_time) {
    Harness h;
    h.boot();
    h.sampling(1, 10000);
    h.heater(2, 3000);
    h.run_us(cfg::WATCHDOG_MS * 1000UL + 10000);  // the host went silent
    CHECK_EQ(h.dev.fault(), proto::fault::WATCHDOG);
    CHECK_EQ(h.board.heater_mV, 0);
    CHECK(h.board.motor_enabled);
    CHECK(h.board.sense_on);  // sampling goes on while the fault holds the motor
    h.clear();
    h.run_us(cfg::FAULT_RELEASE_MS * 1000UL - 20000);
    CHECK(h.board.motor_enabled);
    CHECK_EQ(h.count(proto::Event::ID, ev::MOTOR_RELEASED), 0);
    h.run_us(40000);
    CHECK(!h.board.motor_enabled);
    CHECK(!h.board.sense_on);
    CHECK_EQ(h.dev.sampling_period_us(), 0);
    CHECK(!h.dev.position_known());
    CHECK(!h.board.record_valid);
    int i = h.find(proto::Event::ID, ev::MOTOR_RELEASED);
    CHECK(i >= 0);
    if (i >= 0) CHECK_EQ(h.replies[i].f[3], proto::fault::WATCHDOG);
    h.clear();
    h.run_us(100000);
    CHECK_EQ(h.count(proto::Sample::ID), 0);
    h.heartbeat();
    CHECK_EQ(last_status_field(h, QS_STATE), ds::POSITION_UNKNOWN | ds::MOTOR_RELEASED);
    CHECK_EQ(h.ack_status(h.set_position(0), proto::SetPosition::ID), st::BAD_STATE);  // motor off
    h.clear_queue();  // clears the fault and energizes the motor again
    CHECK(h.board.motor_enabled);
    CHECK(!h.dev.motor_released());
    CHECK(!h.dev.position_known());
    CHECK_EQ(h.ack_status(h.set_position(0), proto::SetPosition::ID), st::OK);
}

TEST(core_stop_acts_while_the_outbox_is_full) {
    // A TX ring that drains one byte per ms: the outbox fills with events, host bytes
    // wait in the RX ring. A STOP behind them acts at once; what came before it never runs.
    Harness h;
    h.boot();
    h.run_us(1000);
    h.board.tx_ring_size = 40;  // one frame at a time
    h.board.tx_drain_bytes_per_ms = 1;
    h.heater(1, 4000);
    for (int i = 0; i < 14 && h.board.rx_pending() == 0; ++i) h.dwell(static_cast<uint16_t>(10 + i), 1);
    CHECK(h.board.rx_pending() > 0);  // replies piled up: host bytes now wait in the RX ring
    uint8_t frame[fw::MAX_WIRE_FRAME];
    proto::MoveTo m;
    m.segment = 50;
    m.target_steps = 3200;
    m.rate_steps_per_s = 1000;
    m.accel_steps_per_s2 = 1000;
    uint8_t p[proto::MoveTo::SIZE];
    uint8_t k = fw::frame_encode(proto::MoveTo::ID, 900, p, proto::pack(m, p), frame);
    h.board.host_write(frame, k);
    k = fw::frame_encode(proto::Stop::ID, 901, 0, 0, frame);
    h.board.host_write(frame, k);
    h.poll_once();  // (no time passes)
    h.poll_once();
    CHECK(h.board.rx_pending() == 0);   // found and dropped up to the STOP
    CHECK_EQ(h.board.heater_mV, 0);     // acted on before any reply could go out
    CHECK_EQ(h.dev.stops_found_waiting(), 1);
    h.board.tx_drain_bytes_per_ms = 1000;  // let the backlog out
    h.clear();
    h.run_us(10000);
    CHECK_EQ(h.ack_status(901, proto::Stop::ID), st::OK);
    CHECK_EQ(h.ack_status(900, proto::MoveTo::ID), -1);  // sent before the STOP: never ran
    CHECK(h.find(proto::Event::ID, ev::STOPPED) >= 0);
    CHECK_EQ(h.board.position, 0);
}

TEST(core_step_underrun_reported_as_event_and_status) {
    // A two-slot ring polled every 2 ms cannot keep 16000 steps/s fed.
    Harness h;
    h.keepalive = true;
    h.board.step_ring_size = 2;
    h.step_us = 2000;
    h.boot();
    h.move_to(1, 16000, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
    h.run_us(300000);
    CHECK(h.board.underruns > 0);
    int i = h.find(proto::Event::ID, ev::STEP_UNDERRUN);
    CHECK(i >= 0);
    if (i >= 0) CHECK(h.replies[i].f[3] >= 1);
    h.heartbeat();
    CHECK_EQ(last_status_field(h, QS_UNDERRUNS), h.board.underruns);
    // at speed (above the start/stop speed) steps may have been lost: the position is
    // suspect (EVENT position_suspect, QUEUE_STATUS state) until SET_POSITION
    CHECK(h.board.fast_underruns > 0);
    CHECK(h.find(proto::Event::ID, ev::POSITION_SUSPECT) >= 0);
    CHECK(h.dev.position_suspect());
    CHECK_EQ(last_status_field(h, QS_STATE) & ds::POSITION_SUSPECT, ds::POSITION_SUSPECT);
    h.run_until_event(ev::QUEUE_EMPTY, 3000000);
    h.set_position(0);
    h.clear();
    h.heartbeat();
    CHECK_EQ(last_status_field(h, QS_STATE) & ds::POSITION_SUSPECT, 0);
    // the same move with the ring deep enough and a fast loop: none
    Harness ok;
    ok.keepalive = true;
    ok.board.step_ring_size = 64;
    ok.boot();
    ok.move_to(1, 16000, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
    ok.run_until_event(ev::QUEUE_EMPTY, 3000000);
    CHECK_EQ(ok.board.position, 16000);
    CHECK_EQ(ok.board.underruns, 0);
    CHECK_EQ(ok.count(proto::Event::ID, ev::STEP_UNDERRUN), 0);
}

TEST(core_board_counters_reach_the_host) {
    Harness h;
    h.boot();
    h.board.i2c_recovery_count = 3;
    h.board.uart_overrun_count = 7;
    h.board.uart_frame_error_count = 2;
    h.clear();
    h.run_us(1000);
    int i = h.find(proto::Event::ID, ev::I2C_RECOVERED);
    CHECK(i >= 0);
    if (i >= 0) CHECK_EQ(h.replies[i].f[3], 3);
    h.run_us(1000);
    CHECK_EQ(h.count(proto::Event::ID, ev::I2C_RECOVERED), 1);  // once per change
    h.heartbeat();
    CHECK_EQ(last_status_field(h, QS_I2C), 3);
    CHECK_EQ(last_status_field(h, QS_UART_OVERRUNS), 7);
    CHECK_EQ(last_status_field(h, QS_FRAME_ERRORS), 2);
}

TEST(core_identity_reports_sampling_floor_and_release_time) {
    Harness h;
    h.boot();
    h.clear();
    h.hello();
    CHECK_EQ(h.replies[0].id, proto::Identity::ID);
    CHECK_EQ(h.replies[0].f[14], cfg::MIN_SAMPLE_PERIOD_US);
    CHECK_EQ(h.replies[0].f[15], cfg::FAULT_RELEASE_MS);
}

// A STOP below the start/stop speed (sqrt(2 a_max) = 800 steps/s) stops at once: the
// steps kept end the train, and their running dry is no underrun. (Before: a false
// STEP_UNDERRUN, the promise of more steps left standing.)
TEST(core_slow_stop_is_no_underrun) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.move_to(1, 100000, 500, 1000);
    h.run_us(1500000);
    CHECK(h.board.step_busy());
    h.stop();
    h.run_us(300000);
    CHECK(!h.board.step_busy());
    CHECK_EQ(h.board.underruns, 0);
    CHECK_EQ(h.count(proto::Event::ID, ev::STEP_UNDERRUN), 0);
}

// Below the start/stop speed an underrun is only a pause: the position stays trusted
// (above it, core_step_underrun_reported_as_event_and_status: suspect).
TEST(core_slow_underrun_leaves_the_position_trusted) {
    Harness slow;
    slow.keepalive = true;
    slow.board.step_ring_size = 1;
    slow.step_us = 20000;
    slow.boot();
    slow.move_to(1, 400, 400, cfg::MAX_ACCEL_STEPS_PER_S2);
    slow.run_until_event(ev::QUEUE_EMPTY, 5000000);
    CHECK(slow.board.underruns > 0);
    CHECK_EQ(slow.board.fast_underruns, 0);
    CHECK(!slow.dev.position_suspect());
    CHECK_EQ(slow.count(proto::Event::ID, ev::POSITION_SUSPECT), 0);
}

// ARM_RESET: the host means to reset the board (it reopens the port). Refused while the
// position is unknown or a move runs; accepted at rest it arms the record; a move
// disarms it; a boot spends it.
TEST(core_arm_reset_arms_the_record_at_rest_only) {
    Harness h;
    h.board.kept_valid = false;
    h.boot();
    CHECK(!h.board.record_armed);
    uint16_t s = h.send(proto::ArmReset::ID, 0, 0);
    CHECK_EQ(h.ack_status(s, proto::ArmReset::ID), st::BAD_STATE);  // position unknown
    h.set_position(0);
    h.move_to(1, 3200, 16000, 320000);
    s = h.send(proto::ArmReset::ID, 0, 0);
    CHECK_EQ(h.ack_status(s, proto::ArmReset::ID), st::BAD_STATE);  // moving
    h.run_until_event(ev::QUEUE_EMPTY, 2000000);
    CHECK(!h.board.record_armed);
    h.clear();
    s = h.send(proto::ArmReset::ID, 0, 0);
    CHECK_EQ(h.ack_status(s, proto::ArmReset::ID), st::OK);
    CHECK(h.board.record_valid && h.board.record_armed && h.board.record_steps == 3200);
    h.clear();
    h.move_to(2, 0, 16000, 320000);  // a move disarms it, for good
    h.run_until_event(ev::QUEUE_EMPTY, 2000000);
    CHECK_EQ(h.board.position, 0);
    CHECK(h.board.record_valid && !h.board.record_armed);
    // a boot spends the arm: the next reset is not armed
    Harness b;
    b.board.kept_valid = true;
    b.board.kept_steps = 3200;
    b.boot();
    CHECK(b.dev.position_known());
    CHECK(b.board.record_valid && !b.board.record_armed);
}

// A slow step longer than the generator takes in a run goes alone (the board chains it);
// the move still ends exactly where it should.
TEST(core_slow_steps_go_alone) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.move_to(1, 20, 20, 40);  // 20 steps/s: 100,000 ticks a step
    h.run_until_event(ev::QUEUE_EMPTY, 5000000);
    CHECK_EQ(h.board.position, 20);
    CHECK(h.board.long_steps >= 15);
    CHECK_EQ(h.board.underruns, 0);
}
