// Continuous sampling (periods below the single-shot minimum): ADS1115 conversions
// paced by ALERT/RDY become samples in SAMPLE_BLOCK frames, with no counter gap, the
// CS5513 words at their own rate, and the device refuses periods the sensor or the line
// cannot carry.
#include "config.h"
#include "sampling_limits.h"
#include "test_core_harness.h"
#include "test_runner.h"

using core_test::Harness;
using fw::Device;
namespace af = proto::adc_flags;
namespace st = proto::status;

namespace {

struct Got {
    int64_t counter, t_us, steps, position, resistance, flags, heater_mV, segment;
    bool word;
};

// Every sample the blocks among the replies stand for, in order; returns the count.
int expand(const Harness& h, Got* out, int cap, int* blocks) {
    int n = 0;
    *blocks = 0;
    for (int i = 0; i < h.n; ++i) {
        const core_test::Reply& r = h.replies[i];
        if (r.id != proto::SampleBlock::ID) continue;
        ++*blocks;
        const int64_t* f = r.f;
        int64_t t = f[1], steps = f[2], pos = f[3], flags = f[4];
        for (int k = 0; k <= f[9] && n < cap; ++k) {
            if (k) {
                const int64_t* e = f + 10 + 4 * (k - 1);
                t += e[0];
                steps += e[1];
                pos = static_cast<int16_t>(static_cast<uint16_t>(pos + e[2]));
                flags = e[3];
            }
            Got& g = out[n++];
            g = Got{f[0] + k, t, steps, pos, k == f[7] ? f[8] : 0, flags, f[5], f[6], k == f[7]};
        }
    }
    return n;
}

}  // namespace

TEST(core_continuous_860_per_second_in_blocks_without_gaps) {
    Harness h;
    h.keepalive = true;
    h.board.resistance_latency_us = 19125;  // the CS5513 at its slowest oscillator: 52.3 words/s
    h.board.position_counts = -1234;
    h.boot();
    CHECK_EQ(h.ack_status(h.sampling(4, cfg::MIN_SAMPLE_PERIOD_US), proto::SetSampling::ID), st::OK);
    h.clear();
    h.run_us(1000000);
    static Got got[1200];
    int blocks = 0;
    const int n = expand(h, got, 1200, &blocks);
    CHECK(n >= 853 && n <= 860);                 // 1 s / 1163 us, less the block under way
    CHECK(blocks * 6 >= n && blocks <= n / 6 + 1);
    int words = 0;
    int64_t t_sum = 0;
    for (int i = 0; i < n; ++i) {
        CHECK_EQ(got[i].counter, i);
        if (i) t_sum += got[i].t_us - got[i - 1].t_us;
        CHECK_EQ(got[i].position, -1234);
        CHECK_EQ(got[i].segment, 4);
        // stamped by the pass that saw the pulse: the harness polls every 50 us
        if (i) CHECK(got[i].t_us - got[i - 1].t_us >= 1163 - 50 && got[i].t_us - got[i - 1].t_us <= 1163 + 50);
        words += got[i].word;
    }
    CHECK(t_sum / (n - 1) >= 1162 && t_sum / (n - 1) <= 1164);   // on average exactly the ADC's pace
    CHECK(words >= 45 && words <= 53);           // CS5513 words, ~52 per second (after the 2 ms settle)
    CHECK_EQ(h.dev.samples_dropped(), 0);
    CHECK(h.count(proto::Sample::ID) == 0);
}

TEST(core_continuous_every_kth_conversion_and_stop_flushes) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.sampling(1, 2 * cfg::MIN_SAMPLE_PERIOD_US);    // every second conversion
    h.clear();
    h.run_us(100000);
    h.sampling(2, 0);
    h.run_us(10000);
    static Got got[200];
    int blocks = 0;
    const int n = expand(h, got, 200, &blocks);
    if (n < 42 || n > 43) testing::note("n = %d", n);
    CHECK(n >= 41 && n <= 43);                    // ~100 ms / 2326 us; 41 = 6 x 6 + 5: the stop sent the rest
    for (int i = 1; i < n; ++i) {
        CHECK_EQ(got[i].counter, got[i - 1].counter + 1);
        CHECK(got[i].t_us - got[i - 1].t_us >= 2326 - 50 && got[i].t_us - got[i - 1].t_us <= 2326 + 50);
    }
    // back to single-shot: no more blocks, and a single-shot period sends SAMPLE frames again
    h.clear();
    h.sampling(3, cfg::SINGLE_SHOT_MIN_PERIOD_US);
    h.run_us(20000);
    CHECK_EQ(h.count(proto::SampleBlock::ID), 0);
    CHECK(h.count(proto::Sample::ID) >= 5);
}

TEST(core_continuous_blocks_close_on_heater_and_flag_resistance) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    h.run_us(50000);
    h.heater(2, 6000);
    h.run_us(50000);
    h.heater(3, 0);
    h.run_us(20000);
    static Got got[200];
    int blocks = 0;
    const int n = expand(h, got, 200, &blocks);
    CHECK(n > 90);
    int heated = 0;
    for (int i = 0; i < n; ++i) {
        if (i) CHECK_EQ(got[i].counter, got[i - 1].counter + 1);
        if (got[i].heater_mV > 0) {
            ++heated;
            CHECK(!got[i].word);                // no resistance while heating
        }
    }
    CHECK(heated > 35);
    CHECK_EQ(h.board.interlock_violations, 0u);
}

// The QUEUE_STATUS answering a HEARTBEAT sent now (its fields), or null.
const int64_t* status_now(Harness& h) {
    const int from = h.n;
    h.heartbeat();
    h.run_us(1000);
    const int i = h.find(proto::QueueStatus::ID, -1, from);
    return i < 0 ? 0 : h.replies[i].f;
}

// Each sample is stamped with its conversion's start (the ALERT/RDY edge before its own)
// and carries the step position at that instant, however late the main loop comes for
// it: here it polls every 2 ms, longer than a conversion, while the motor turns at the
// top rate. (Before: the pass that noticed the pulse, minus 1163 us, with the position
// of the moment it was processed.)
TEST(core_continuous_stamps_and_positions_are_the_edges_whatever_the_pass) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    h.move_to(2, 40000, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
    h.step_us = 2000;  // a slow main loop: two conversions finish between its passes
    h.run_us(400000);
    static Got got[400];
    int blocks = 0;
    const int n = expand(h, got, 400, &blocks);
    CHECK(n > 300);
    int moving = 0;
    for (int i = 0; i < n; ++i) {
        if (i) CHECK_EQ(got[i].counter, got[i - 1].counter + 1);  // none lost
        // find the edge it claims to start at: exactly, with the position then
        uint32_t e = 0;
        while (e < h.board.edges_logged && static_cast<int64_t>(h.board.edge_t_us[e]) < got[i].t_us) ++e;
        CHECK(e < h.board.edges_logged);
        if (e >= h.board.edges_logged) break;
        CHECK_EQ(static_cast<int64_t>(h.board.edge_t_us[e]), got[i].t_us);
        CHECK_EQ(got[i].steps, h.board.edge_position[e]);
        if (i && got[i].steps - got[i - 1].steps > 15) ++moving;  // 16,000 steps/s: ~18 a conversion
    }
    CHECK(moving > 100);
    CHECK_EQ(h.dev.samples_dropped(), 0u);
}

// The measured conversion period goes to QUEUE_STATUS (the host fits the sensor's clock
// with it): a chip 0.6 % slow says so.
TEST(core_continuous_reports_the_measured_conversion_period) {
    Harness h;
    h.keepalive = true;
    h.board.position_conversion_us = 1170;
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    h.run_us(2500000);
    h.clear();
    const int64_t* qs = status_now(h);
    CHECK(qs != 0);
    if (!qs) return;
    CHECK_EQ(qs[12], 1170000);  // sensor_period_ns
    CHECK_EQ(qs[13], 0);        // no restarts
    h.sampling(2, 0);
    h.run_us(10000);
    qs = status_now(h);
    CHECK(qs && qs[12] == 0);   // not sampling continuously: 0
}

// ALERT/RDY never pulses (an unwired D2): the ADS1115 is set up again after three silent
// conversions, EVENT sensor_restarted once, and after 200 ms of silence fault
// position_sensor; the set-up is still retried, every 100 ms. (Before: no sample, no
// event, no fault, for ever.)
TEST(core_continuous_silent_ready_line_restarts_then_faults_by_name) {
    Harness h;
    h.keepalive = true;
    h.board.rdy_dead = true;
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    const int fault = h.run_until_event(proto::event_kind::FAULT, 400000);
    CHECK(fault >= 0);
    if (fault < 0) return;
    CHECK_EQ(h.replies[fault].f[3], proto::fault::POSITION_SENSOR);
    CHECK_EQ(h.count(proto::Event::ID, proto::event_kind::SENSOR_RESTARTED), 1);
    const int restarted = h.find(proto::Event::ID, proto::event_kind::SENSOR_RESTARTED);
    CHECK(restarted < fault);
    const uint32_t setups_at_fault = h.board.continuous_setups;
    CHECK(setups_at_fault >= 200000 / (3 * 1163) - 2);  // every three conversions until then
    h.run_us(500000);
    const uint32_t later = h.board.continuous_setups - setups_at_fault;
    CHECK(later >= 4 && later <= 6);                    // then every 100 ms
    const int64_t* qs = status_now(h);
    CHECK(qs && qs[4] == proto::fault::POSITION_SENSOR && qs[13] == h.dev.sensor_restarts());
    CHECK_EQ(h.count(proto::SampleBlock::ID), 0);
}

// A NACK while switching into continuous mode: the switch is retried and samples come,
// valid, with one EVENT sensor_restarted and no fault. (Before: every later sample
// position_invalid, on a grid of its own.)
TEST(core_continuous_failed_switch_is_retried) {
    Harness h;
    h.keepalive = true;
    h.board.continuous_start_failures = 3;
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    h.clear();
    h.run_us(100000);
    static Got got[100];
    int blocks = 0;
    const int n = expand(h, got, 100, &blocks);
    CHECK(n >= 70);
    for (int i = 0; i < n; ++i) CHECK(!(got[i].flags & proto::sample_flags::POSITION_INVALID));
    CHECK_EQ(h.board.continuous_setups, 4u);
    CHECK_EQ(h.count(proto::Event::ID, proto::event_kind::SENSOR_RESTARTED), 1);
    CHECK_EQ(h.count(proto::Event::ID, proto::event_kind::FAULT), 0);
}

// The sensor goes quiet mid-stream and comes back: a restart, and the counter jumps over
// the conversions the outage cost (the host sees them lost).
TEST(core_continuous_outage_shows_as_a_counter_gap) {
    Harness h;
    h.keepalive = true;
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    h.run_us(50000);
    h.board.rdy_dead = true;
    h.run_us(10000);
    h.board.rdy_dead = false;
    h.run_us(50000);
    static Got got[200];
    int blocks = 0;
    const int n = expand(h, got, 200, &blocks);
    int64_t gap = 0;
    for (int i = 1; i < n; ++i) gap += got[i].counter - got[i - 1].counter - 1;
    CHECK(gap >= 5 && gap <= 12);   // ~10 ms of conversions, plus the restart's own
    CHECK_EQ(static_cast<int64_t>(h.dev.samples_dropped()), gap);
    CHECK_EQ(h.count(proto::Event::ID, proto::event_kind::SENSOR_RESTARTED), 1);
    CHECK_EQ(h.count(proto::Event::ID, proto::event_kind::FAULT), 0);
}

// A burst of host frames while sampling at 860/s and moving at the top rate: the host's
// frames wait while a sample block waits for the line, at most FRAMES_PER_PASS are
// handled per pass with the step ring fed after each, so no sample is lost and the step
// train never runs dry. (Before: 87 samples lost, 4 underruns in simavr.)
TEST(core_continuous_frame_burst_loses_no_sample_and_no_step) {
    Harness h;
    h.board.tx_drain_bytes_per_ms = 25;  // 250 kbaud
    h.board.tx_ring_size = 256;          // the AVR's
    h.board.resistance_latency_us = 19125;  // CS5513 words at 52 per second: full blocks
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    h.move_to(2, 60000, cfg::MAX_RATE_STEPS_PER_S, cfg::MAX_ACCEL_STEPS_PER_S2);
    h.run_us(200000);
    // 300 HEARTBEATs back to back (as much as the 4 KB fake RX holds)
    for (int i = 0; i < 300; ++i) {
        uint8_t frame[fw::MAX_WIRE_FRAME];
        const uint8_t k = fw::frame_encode(proto::Heartbeat::ID, static_cast<uint16_t>(1000 + i), 0, 0, frame);
        CHECK_EQ(h.board.host_write(frame, k), k);
    }
    // one pass handles at most two of them
    h.clear();
    h.poll_once();
    CHECK(h.count(proto::Ack::ID) <= Device::FRAMES_PER_PASS);
    int acks = 0;
    for (int i = 0; i < 30; ++i) {
        acks += h.count(proto::Ack::ID);
        h.clear();
        h.run_us(100000);
    }
    acks += h.count(proto::Ack::ID);
    CHECK_EQ(h.board.underruns, 0);
    CHECK_EQ(h.dev.samples_dropped(), 0u);
    CHECK_EQ(acks, 300);  // every one answered, later
    CHECK_EQ(h.dev.urgent_lost(), 0u);
}

TEST(core_sampling_refusals_name_sensor_and_line) {
    CHECK_EQ(fw::sampling_refusal(0, 9600), st::OK);
    CHECK_EQ(fw::sampling_refusal(cfg::MIN_SAMPLE_PERIOD_US, 250000), st::OK);
    CHECK_EQ(fw::sampling_refusal(cfg::MIN_SAMPLE_PERIOD_US - 1, 250000), st::TOO_FAST_FOR_SENSOR);
    CHECK_EQ(fw::sampling_refusal(cfg::MIN_SAMPLE_PERIOD_US, 115200), st::TOO_FAST_FOR_LINE);
    CHECK_EQ(fw::sampling_refusal(2 * cfg::MIN_SAMPLE_PERIOD_US, 115200), st::OK);
    CHECK_EQ(fw::sampling_refusal(3000, 115200), st::TOO_FAST_FOR_LINE);    // 12,000 B/s of SAMPLE frames
    CHECK_EQ(fw::sampling_refusal(4000, 115200), st::OK);
    // below the single-shot minimum only whole conversions: never rounded
    CHECK_EQ(fw::sampling_refusal(cfg::MIN_SAMPLE_PERIOD_US + 1, 250000), st::BETWEEN_CONVERSIONS);
    CHECK_EQ(fw::sampling_refusal(2000, 250000), st::BETWEEN_CONVERSIONS);
    CHECK_EQ(fw::sampling_refusal(2 * cfg::MIN_SAMPLE_PERIOD_US + 1, 250000), st::BETWEEN_CONVERSIONS);
    CHECK_EQ(fw::sampling_refusal(2999, 250000), st::BETWEEN_CONVERSIONS);
    CHECK_EQ(fw::sampling_refusal(2 * cfg::MIN_SAMPLE_PERIOD_US, 250000), st::OK);
    CHECK_EQ(fw::sampling_refusal(3000, 250000), st::OK);
    CHECK_EQ(fw::sampling_refusal(3001, 250000), st::OK);
    Harness h;
    h.boot();
    CHECK_EQ(h.ack_status(h.sampling(1, 100), proto::SetSampling::ID), st::TOO_FAST_FOR_SENSOR);
    CHECK_EQ(h.ack_status(h.sampling(1, 1500), proto::SetSampling::ID), st::BETWEEN_CONVERSIONS);
}

// The board's edge count wraps every 65,536 conversions (76 s at 860/s): no restart, no
// gap, the period still right after it. (Before: a restart and a gap of 2-3 samples every
// 76.2 s, found by scripts/bench/wire_limit.py over ten minutes in simavr.)
TEST(core_continuous_edge_count_wrap_is_no_outage) {
    Harness h;
    h.keepalive = true;
    h.step_us = 500;
    h.boot();
    h.sampling(1, cfg::MIN_SAMPLE_PERIOD_US);
    for (int i = 0; i < 160; ++i) {  // 80 s
        h.clear();
        h.run_us(500000);
    }
    CHECK(h.board.edges_logged >= fw::FakeBoard::EDGE_LOG);  // (the log is full: far past 65,536 edges)
    CHECK_EQ(h.dev.sensor_restarts(), 0);
    CHECK_EQ(h.dev.samples_dropped(), 0u);
    CHECK_EQ(h.count(proto::Event::ID, proto::event_kind::SENSOR_RESTARTED), 0);
    CHECK_EQ(h.dev.sensor_period_ns(), 1163000u);
}
