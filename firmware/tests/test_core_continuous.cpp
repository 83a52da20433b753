// Continuous sampling (periods below the single-shot minimum): ADS1115 conversions
// paced by ALERT/RDY become samples in SAMPLE_BLOCK frames, with no counter gap, the
// CS5513 words at their own rate, and the device refuses periods the sensor or the line
// cannot carry.
#include "config.h"
#include "sampling_limits.h"
#include "test_core_harness.h"
#include "test_runner.h"

using core_test::Harness;
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

TEST(core_continuous_without_the_adc_keeps_the_grid_flagged) {
    Harness h;
    h.keepalive = true;
    h.board.position_start_fails = true;
    h.boot();
    h.sampling(1, 1500);
    h.clear();
    h.run_us(30000);
    static Got got[50];
    int blocks = 0;
    const int n = expand(h, got, 50, &blocks);
    CHECK(n >= 18 && n <= 20);
    for (int i = 0; i < n; ++i) CHECK(got[i].flags & proto::sample_flags::POSITION_INVALID);
}

TEST(core_sampling_refusals_name_sensor_and_line) {
    CHECK_EQ(fw::sampling_refusal(0, 9600), st::OK);
    CHECK_EQ(fw::sampling_refusal(cfg::MIN_SAMPLE_PERIOD_US, 250000), st::OK);
    CHECK_EQ(fw::sampling_refusal(cfg::MIN_SAMPLE_PERIOD_US - 1, 250000), st::TOO_FAST_FOR_SENSOR);
    CHECK_EQ(fw::sampling_refusal(cfg::MIN_SAMPLE_PERIOD_US, 115200), st::TOO_FAST_FOR_LINE);
    CHECK_EQ(fw::sampling_refusal(2 * cfg::MIN_SAMPLE_PERIOD_US, 115200), st::OK);
    CHECK_EQ(fw::sampling_refusal(3000, 115200), st::TOO_FAST_FOR_LINE);    // 12,000 B/s of SAMPLE frames
    CHECK_EQ(fw::sampling_refusal(4000, 115200), st::OK);
    Harness h;
    h.boot();
    CHECK_EQ(h.ack_status(h.sampling(1, 100), proto::SetSampling::ID), st::TOO_FAST_FOR_SENSOR);
}
